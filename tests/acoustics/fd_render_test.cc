// The FD rung as a cross-check (acoustics/fd_render.cc): impacts closed against the FD wall
// itself agree with the modal wall's contact solve and stay stable however stiff the contact;
// the output is anti-aliased (what a 44.1 kHz run reports below 16 kHz is what an 88.2 kHz run
// of the same steps reports there).
#include <gtest/gtest.h>

#include <cmath>
#include <complex>
#include <iostream>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "sonicboom/acoustics/contact.h"
#include "sonicboom/acoustics/fd_render.h"
#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_bank.h"
#include "sonicboom/acoustics/shell_fd.h"
#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

using sonicboom::kPi;

// the default seamed, drilled, mounted tube, Rayleigh-damped (what FD realizes), on a grid
ShellModel Tube(double spacing_m, double loss_factor = MaterialConfig{}.loss_factor) {
  ShellConfig s;
  s.grid_spacing_m = spacing_m;
  s.axial_spacing_m = spacing_m;
  s.damping = DampingModel::kRayleigh;
  // the thin shell the FD rung integrates (the thick-plate correction is dispersion_test's)
  s.dispersion = Dispersion::kThin;
  MaterialConfig material;
  material.loss_factor = loss_factor;
  return ShellModel(TubeConfig{}, material, s);
}

const ShellModel& Tube10mm() {
  static const ShellModel model = Tube(0.01);
  return model;
}

// a rigid striker of mass_kg hitting the held tube at (0.03 m, 1 rad) 2 ms into the record
FdImpact Impact(double mass_kg, double speed_m_s, double stiffness_n_m15) {
  FdImpact impact;
  impact.time_s = 0.002;
  impact.z_m = 0.03;
  impact.theta_rad = 1.0;
  impact.approach_speed_m_s = speed_m_s;
  impact.tube_side_kg = std::numeric_limits<double>::infinity();
  impact.striker.rigid_mass_kg = mass_kg;
  impact.stiffness_n_m15 = stiffness_n_m15;
  return impact;
}

TEST(FdImpactTest, AgreesWithTheModalWallsContactSolve) {
  // a 50 g rigid striker at 0.5 m/s, K = 3e8 N/m^1.5 (hard wood on PVC): against the FD grid in
  // the run, and against the same grid's modes to 20 kHz at the contact point by SolveContact
  const ShellModel& model = Tube10mm();
  const double fs = 44100.0;
  const ShellFd fd(model, fs, 0);
  const FdImpact impact = Impact(0.05, 0.5, 3e8);
  const Eigen::MatrixXd sensors = model.SensorRows(MicArrayConfig{});
  const FdRun run = FdRender(model, fd, {}, std::span<const FdImpact>(&impact, 1), ContactConfig{},
                             sensors, 1323, -300.0);
  ASSERT_EQ(run.impacts.size(), 1u);
  const ContactForce& on_fd = run.impacts[0];

  const ShellModes modes = SolveShellModes(model, 20000.0, 0, true);
  const ShellModalBank bank(model, modes, MicArrayConfig{}, fs, -300.0, true);
  DrivingPoint striker;
  striker.rigid_mass_kg = impact.striker.rigid_mass_kg;
  const ContactForce on_modes =
      SolveContact(bank.WallAt(impact.z_m, impact.theta_rad, 20000.0), striker,
                   impact.stiffness_n_m15, impact.approach_speed_m_s, impact.time_s, fs,
                   ContactConfig{});
  std::cout << "FD wall: " << on_fd.duration_s * 1e6 << " us, peak " << on_fd.peak_force_n
            << " N, impulse " << on_fd.impulse_ns << " Ns, " << on_fd.touches
            << " touches; modal wall: " << on_modes.duration_s * 1e6 << " us, peak "
            << on_modes.peak_force_n << " N, impulse " << on_modes.impulse_ns << " Ns, "
            << on_modes.touches << " touches\n";
  EXPECT_EQ(on_fd.first_sample, on_modes.first_sample);
  EXPECT_NEAR(on_fd.impulse_ns, on_modes.impulse_ns, 0.03 * on_modes.impulse_ns);
  EXPECT_NEAR(on_fd.peak_force_n, on_modes.peak_force_n, 0.05 * on_modes.peak_force_n);
  EXPECT_NEAR(on_fd.first_closure_s, on_modes.first_closure_s, 0.05 * on_modes.first_closure_s);
  // a striker cannot take more than twice its momentum, nor less than it (it stops at least)
  EXPECT_GT(on_fd.impulse_ns, 0.05 * 0.5);
  EXPECT_LT(on_fd.impulse_ns, 2 * 0.05 * 0.5);
  // the force of the run is what it reports: its sample means integrate to the impulse
  double sum = 0.0;
  for (double f : on_fd.force_n) sum += f / fs;
  EXPECT_NEAR(sum, on_fd.impulse_ns, 1e-9);
  // and the sensors hear the same strike as under the modal wall's force
  std::vector<ForceInput> forces{{impact.z_m, impact.theta_rad, on_modes.first_sample,
                                  on_modes.force_n}};
  const Eigen::MatrixXd prescribed = FdRender(model, fd, forces, sensors, 1323, -300.0);
  const double error = (run.strain - prescribed).norm() / prescribed.norm();
  std::cout << "sensor signals, FD-wall impact against the modal wall's force: " << error << "\n";
  EXPECT_LT(error, 0.1);
}

