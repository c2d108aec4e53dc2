#include "sonicboom/acoustics/contact.h"

#include <Eigen/Dense>
#include <unsupported/Eigen/MatrixFunctions>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include <fmt/format.h>

#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

// rigid-target Hertz: t_c = kHertzDuration delta_max / v (docs/physics.md, "Hertz impact")
constexpr double kHertzDuration = 2.9432;
// a first closure shorter than this fraction of substeps_per_duration substeps (or longer than
// its inverse) is redone with a substep sized on it, at most kMaxResolves times
constexpr double kResolveFraction = 0.5;
constexpr int kMaxResolves = 4;
// substeps per Hertz time of the lightest apparent mass, at least (stability of the coupling)
constexpr double kStabilitySubsteps = 20.0;
// apart near the other body: free strides of substeps_per_duration / this many substeps
constexpr int64_t kApartStrideDivisor = 50;
constexpr int64_t kMaxSubstepsPerSample = int64_t{1} << 20;

// ---- beam finite elements ----

// the rod's mesh: node positions (m), two uniform parts either side of the contact node
struct BeamMesh {
  std::vector<double> x_m;  // (nodes) from the clamp
  int contact_node{0};
};

void CheckBeam(const BeamSpec& beam, int elements) {
  auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(beam.length_m)) {
    throw ConfigError(fmt::format("beam length_m must be positive, got {}", beam.length_m));
  }
  if (!positive(beam.flexural_rigidity_n_m2)) {
    throw ConfigError(fmt::format("beam flexural_rigidity_n_m2 (E I) must be positive, got {}",
                                  beam.flexural_rigidity_n_m2));
  }
  if (!positive(beam.linear_density_kg_m)) {
    throw ConfigError(fmt::format("beam linear_density_kg_m (rho A) must be positive, got {}",
                                  beam.linear_density_kg_m));
  }
  const double a = beam.contact_from_clamp_m;
  if (!(a > 0.0 && a <= beam.length_m) || (beam.clamped_both_ends && a >= beam.length_m)) {
    throw ConfigError(
        fmt::format("beam contact_from_clamp_m must lie in (0, {}{} m (the rod's length), got {}",
                    beam.length_m, beam.clamped_both_ends ? ")" : "]", a));
  }
  if (!(std::isfinite(beam.loss_factor) && beam.loss_factor >= 0.0 && beam.loss_factor < 2.0)) {
    throw ConfigError(fmt::format("beam loss_factor must lie in [0, 2), got {}", beam.loss_factor));
  }
  if (elements < 2) throw ConfigError(fmt::format("beam elements must be >= 2, got {}", elements));
}

BeamMesh MakeMesh(const BeamSpec& beam, int elements) {
  const double length = beam.length_m, a = beam.contact_from_clamp_m;
  // elements either side of the contact, in proportion to the lengths (at least one each)
  int inner = elements;
  if (a < length) {
    inner = static_cast<int>(std::lround(elements * a / length));
    inner = std::clamp(inner, 1, elements - 1);
  }
  const int outer = elements - inner;
  BeamMesh mesh;
  mesh.x_m.reserve(static_cast<size_t>(elements) + 1);
  for (int i = 0; i <= inner; ++i) mesh.x_m.push_back(a * i / inner);
  for (int i = 1; i <= outer; ++i) mesh.x_m.push_back(a + (length - a) * i / outer);
  mesh.contact_node = inner;
  return mesh;
}

// the rod's modes: omega (rad/s, ascending), mass-normalized shapes over the free DOFs, and the
// free-DOF index of the contact node's displacement; only modes the mesh resolves
struct BeamModes {
  Eigen::VectorXd omega_rad_s;   // (modes)
  Eigen::MatrixXd shapes;        // (free dofs x modes), shapes^T M shapes = I
  Eigen::Index contact_dof{-1};  // row of the contact displacement in shapes
};

