#include "sonicboom/acoustics/ladder.h"

#include <fmt/format.h>

#include <algorithm>
#include <limits>
#include <numbers>
#include <utility>

#include "internal/render_stages.h"
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

AcousticModelConfig RungConfig(const AcousticModelConfig& base, const RungSpec& spec,
                               double full_band_hz) {
  AcousticModelConfig c = base;
  c.randomize = RandomizeConfig{};
  c.synth.model = spec.model;
  c.synth.render_span = RenderSpan::kRecord;
  c.synth.mode_band_hz = spec.mode_band_hz > 0 ? spec.mode_band_hz : full_band_hz;
  c.synth.mode_count = spec.mode_count;
  c.synth.residual = spec.residual;
  c.synth.fd_oversampling = 0;
  // the closed form's widest band; a modal rung's band is the ladder's to choose per render
  c.synth.max_frequency_hz = spec.model == VibrationModel::kModalClosedForm ? full_band_hz : 0.0;
  if (spec.model == VibrationModel::kFd) c.synth.decay_floor_db = -300.0;
  c.shell.grid_spacing_m = spec.arc_m;
  c.shell.axial_spacing_m = spec.axial_m;
  return c;
}

struct VibrationRung::Impl {
  RungSpec spec;
  std::unique_ptr<VibrationRenderer> renderer;
};

VibrationRung::VibrationRung(const AcousticModelConfig& base, const RungSpec& spec,
                             double full_band_hz)
    : impl_(std::make_unique<Impl>()) {
  if (spec.model != VibrationModel::kModal && spec.model != VibrationModel::kFd &&
      spec.model != VibrationModel::kModalClosedForm) {
    throw ConfigError(
        fmt::format("a ladder rung is modal, fd or modal-closed-form, not {}", NameOf(spec.model)));
  }
  impl_->spec = spec;
  impl_->renderer = MakeVibrationRenderer(RungConfig(base, spec, full_band_hz));
}

VibrationRung::~VibrationRung() = default;

int64_t VibrationRung::ModesPlayed(double derived_band_hz) const {
  return impl_->renderer->ModesPlayed(PlayedBand(derived_band_hz));
}

Eigen::MatrixXd VibrationRung::Render(std::span<const ForceInput> forces, int64_t samples,
                                      double derived_band_hz) const {
  return impl_->renderer->PlayForces(forces, PlayedBand(derived_band_hz), samples);
}

Eigen::MatrixXd VibrationRung::RenderImpacts(std::span<const FdImpact> impacts,
                                             int64_t samples) const {
  return impl_->renderer->PlayImpacts(impacts, samples);
}

DrivingPoint VibrationRung::WallAt(double z_m, double theta_rad, double band_hz) const {
  return impl_->renderer->WallAt(z_m, theta_rad, band_hz);
}

double VibrationRung::PlayedBand(double derived_band_hz) const {
  return impl_->spec.band_hz > 0 ? impl_->spec.band_hz : derived_band_hz;
}

Eigen::VectorXd VibrationRung::FrequenciesHz() const {
  return impl_->renderer->FrequenciesHz();
}

Eigen::VectorXd VibrationRung::GridFrequenciesHz() const {
  return impl_->renderer->GridFrequenciesHz();
}

int64_t VibrationRung::dofs() const {
  return impl_->renderer->dofs();
}

int64_t VibrationRung::oversampling() const {
  return impl_->renderer->oversampling();
}

bool VibrationRung::fd() const {
  return impl_->spec.model == VibrationModel::kFd;
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