TEST(FdImpactTest, AStiffImpactNeedsFineStepsAndThenAgrees) {
  // steel-like contact (K = 3e10, 100 times the stiffness above) of 200 g at 5 m/s: its first
  // closure, on the wall's local mass, lasts about 8 us; the grid's own step cannot resolve it
  // and is refused naming the oversampling that can; at that oversampling the FD wall agrees
  // with the modal wall's solve
  const ShellModel& model = Tube10mm();
  const double fs = 44100.0;
  const FdImpact impact = Impact(0.2, 5.0, 3e10);
  const Eigen::MatrixXd sensors = model.SensorRows(MicArrayConfig{});
  int64_t needed = 0;
  try {
    FdRender(model, ShellFd(model, fs, 0), {}, std::span<const FdImpact>(&impact, 1),
             ContactConfig{}, sensors, 882, -300.0);
    ADD_FAILURE() << "expected the coarse step to be refused";
  } catch (const NumericalError& e) {
    const std::string what = e.what();
    const std::string key = "acoustics.fd_oversampling >= ";
    ASSERT_NE(what.find(key), std::string::npos) << what;
    needed = std::stoll(what.substr(what.find(key) + key.size()));
  }
  ASSERT_GT(needed, ShellFd(model, fs, 0).oversampling());
  const FdRun run = FdRender(model, ShellFd(model, fs, needed), {},
                             std::span<const FdImpact>(&impact, 1), ContactConfig{}, sensors, 882,
                             -300.0);
  ASSERT_TRUE(run.strain.allFinite());
  const ContactForce& f = run.impacts[0];
  const ShellModes modes = SolveShellModes(model, 20000.0, 0, true);
  const ShellModalBank bank(model, modes, MicArrayConfig{}, fs, -300.0, true);
  DrivingPoint striker;
  striker.rigid_mass_kg = impact.striker.rigid_mass_kg;
  const ContactForce m = SolveContact(bank.WallAt(impact.z_m, impact.theta_rad, 20000.0),
                                      striker, impact.stiffness_n_m15, impact.approach_speed_m_s,
                                      impact.time_s, fs, ContactConfig{});
  std::cout << "stiff impact at oversampling " << needed << ", FD wall: first closure "
            << f.first_closure_s * 1e6 << " us, peak " << f.peak_force_n << " N, impulse "
            << f.impulse_ns << " Ns, " << f.touches << " touches; modal wall: "
            << m.first_closure_s * 1e6 << " us, peak " << m.peak_force_n << " N, impulse "
            << m.impulse_ns << " Ns, " << m.touches << " touches\n";
  EXPECT_GT(f.impulse_ns, 0.2 * 5.0);
  EXPECT_LT(f.impulse_ns, 2 * 0.2 * 5.0);
  EXPECT_NEAR(f.impulse_ns, m.impulse_ns, 0.03 * m.impulse_ns);
  // (8 steps per closure: 7 % long and 14 % low in peak against the modal wall; at 4 times the
  // oversampling 1.5 % and 8 %, the rest being the two walls' difference above 20 kHz)
  EXPECT_NEAR(f.first_closure_s, m.first_closure_s, 0.1 * m.first_closure_s);
  EXPECT_NEAR(f.peak_force_n, m.peak_force_n, 0.2 * m.peak_force_n);
}