BeamModes SolveBeam(const BeamSpec& beam, int elements, double max_frequency_hz) {
  CheckBeam(beam, elements);
  const BeamMesh mesh = MakeMesh(beam, elements);
  const int nodes = static_cast<int>(mesh.x_m.size());
  const int dofs = 2 * nodes;  // per node: w (m), w' (rad)
  const double ei = beam.flexural_rigidity_n_m2, rho_a = beam.linear_density_kg_m;

  // assemble Hermite-cubic stiffness and consistent mass (dofs x dofs)
  Eigen::MatrixXd k = Eigen::MatrixXd::Zero(dofs, dofs), m = Eigen::MatrixXd::Zero(dofs, dofs);
  double largest_element_m = 0.0;
  for (int e = 0; e + 1 < nodes; ++e) {
    const double l = mesh.x_m[e + 1] - mesh.x_m[e];
    largest_element_m = std::max(largest_element_m, l);
    Eigen::Matrix4d ke, me;
    ke << 12, 6 * l, -12, 6 * l, 6 * l, 4 * l * l, -6 * l, 2 * l * l, -12, -6 * l, 12, -6 * l,
        6 * l, 2 * l * l, -6 * l, 4 * l * l;
    me << 156, 22 * l, 54, -13 * l, 22 * l, 4 * l * l, 13 * l, -3 * l * l, 54, 13 * l, 156, -22 * l,
        -13 * l, -3 * l * l, -22 * l, 4 * l * l;
    k.block<4, 4>(2 * e, 2 * e) += ei / (l * l * l) * ke;
    m.block<4, 4>(2 * e, 2 * e) += rho_a * l / 420.0 * me;
  }

  // clamp: drop w and w' at x = 0 (and at x = L)
  const int first = 2, last = beam.clamped_both_ends ? dofs - 2 : dofs;
  const int free = last - first;
  const Eigen::MatrixXd kf = k.block(first, first, free, free);
  const Eigen::MatrixXd mf = m.block(first, first, free, free);

  // generalized eigenproblem K v = omega^2 M v; Eigen normalizes v^T M v = 1
  Eigen::GeneralizedSelfAdjointEigenSolver<Eigen::MatrixXd> solver(kf, mf);
  if (solver.info() != Eigen::Success) {
    throw NumericalError("beam modes: the generalized eigenproblem failed to converge");
  }
  const Eigen::VectorXd lambda = solver.eigenvalues();  // (free) ascending, rad^2/s^2

  // keep modes the mesh resolves: at least 2 of the largest elements per half flexural
  // wavelength (k l <= pi / 2, k = (omega^2 rho A / EI)^(1/4)), and never the top third of the
  // FE spectrum
  const double k_max_rad_m = kPi / (2.0 * largest_element_m);
  const double omega_resolved = k_max_rad_m * k_max_rad_m * std::sqrt(ei / rho_a);
  const double omega_cap = max_frequency_hz > 0.0 ? 2.0 * kPi * max_frequency_hz
                                                  : std::numeric_limits<double>::infinity();
  const Eigen::Index spectrum_cap = (2 * free) / 3;
  Eigen::Index kept = 0;
  while (kept < spectrum_cap && lambda[kept] > 0.0) {
    const double omega = std::sqrt(lambda[kept]);
    if (omega > omega_resolved || omega > omega_cap) break;
    ++kept;
  }
  BeamModes modes;
  modes.omega_rad_s = lambda.head(kept).cwiseSqrt();
  modes.shapes = solver.eigenvectors().leftCols(kept);
  modes.contact_dof = 2 * mesh.contact_node - first;
  return modes;
}

// ---- contact integrator ----

// exact one-step maps of y'' + 2 zeta omega y' + omega^2 y = u over a step h, u held:
// [y; y'](h) = [e11 e12; e21 e22] [y; y'](0) + [g1; e12] u
struct StepMap {
  double e11, e12, e21, e22, g1;
};

