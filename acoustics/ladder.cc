#include "sonicboom/acoustics/ladder.h"

#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <numbers>
#include <utility>

#include "sonicboom/acoustics/closed_form_bank.h"
#include "sonicboom/acoustics/fd_render.h"
#include "sonicboom/acoustics/shell_fd.h"
#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {

void UseFdDamping(const TubeConfig& tube, MaterialConfig* material, ShellConfig* shell) {
  if (shell->damping == DampingModel::kLaw) {
    // the Rayleigh curve through the law at the anchors, as the FD rung builds it
    const ShellModel law(tube, *material, *shell);
    material->loss_factor = 2.0 * law.DampingRatio(2.0 * std::numbers::pi * shell->loss_low_hz);
    shell->loss_factor_high = 2.0 * law.DampingRatio(2.0 * std::numbers::pi * shell->loss_high_hz);
  }
  shell->damping = DampingModel::kRayleigh;
}

struct VibrationRung::Impl {
  RungSpec spec;
  std::unique_ptr<ShellModel> model;
  Eigen::MatrixXd sensor_rows;  // (mics x dofs): what an FD render reads
  std::unique_ptr<ShellFd> fd;
  ShellModes modes;
  std::unique_ptr<ShellModalBank> bank;
  std::unique_ptr<ClosedFormBank> closed_form;
  double full_band_hz{0.0};
};

VibrationRung::VibrationRung(const TubeConfig& tube, const MaterialConfig& material,
                             const ShellConfig& shell, const MicArrayConfig& mics,
                             double sample_rate_hz, const RungSpec& spec, double full_band_hz,
                             double decay_floor_db, const std::string& cache_dir)
    : impl_(std::make_unique<Impl>()) {
  Impl& m = *impl_;
  m.spec = spec;
  m.full_band_hz = full_band_hz;
  if (spec.model == VibrationModel::kModalClosedForm) {
    // the ideal tube in closed form: no grid, no shell
    m.closed_form = std::make_unique<ClosedFormBank>(tube, material, mics, sample_rate_hz,
                                                     full_band_hz, decay_floor_db);
    return;
  }
  ShellConfig grid = shell;
  grid.grid_spacing_m = spec.arc_m;
  grid.axial_spacing_m = spec.axial_m;
  m.model = std::make_unique<ShellModel>(tube, material, grid);
  m.sensor_rows = m.model->SensorRows(mics);
  if (spec.model == VibrationModel::kFd) {
    // a multiple of the smallest stable oversampling
    const ShellFd stable(*m.model, sample_rate_hz, 0);
    m.fd = std::make_unique<ShellFd>(*m.model, sample_rate_hz,
                                     stable.oversampling() * spec.oversampling_factor);
  } else if (spec.model == VibrationModel::kModal) {
    m.modes = CachedShellModes(*m.model, full_band_hz, 0, true, cache_dir);
    m.bank = std::make_unique<ShellModalBank>(*m.model, m.modes, mics, sample_rate_hz,
                                              decay_floor_db, spec.residual);
  } else {
    throw ConfigError(
        fmt::format("a ladder rung is modal, fd or modal-closed-form, not {}", NameOf(spec.model)));
  }
}

VibrationRung::~VibrationRung() = default;

int64_t VibrationRung::ModesPlayed(double derived_band_hz) const {
  const Impl& m = *impl_;
  if (m.fd) return 0;
  if (m.closed_form) return m.closed_form->FrequenciesHz(PlayedBand(derived_band_hz)).size();
  if (m.spec.mode_count > 0) return m.spec.mode_count;
  return m.bank->ModesBelow(PlayedBand(derived_band_hz));
}

Eigen::MatrixXd VibrationRung::Render(std::span<const ForceInput> forces, int64_t samples,
                                      double derived_band_hz) const {
  const Impl& m = *impl_;
  if (m.fd) return FdRender(*m.model, *m.fd, forces, m.sensor_rows, samples, -300.0);
  if (m.closed_form) return m.closed_form->Render(forces, PlayedBand(derived_band_hz), samples);
  return m.bank->Render(forces, ModesPlayed(derived_band_hz), samples);
}

Eigen::MatrixXd VibrationRung::RenderImpacts(std::span<const FdImpact> impacts,
                                             const ContactConfig& contact, int64_t samples) const {
  const Impl& m = *impl_;
  if (!m.fd) throw Error("VibrationRung::RenderImpacts: only an FD rung closes its own contact");
  return FdRender(*m.model, *m.fd, {}, impacts, contact, m.sensor_rows, samples, -300.0).strain;
}

DrivingPoint VibrationRung::WallAt(double z_m, double theta_rad, double band_hz) const {
  if (!impl_->bank) throw Error("VibrationRung::WallAt: only a modal rung has a modal wall");
  return impl_->bank->WallAt(z_m, theta_rad, band_hz);
}

double VibrationRung::PlayedBand(double derived_band_hz) const {
  return impl_->spec.band_hz > 0 ? impl_->spec.band_hz : derived_band_hz;
}

Eigen::VectorXd VibrationRung::FrequenciesHz() const {
  if (impl_->fd) return {};
  if (impl_->closed_form) return impl_->closed_form->FrequenciesHz(impl_->full_band_hz);
  return impl_->bank->frequencies_hz();
}

Eigen::VectorXd VibrationRung::GridFrequenciesHz() const {
  if (impl_->fd || impl_->closed_form) return {};
  return impl_->modes.omega_rad_s / (2.0 * kPi);
}

int64_t VibrationRung::dofs() const {
  return impl_->model ? impl_->model->dofs() : 0;
}

int64_t VibrationRung::oversampling() const {
  return impl_->fd ? impl_->fd->oversampling() : 0;
}

bool VibrationRung::fd() const {
  return impl_->fd != nullptr;
}

SolvedForce SolveRigidStrikeForce(const ContactEvent& contact, const VibrationRung& wall,
                                  const TubeConfig& tube, const MaterialConfig& material,
                                  const SynthConfig& synth, double sample_rate_hz,
                                  double full_band_hz) {
  const HertzImpact hz = SolveHertzImpact(contact, tube, material);
  DrivingPoint striker;
  striker.rigid_mass_kg = contact.effective_mass_kg;
  const double band = std::min(full_band_hz, ContactBandHz(synth.band_factor, hz.duration_s));
  const DrivingPoint tube_side =
      wall.WallAt(contact.z_m, contact.theta_rad, std::min(full_band_hz, 2 * band));
  ContactForce cf = SolveContact(tube_side, striker, hz.stiffness_n_m15, contact.normal_speed_m_s,
                                 contact.time_s, sample_rate_hz, synth.contact);
  SolvedForce out;
  out.derived_band_hz =
      std::min(full_band_hz, ContactBandHz(synth.band_factor, cf.first_closure_s));
  out.force = {contact.z_m, contact.theta_rad, cf.first_sample, std::move(cf.force_n)};
  return out;
}

FdImpact RigidStrikeImpact(const ContactEvent& contact, const TubeConfig& tube,
                           const MaterialConfig& material) {
  FdImpact impact;
  impact.time_s = contact.time_s;
  impact.z_m = contact.z_m;
  impact.theta_rad = contact.theta_rad;
  impact.approach_speed_m_s = contact.normal_speed_m_s;
  impact.tube_side_kg = std::numeric_limits<double>::infinity();
  impact.striker.rigid_mass_kg = contact.effective_mass_kg;
  impact.stiffness_n_m15 = SolveHertzImpact(contact, tube, material).stiffness_n_m15;
  return impact;
}

}  // namespace sonicboom::acoustics