TEST(FdImpactTest, AnImpactThatNeverEndsNamesTheLimit) {
  // a 1 kg striker resting its weight on a slow approach outlasts a 0.1 ms limit
  const ShellModel& model = Tube10mm();
  const ShellFd fd(model, 44100.0, 0);
  const FdImpact impact = Impact(1.0, 0.01, 3e8);
  ContactConfig config;
  config.max_duration_s = 1e-4;
  try {
    FdRender(model, fd, {}, std::span<const FdImpact>(&impact, 1), config,
             model.SensorRows(MicArrayConfig{}), 441, -300.0);
    ADD_FAILURE() << "expected a NumericalError";
  } catch (const NumericalError& e) {
    EXPECT_NE(std::string(e.what()).find("acoustics.contact.max_duration_s"), std::string::npos)
        << e.what();
  }
}

// (channels x bins) spectrum of the first `bins` DFT bins of x (channels x n)
Eigen::MatrixXcd Spectrum(const Eigen::MatrixXd& x, int bins) {
  const Eigen::Index n = x.cols();
  Eigen::MatrixXcd out(x.rows(), bins);
  for (int b = 0; b < bins; ++b) {
    for (Eigen::Index c = 0; c < x.rows(); ++c) {
      std::complex<double> sum = 0.0;
      for (Eigen::Index t = 0; t < n; ++t)
        sum += x(c, t) * std::polar(1.0, -2 * kPi * b * static_cast<double>(t) / n);
      out(c, b) = sum;
    }
  }
  return out;
}

TEST(FdRenderTest, OutputBelowTheBandEdgeIsFreeOfAliases) {
  // the same FD steps reported at 44.1 and at 88.2 kHz: a hard impact excites the grid far
  // above 22 kHz (a 5 mm grid holds bending waves to about 90 kHz; a loss factor of 1e-3 keeps
  // them ringing, heard at two points); point-sampled at 44.1 kHz that content would fold into
  // the band
  const ShellModel model = Tube(0.005, 1e-3);
  const int64_t base = ShellFd(model, 88200.0, 0).oversampling();
  const ShellFd slow(model, 44100.0, 2 * base), fast(model, 88200.0, base);
  ASSERT_DOUBLE_EQ(slow.timestep_s(), fast.timestep_s());
  Eigen::MatrixXd sensors(2, model.dofs());
  sensors.row(0) = model.SensorRow(0.05, 1.0, 1e-4).transpose();
  sensors.row(1) = model.SensorRow(0.03, 0.6, 1e-4).transpose();
  // a hard impact (K = 1e9, 50 g at 1 m/s: about 20 us on the wall's local mass), solved at the
  // FD steps, so both runs step through the same states
  const FdImpact impact = Impact(0.05, 1.0, 1e9);
  const std::span<const FdImpact> impacts(&impact, 1);
  const int n = 441;  // 10 ms
  const Eigen::MatrixXd y44 =
      FdRender(model, slow, {}, impacts, ContactConfig{}, sensors, n, -300.0).strain;
  const Eigen::MatrixXd y88 =
      FdRender(model, fast, {}, impacts, ContactConfig{}, sensors, 2 * n, -300.0).strain;
  // bins below 16 kHz: 10 ms records, 100 Hz bins
  const int bins = 160;
  const Eigen::MatrixXcd s44 = Spectrum(y44, bins), s88 = Spectrum(y88, bins) / 2.0;
  const double error = (s44 - s88).norm() / s88.norm();
  std::cout << "44.1 against 88.2 kHz below 16 kHz: " << error << "\n";
  const Eigen::MatrixXcd all88 = Spectrum(y88, n);
  std::cout << "above 22 kHz at 88.2: " << all88.rightCols(n - 220).norm() / all88.norm() << "\n";
  // 0.0024 anti-aliased; point-sampled (the taps a single 1) it was 0.0066, with 1.4 % of the
  // 88.2 kHz run's spectrum above 22 kHz
  EXPECT_LT(error, 0.004);
}

}  // namespace
}  // namespace sonicboom::acoustics