StepMap OscillatorStep(double omega, double zeta, double h) {
  StepMap s{};
  if (zeta < 1.0) {
    // underdamped closed form; g1 = (1 - e11) / omega^2 rearranged against cancellation
    const double sigma = zeta * omega, omega_d = omega * std::sqrt(1.0 - zeta * zeta);
    const double decay = std::exp(-sigma * h);
    const double c = std::cos(omega_d * h), sn = std::sin(omega_d * h);
    const double half_sin = std::sin(0.5 * omega_d * h);
    s.e11 = decay * (c + sigma / omega_d * sn);
    s.e12 = decay * sn / omega_d;
    s.e21 = -decay * omega * omega / omega_d * sn;
    s.e22 = decay * (c - sigma / omega_d * sn);
    const double one_minus_e11 =
        -std::expm1(-sigma * h) + decay * (2.0 * half_sin * half_sin - sigma / omega_d * sn);
    s.g1 = one_minus_e11 / (omega * omega);
    return s;
  }
  // critically or over-damped (rare): augmented matrix exponential
  Eigen::Matrix3d a = Eigen::Matrix3d::Zero();
  a(0, 1) = 1.0;
  a(1, 0) = -omega * omega;
  a(1, 1) = -2.0 * zeta * omega;
  a(1, 2) = 1.0;
  const Eigen::Matrix3d e = (a * h).exp();
  s.e11 = e(0, 0);
  s.e12 = e(0, 1);
  s.e21 = e(1, 0);
  s.e22 = e(1, 1);
  s.g1 = e(0, 2);
  return s;
}

void CheckBody(const DrivingPoint& body, const char* side) {
  const Eigen::Index n = body.omega_rad_s.size();
  if (body.zeta.size() != n || body.phi.size() != n) {
    throw ConfigError(
        fmt::format("contact {}: omega_rad_s, zeta and phi differ in length ({}, {}, {})", side, n,
                    body.zeta.size(), body.phi.size()));
  }
  if (!(body.rigid_mass_kg > 0.0)) {
    throw ConfigError(fmt::format("contact {}: rigid_mass_kg must be positive (inf = held), got {}",
                                  side, body.rigid_mass_kg));
  }
  for (Eigen::Index i = 0; i < n; ++i) {
    const double w = body.omega_rad_s[i], z = body.zeta[i], p = body.phi[i];
    if (!(std::isfinite(w) && w > 0.0 && std::isfinite(z) && z >= 0.0 && std::isfinite(p))) {
      throw ConfigError(fmt::format(
          "contact {}: mode {} needs omega_rad_s > 0, zeta >= 0 and a finite phi, got {}, {}, {}",
          side, i, w, z, p));
    }
  }
}

// both bodies reduced to the compression delta = x_tube - x_striker: a rigid part with inverse
// mass 1/m_tube + 1/m_striker and modes y_i = phi_i q_i (the striker's sign flipped), each
// y_i'' + 2 zeta_i omega_i y_i' + omega_i^2 y_i = -gain_i F, gain_i = phi_i^2
struct Reduced {
  double inv_mass_per_kg{0.0};
  Eigen::ArrayXd omega_rad_s, zeta, gain_per_kg;  // (modes)
};

// what one pass at a fixed substep needs besides the bodies
struct PassSetup {
  double stiffness_n_m15, v_m_s, time_s, sample_rate_hz;
  int64_t per_sample;     // substeps per audio sample
  int64_t apart_stride;   // substeps per free step while apart near the other body
  int64_t restart_below;  // abandon the pass when the first closure is shorter (substeps)
  int64_t restart_above;  // ... or longer (substeps)
};

// one pass of the contact solve at a fixed substep
struct Pass {
  ContactForce result;
  bool restart{false};                // the first closure fell outside the wanted substep band
  int64_t first_closure_substeps{0};  // length of the first closure, substeps
};

// One pass of the contact solve at a fixed substep h: both bodies reduced to the compression,
// stepped exactly for the force held over each substep (midpoint predictor), with whole free
// samples or strides while apart. Time runs from the start of the sample holding time_s; the
// bodies start apart on the substep grid, closing at v with the modes at rest, so that they
// touch exactly at time_s.
class SubstepSolver {
 public:
  SubstepSolver(const Reduced& body, const PassSetup& setup, const ContactConfig& config);
  Pass Run();

 private:
  void BuildMaps();
  double Force(double delta, double rate) const;
  void CheckProgress(double t_s, double delta, double rate) const;
  bool FreeWhileApart(double delta, double rate);
  bool FreeStep(int col, int64_t substeps, double dt_s, double delta, double rate, bool certain);
  bool ForcedSubstep(double t_s, double delta, double rate);
  void Finish();

  const Reduced& body_;
  const PassSetup& setup_;
  const ContactConfig& config_;
  Eigen::Index n_;  // modes
  double period_s_, h_, stride_s_;
  // per-mode maps (modes x 18): half step e11 e12 e21 e22 (predictor) | substep e11 e12 e21 e22
  // | substep input (x gain) g1 g2 | stride e11..e22 | sample e11..e22 (both free, apart)
  Eigen::ArrayXXd map_;
  Eigen::ArrayXd inv_omega_sq_;         // (modes) s^2
  double half_g1_{0.0}, half_g2_{0.0};  // sum of gain x half-step input response, m/N, m/(N s)
  double touch_s_;                      // from the origin, [0, T)
  // the state: substep count, rigid part x (m) and its rate (m/s), modal parts y (m), y' (m/s)
  // with the next state built beside them, then swapped, and their sums over the modes
  int64_t step_;
  double x_m_, xd_m_s_;
  Eigen::ArrayXd y_, yd_, y_next_, yd_next_;
  double sum_y_{0.0}, sum_yd_{0.0};
  Pass pass_;
  bool closed_{false};
  int64_t touches_{0}, closure_start_{0}, fine_until_{0};
  double modal_reach_{-1.0};  // m, the modes' energy bound while free; < 0 = to compute
  double release_s_;          // the last release, from the origin
  double give_up_s_;
};

SubstepSolver::SubstepSolver(const Reduced& body, const PassSetup& setup,
                             const ContactConfig& config)
    : body_(body),
      setup_(setup),
      config_(config),
      n_(body.omega_rad_s.size()),
      period_s_(1.0 / setup.sample_rate_hz),
      h_(period_s_ / static_cast<double>(setup.per_sample)),
      stride_s_(h_ * static_cast<double>(setup.apart_stride)) {
  BuildMaps();
  const double first_sample_f = std::floor(setup.time_s * setup.sample_rate_hz);
  touch_s_ = setup.time_s - first_sample_f * period_s_;
  step_ = static_cast<int64_t>(std::floor(touch_s_ / h_));
  x_m_ = -setup.v_m_s * (touch_s_ - static_cast<double>(step_) * h_);
  xd_m_s_ = setup.v_m_s;
  y_ = Eigen::ArrayXd::Zero(n_);
  yd_ = Eigen::ArrayXd::Zero(n_);
  y_next_.resize(n_);
  yd_next_.resize(n_);
  pass_.result.first_sample = static_cast<int64_t>(first_sample_f);
  pass_.result.force_n.reserve(16);  // N s per audio sample until the end, then / T
  release_s_ = touch_s_;
  give_up_s_ = touch_s_ + config.max_duration_s;
}

void SubstepSolver::BuildMaps() {
  const Eigen::ArrayXd& omega = body_.omega_rad_s;
  map_.resize(n_, 18);
  inv_omega_sq_ = omega.square().inverse();
  for (Eigen::Index i = 0; i < n_; ++i) {
    const StepMap half = OscillatorStep(omega[i], body_.zeta[i], 0.5 * h_);
    const StepMap full = OscillatorStep(omega[i], body_.zeta[i], h_);
    const StepMap strided = OscillatorStep(omega[i], body_.zeta[i], stride_s_);
    const StepMap sample = OscillatorStep(omega[i], body_.zeta[i], period_s_);
    const double g = body_.gain_per_kg[i];
    map_.row(i) << half.e11, half.e12, half.e21, half.e22, full.e11, full.e12, full.e21, full.e22,
        g * full.g1, g * full.e12, strided.e11, strided.e12, strided.e21, strided.e22, sample.e11,
        sample.e12, sample.e21, sample.e22;
    half_g1_ += g * half.g1;
    half_g2_ += g * half.e12;
  }
}

// contact force (N) from compression (m) and its rate (m/s); Hunt-Crossley never pulls
double SubstepSolver::Force(double delta, double rate) const {
  if (delta <= 0.0) return 0.0;
  const double bracket = 1.0 + config_.hunt_crossley_s_m * rate;
  return bracket > 0.0 ? setup_.stiffness_n_m15 * delta * std::sqrt(delta) * bracket : 0.0;
}

// a non-finite state, or a contact that does not end, is an error
void SubstepSolver::CheckProgress(double t_s, double delta, double rate) const {
  if (!std::isfinite(delta) || !std::isfinite(rate)) {
    throw NumericalError(fmt::format(
        "contact solve turned non-finite {:.3g} s after the touch ({} substeps per sample)",
        t_s - touch_s_, setup_.per_sample));
  }
  if (t_s > give_up_s_ && (closed_ || t_s > give_up_s_ + config_.separation_window_s)) {
    throw NumericalError(fmt::format(
        "contact not over {:.3g} s after the first touch ({} touches): over "
        "acoustics.contact.max_duration_s = {} s (a heavy side pressing into a compliant one "
        "takes long to push back)",
        t_s - touch_s_, touches_, config_.max_duration_s));
  }
}

// apart: a whole free sample when no mode can reach across the gap in it (energy bound
// |y_i(t)| <= sqrt(y_i^2 + (y_i'/omega_i)^2), which only shrinks while free, so it is kept
// until a force acts), else a free stride when it shows no contact; false: take substeps
bool SubstepSolver::FreeWhileApart(double delta, double rate) {
  const double rigid_reach = std::max(x_m_, x_m_ + xd_m_s_ * period_s_);
  if (rigid_reach < 0.0 && modal_reach_ < 0.0) {
    modal_reach_ = (y_.square() + yd_.square() * inv_omega_sq_).sqrt().sum();
  }
  if (rigid_reach < 0.0 && rigid_reach + modal_reach_ < 0.0 &&
      FreeStep(14, setup_.per_sample, period_s_, delta, rate, true)) {
    return true;
  }
  if (setup_.apart_stride > 1 && FreeStep(10, setup_.apart_stride, stride_s_, delta, rate, false))
    return true;
  fine_until_ = step_ + setup_.apart_stride;  // this stride closes: take it in substeps
  return false;
}

// a free step of `substeps` substeps with map columns from `col` into the next state; kept
// when no contact can have happened inside it
bool SubstepSolver::FreeStep(int col, int64_t substeps, double dt_s, double delta, double rate,
                             bool certain) {
  y_next_ = map_.col(col) * y_ + map_.col(col + 1) * yd_;
  yd_next_ = map_.col(col + 2) * y_ + map_.col(col + 3) * yd_;
  const double x_end = x_m_ + xd_m_s_ * dt_s;
  const double delta_end = x_end + y_next_.sum(), rate_end = xd_m_s_ + yd_next_.sum();
  ++pass_.result.substeps;
  if (!certain) {
    // refused when closed at the end, or when the cubic through both ends peaks above zero
    if (delta_end > 0.0) return false;
    const double a = rate * dt_s, b = rate_end * dt_s;
    const double c2 = 3.0 * (delta_end - delta) - 2.0 * a - b;
    const double c3 = 2.0 * (delta - delta_end) + a + b;
    // roots of the cubic's slope a + 2 c2 s + 3 c3 s^2 on (0, 1)
    const double qa = 3.0 * c3, qb = 2.0 * c2, qc = a;
    const double disc = qb * qb - 4.0 * qa * qc;
    if (disc >= 0.0 && qa != 0.0) {
      for (const double sgn : {-1.0, 1.0}) {
        const double s = (-qb + sgn * std::sqrt(disc)) / (2.0 * qa);
        if (s > 0.0 && s < 1.0 && delta + s * (a + s * (c2 + s * c3)) > 0.0) return false;
      }
    } else if (qa == 0.0 && qb != 0.0) {
      const double s = -qc / qb;
      if (s > 0.0 && s < 1.0 && delta + s * (a + s * (c2 + s * c3)) > 0.0) return false;
    }
  }
  y_.swap(y_next_);
  yd_.swap(yd_next_);
  x_m_ = x_end;
  sum_y_ = delta_end - x_end;
  sum_yd_ = rate_end - xd_m_s_;
  step_ += substeps;
  return true;
}

// One substep under the midpoint force, its impulse, and the touches and releases; true when
// the first closure falls outside the wanted substep band (the pass must restart).
bool SubstepSolver::ForcedSubstep(double t_s, double delta, double rate) {
  const double h = h_, inv_mass = body_.inv_mass_per_kg;
  ContactForce& out = pass_.result;
  std::vector<double>& impulse = out.force_n;
  const size_t sample = static_cast<size_t>(step_ / setup_.per_sample);
  if (impulse.size() <= sample) impulse.resize(sample + 1, 0.0);

  // midpoint predictor: the half-step state under the force at the step start
  const double f0 = Force(delta, rate);
  const double delta_mid = x_m_ + 0.5 * h * xd_m_s_ - 0.125 * h * h * inv_mass * f0 +
                           (map_.col(0) * y_ + map_.col(1) * yd_).sum() - half_g1_ * f0;
  const double rate_mid = xd_m_s_ - 0.5 * h * inv_mass * f0 +
                          (map_.col(2) * y_ + map_.col(3) * yd_).sum() - half_g2_ * f0;
  const double f = Force(delta_mid, rate_mid);

  // exact substep for the midpoint force held over it (rigid and modal parts)
  y_next_ = map_.col(4) * y_ + map_.col(5) * yd_ - map_.col(8) * f;
  yd_next_ = map_.col(6) * y_ + map_.col(7) * yd_ - map_.col(9) * f;
  y_.swap(y_next_);
  yd_.swap(yd_next_);
  x_m_ += h * xd_m_s_ - 0.5 * h * h * inv_mass * f;
  xd_m_s_ -= h * inv_mass * f;
  sum_y_ = y_.sum();
  sum_yd_ = yd_.sum();
  ++step_;
  ++out.substeps;

  // the impulse into its audio sample; touches and releases
  if (f != 0.0) modal_reach_ = -1.0;
  impulse[sample] += f * h;
  out.impulse_ns += f * h;
  out.peak_force_n = std::max(out.peak_force_n, f);
  const double delta_end = x_m_ + sum_y_, rate_end = xd_m_s_ + sum_yd_;
  if (!closed_ && delta_end > 0.0) {
    closed_ = true;
    ++touches_;
    closure_start_ = step_ - 1;
  } else if (closed_ && delta_end <= 0.0) {
    // release inside the substep, by linear interpolation of the compression
    closed_ = false;
    const double frac = delta > 0.0 ? delta / (delta - delta_end) : 0.0;
    release_s_ = t_s + frac * h;
    out.rebound_speed_m_s = -(rate + frac * (rate_end - rate));
    if (touches_ == 1) {
      out.first_closure_s = release_s_ - touch_s_;
      pass_.first_closure_substeps = step_ - closure_start_;
      if (pass_.first_closure_substeps < setup_.restart_below ||
          pass_.first_closure_substeps > setup_.restart_above) {
        pass_.restart = true;
        return true;
      }
    }
  }
  return false;
}

// trim to the sample of the final release (less a trailing sample whose only substep held no
// force); impulses to sample-averaged forces
void SubstepSolver::Finish() {
  ContactForce& out = pass_.result;
  std::vector<double>& impulse = out.force_n;
  const size_t last = static_cast<size_t>(std::floor(release_s_ / period_s_));
  impulse.resize(std::min(impulse.size(), last + 1));
  while (!impulse.empty() && impulse.back() == 0.0) impulse.pop_back();
  for (double& v : impulse) v /= period_s_;
  out.duration_s = release_s_ - touch_s_;
  out.touches = touches_;
}

Pass SubstepSolver::Run() {
  for (;;) {
    const double t_s = static_cast<double>(step_) * h_;
    const double delta = x_m_ + sum_y_, rate = xd_m_s_ + sum_yd_;
    CheckProgress(t_s, delta, rate);
    // done once apart for the separation window with the rigid parts not closing (a rigid
    // part still closing meets the other body again: the modal parts are bounded)
    if (!closed_ && touches_ > 0 && t_s - release_s_ >= config_.separation_window_s &&
        xd_m_s_ <= 0.0) {
      break;
    }
    if (!closed_ && delta < 0.0 && step_ >= fine_until_ && FreeWhileApart(delta, rate)) continue;
    if (ForcedSubstep(t_s, delta, rate)) return pass_;
  }
  Finish();
  return pass_;
}

Pass SolveAtSubsteps(const Reduced& body, const PassSetup& setup, const ContactConfig& config) {
  return SubstepSolver(body, setup, config).Run();
}

}  // namespace

double HertzDuration(double m_kg, double stiffness_n_m15, double v_m_s) {
  const double delta_max = std::pow(5.0 * m_kg * v_m_s * v_m_s / (4.0 * stiffness_n_m15), 0.4);
  return kHertzDuration * delta_max / v_m_s;
}

void ContactConfig::Serialize(Archive* a) {
  a->Visit("substeps_per_duration", &substeps_per_duration, Bounds::Closed(50, 100000));
  a->Visit("min_substeps", &min_substeps, Bounds::Closed(1, 4096));
  a->Visit("hunt_crossley_s_m", &hunt_crossley_s_m, Bounds::Closed(0.0, 100.0));
  a->Visit("separation_window_s", &separation_window_s, Bounds{0.0, 1.0, true, false});
  a->Visit("max_duration_s", &max_duration_s, Bounds{0.0, 10.0, true, false});
  a->Visit("beam_max_frequency_hz", &beam_max_frequency_hz, Bounds::Positive());
  a->Visit("wall", &wall);
}

Eigen::VectorXd BeamFrequenciesHz(const BeamSpec& beam, int elements, double max_frequency_hz) {
  return SolveBeam(beam, elements, max_frequency_hz).omega_rad_s / (2.0 * kPi);
}

DrivingPoint BeamDrivingPoint(const BeamSpec& beam, double max_frequency_hz) {
  constexpr int kElements = 48;
  // the same rods are struck again and again: each thread keeps its last few answers
  struct Entry {
    BeamSpec beam;
    double max_frequency_hz{-1.0};
    DrivingPoint point;
    bool used{false};
  };
  constexpr size_t kCached = 8;
  thread_local std::array<Entry, kCached> cache;
  thread_local size_t next_slot = 0;
  auto same = [&](const Entry& e) {
    const BeamSpec& b = e.beam;
    return e.used && e.max_frequency_hz == max_frequency_hz && b.length_m == beam.length_m &&
           b.flexural_rigidity_n_m2 == beam.flexural_rigidity_n_m2 &&
           b.linear_density_kg_m == beam.linear_density_kg_m &&
           b.contact_from_clamp_m == beam.contact_from_clamp_m &&
           b.clamped_both_ends == beam.clamped_both_ends && b.loss_factor == beam.loss_factor;
  };
  for (const Entry& e : cache) {
    if (same(e)) return e.point;
  }

  const BeamModes modes = SolveBeam(beam, kElements, max_frequency_hz);
  DrivingPoint point;  // held at the clamp: no rigid motion
  point.omega_rad_s = modes.omega_rad_s;
  point.zeta = Eigen::VectorXd::Constant(modes.omega_rad_s.size(), 0.5 * beam.loss_factor);
  point.phi = modes.shapes.row(modes.contact_dof).transpose();
  cache[next_slot] = Entry{beam, max_frequency_hz, point, true};
  next_slot = (next_slot + 1) % kCached;
  return point;
}

ContactForce SolveContact(const DrivingPoint& tube, const DrivingPoint& striker,
                          double stiffness_n_m15, double approach_speed_m_s, double time_s,
                          double sample_rate_hz, const ContactConfig& config) {
  CheckBody(tube, "tube");
  CheckBody(striker, "striker");
  if (!(std::isfinite(stiffness_n_m15) && stiffness_n_m15 > 0.0)) {
    throw ConfigError(
        fmt::format("contact: Hertz stiffness must be positive, got {} N/m^1.5", stiffness_n_m15));
  }
  if (!(std::isfinite(approach_speed_m_s) && approach_speed_m_s > 0.0)) {
    throw ConfigError(
        fmt::format("contact: approach speed must be positive, got {} m/s", approach_speed_m_s));
  }
  if (!(std::isfinite(sample_rate_hz) && sample_rate_hz > 0.0 && std::isfinite(time_s))) {
    throw ConfigError(
        fmt::format("contact: needs a positive sample rate and a finite time, got "
                    "{} Hz, {} s",
                    sample_rate_hz, time_s));
  }
  // relative rigid coordinate: (x_tube - x_striker)'' = -F (1/m_tube + 1/m_striker)
  const double inv_mass = 1.0 / tube.rigid_mass_kg + 1.0 / striker.rigid_mass_kg;
  if (inv_mass == 0.0) {
    throw ConfigError(
        "contact: the tube and the striker are both held (infinite rigid_mass_kg): closing at a "
        "constant speed they never release; give one side a finite mass");
  }

  // both bodies' modes as compression parts; modes that do not move the contact dropped
  Reduced body;
  body.inv_mass_per_kg = inv_mass;
  const Eigen::Index n_all = tube.omega_rad_s.size() + striker.omega_rad_s.size();
  body.omega_rad_s.resize(n_all);
  body.zeta.resize(n_all);
  body.gain_per_kg.resize(n_all);
  Eigen::Index n = 0;
  for (const DrivingPoint* side : {&tube, &striker}) {
    for (Eigen::Index i = 0; i < side->phi.size(); ++i) {
      if (side->phi[i] == 0.0) continue;
      body.omega_rad_s[n] = side->omega_rad_s[i];
      body.zeta[n] = side->zeta[i];
      body.gain_per_kg[n] = side->phi[i] * side->phi[i];
      ++n;
    }
  }
  body.omega_rad_s.conservativeResize(n);
  body.zeta.conservativeResize(n);
  body.gain_per_kg.conservativeResize(n);

  // substep: substeps_per_duration per contact time, first the rigid-mass Hertz duration; a
  // pass whose first closure takes under half or over twice that many substeps is abandoned at
  // its first release and redone on the measured length. The substep never exceeds 1/20 of the
  // Hertz time of the lightest mass the contact can see (all modes as masses), which keeps the
  // explicit force coupling stable. An integer number of substeps fits one audio sample.
  const double period_s = 1.0 / sample_rate_hz;
  const double spd = static_cast<double>(config.substeps_per_duration);
  const double lightest_kg = 1.0 / (inv_mass + body.gain_per_kg.sum());
  const double h_stable_s =
      HertzDuration(lightest_kg, stiffness_n_m15, approach_speed_m_s) / kStabilitySubsteps;
  double t_c = HertzDuration(1.0 / inv_mass, stiffness_n_m15, approach_speed_m_s);
  int64_t total_steps = 0;
  for (int attempt = 0;; ++attempt) {
    const double h_target = std::min(t_c / spd, h_stable_s);
    const double per_sample_f = std::ceil(period_s / h_target * (1.0 - 1e-12));
    if (!(per_sample_f <= static_cast<double>(kMaxSubstepsPerSample))) {
      throw NumericalError(fmt::format(
          "contact needs {:.3g} substeps per audio sample (contact time {:.3g} s): over the "
          "limit {}; lower acoustics.contact.substeps_per_duration",
          per_sample_f, t_c, kMaxSubstepsPerSample));
    }
    PassSetup setup{stiffness_n_m15,
                    approach_speed_m_s,
                    time_s,
                    sample_rate_hz,
                    0,
                    1,
                    0,
                    std::numeric_limits<int64_t>::max()};
    setup.per_sample = std::max<int64_t>(config.min_substeps, static_cast<int64_t>(per_sample_f));
    setup.apart_stride = std::max<int64_t>(1, config.substeps_per_duration / kApartStrideDivisor);
    if (attempt < kMaxResolves) {
      setup.restart_below = static_cast<int64_t>(kResolveFraction * spd);
      // longer closures only matter when the substep can still grow
      if (setup.per_sample > config.min_substeps && h_target < h_stable_s) {
        setup.restart_above = static_cast<int64_t>(spd / kResolveFraction);
      }
    }
    Pass pass = SolveAtSubsteps(body, setup, config);
    total_steps += pass.result.substeps;
    if (!pass.restart) {
      pass.result.substeps = total_steps;
      return std::move(pass.result);
    }
    // redo with the substep sized on the first closure's measured length
    t_c = static_cast<double>(pass.first_closure_substeps) * period_s /
          static_cast<double>(setup.per_sample);
  }
}

}  // namespace sonicboom::acoustics
