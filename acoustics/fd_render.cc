#include "sonicboom/acoustics/fd_render.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

#include <fmt/format.h>

#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

// an FD impact's shortest closure spans at least this many steps
constexpr double kStepsPerClosure = 8.0;
using Terms = std::vector<std::pair<int64_t, double>>;  // (DOF, coefficient)

// the nonzero entries of a dense row
Terms SparseRow(const Eigen::VectorXd& row) {
  Terms terms;
  for (Eigen::Index d = 0; d < row.size(); ++d) {
    if (row[d] != 0.0) terms.push_back({d, row[d]});
  }
  return terms;
}

double Dot(const Terms& terms, const Eigen::VectorXd& u) {
  double sum = 0.0;
  for (const auto& [d, w] : terms) sum += w * u[d];
  return sum;
}

// A prescribed force's value at time t (audio samples): a sample's force is its interval's mean,
// placed mid-sample, linear between
double ForceAt(const ForceInput& f, double t_samples) {
  const double x = t_samples - 0.5 - static_cast<double>(f.first_sample);
  const int64_t i = static_cast<int64_t>(std::floor(x));
  const double frac = x - std::floor(x);
  const auto at = [&](int64_t j) {
    return j >= 0 && j < static_cast<int64_t>(f.force_n.size()) ? f.force_n[static_cast<size_t>(j)]
                                                                : 0.0;
  };
  return (1 - frac) * at(i) + frac * at(i + 1);
}

// One impact closed against the FD wall, step by step. Positions on the approach axis (positive
// from the tube towards the striker): compression delta = tube rigid part + wall's outward
// displacement at the point - striker rigid part - striker modes. Every body steps by central
// differences with the force F_n of step n, taken implicitly on the average of the neighbouring
// compressions: F_n = K dbar^1.5 (1 + lambda (delta_n+1 - delta_n-1) / 2h), dbar = (delta_n+1 +
// delta_n-1) / 2, where delta_n+1 is linear in F_n (compliance G). Like the average-acceleration
// treatment of a stiff spring, this keeps the scheme second order and stable for any contact
// stiffness.
class WallImpact {
 public:
  WallImpact(const FdImpact& spec, const ShellModel& model, const ShellFd& fd,
             const ContactConfig& config, double sample_rate_hz)
      : spec_(spec),
        config_(config),
        h_(fd.timestep_s()),
        over_(fd.oversampling()),
        nodes_(SparseRow(model.RadialForceWeights(spec.z_m, spec.theta_rad))) {
    if (!(spec.approach_speed_m_s > 0.0) || !(spec.stiffness_n_m15 > 0.0)) {
      throw ConfigError(fmt::format(
          "FD impact at t = {} s: approach speed {} m/s and Hertz constant {} must be positive",
          spec.time_s, spec.approach_speed_m_s, spec.stiffness_n_m15));
    }
    const Eigen::VectorXd& gain = fd.force_gain();
    for (const auto& [d, w] : nodes_) wall_compliance_ += w * w * gain[d];
    tube_inv_mass_ = spec.tube_side_kg > 0 && std::isfinite(spec.tube_side_kg)
                         ? 1.0 / spec.tube_side_kg
                         : 0.0;
    striker_inv_mass_ =
        std::isfinite(spec.striker.rigid_mass_kg) ? 1.0 / spec.striker.rigid_mass_kg : 0.0;
    // the striker's modes this step resolves (omega h < 1; central differences need < 2)
    for (Eigen::Index i = 0; i < spec.striker.omega_rad_s.size(); ++i) {
      if (spec.striker.omega_rad_s[i] * h_ < 1.0) modes_.push_back(i);
    }
    q_ = q_prev_ = q_free_ = Eigen::VectorXd::Zero(static_cast<Eigen::Index>(modes_.size()));
    // each stepped mode's response to the step's force, and their sum at the contact
    q_gain_.resize(q_.size());
    for (size_t k = 0; k < modes_.size(); ++k) {
      const Eigen::Index i = modes_[k];
      const double c = spec.striker.zeta[i] * spec.striker.omega_rad_s[i] * h_;
      const double phi = spec.striker.phi[i];
      q_gain_[static_cast<Eigen::Index>(k)] = h_ * h_ * phi / (1 + c);
      modes_compliance_ += phi * q_gain_[static_cast<Eigen::Index>(k)];
    }
    CheckResolved(model, sample_rate_hz);
    start_step_ = static_cast<int64_t>(std::ceil(spec.time_s / h_));
    result_.first_sample = static_cast<int64_t>(std::floor(spec.time_s * sample_rate_hz));
  }

  bool done() const { return done_; }
  const ContactForce& result() const { return result_; }

  // After the FD step from n to n + 1 = next_step: u_now at n, u_next at n + 1 with the
  // prescribed forces; adds the impact's force of the step to u_next.
  void Close(int64_t next_step, const Eigen::VectorXd& u_now, Eigen::VectorXd* u_next,
             const Eigen::VectorXd& gain) {
    if (done_ || next_step < start_step_) return;
    if (next_step == start_step_) Start(next_step - 1, u_now);
    const double h2 = h_ * h_;
    // each body's position at n + 1 without the force, and its compliance to it
    const double tube_free = 2 * tube_ - tube_prev_;
    const double striker_free = 2 * striker_ - striker_prev_;
    double modes_free = 0.0;
    for (size_t k = 0; k < modes_.size(); ++k) {
      const Eigen::Index i = modes_[k];
      const double w = spec_.striker.omega_rad_s[i], c = spec_.striker.zeta[i] * w * h_;
      const auto j = static_cast<Eigen::Index>(k);
      q_free_[j] = (2 * q_[j] - (1 - c) * q_prev_[j] - h2 * w * w * q_[j]) / (1 + c);
      modes_free += spec_.striker.phi[i] * q_free_[j];
    }
    const double wall_free = Dot(nodes_, *u_next) - wall_ref_;
    const double d0 = tube_free + wall_free - striker_free - modes_free;
    const double g = h2 * tube_inv_mass_ + wall_compliance_ + h2 * striker_inv_mass_ +
                     modes_compliance_;
    const double force = SolveForce(d0, g);
    // advance every body with it
    tube_prev_ = tube_;
    tube_ = tube_free - h2 * tube_inv_mass_ * force;
    striker_prev_ = striker_;
    striker_ = striker_free + h2 * striker_inv_mass_ * force;
    q_prev_.swap(q_);
    q_ = q_free_ + force * q_gain_;
    for (const auto& [d, w] : nodes_) (*u_next)[d] -= gain[d] * w * force;
    const double delta_next = d0 - g * force;
    Record(next_step - 1, force, delta_next);
    delta_prev_ = delta_;
    delta_ = delta_next;
  }

 private:
  // the state one step before the first touch: the tube's rigid part closing at the approach
  // speed, the striker and its modes at rest, the wall where it is (its displacement there is
  // the reference of the compression)
  void Start(int64_t step, const Eigen::VectorXd& u_now) {
    const double v = spec_.approach_speed_m_s;
    tube_ = v * (static_cast<double>(step) * h_ - spec_.time_s);
    tube_prev_ = tube_ - v * h_;
    wall_ref_ = Dot(nodes_, u_now);
    delta_ = tube_;
    delta_prev_ = tube_prev_;
  }

  // The shortest closure the impact can have: the striker on the grid's own mass at the point
  // (1 / sum w^2 / m over its nodes). An implicit force stays stable on any step, but a closure
  // spanning fewer than kStepsPerClosure steps is smeared: refused naming the oversampling.
  void CheckResolved(const ShellModel& model, double sample_rate_hz) const {
    double inv_local = 0.0;
    for (const auto& [d, w] : nodes_) inv_local += w * w / model.mass_kg()[d];
    const double reduced_kg = 1.0 / (inv_local + striker_inv_mass_);
    const double closure_s =
        HertzDuration(reduced_kg, spec_.stiffness_n_m15, spec_.approach_speed_m_s);
    if (closure_s >= kStepsPerClosure * h_) return;
    const auto needed = static_cast<int64_t>(
        std::ceil(kStepsPerClosure / (closure_s * sample_rate_hz)));
    throw NumericalError(fmt::format(
        "FD impact at t = {} s: its closure on the wall's local mass ({:.3g} kg) lasts about "
        "{:.3g} us, under {} FD steps of {:.3g} us; set acoustics.fd_oversampling >= {} (now {})",
        spec_.time_s, 1.0 / inv_local, 1e6 * closure_s, kStepsPerClosure, 1e6 * h_, needed,
        over_));
  }

  // F >= 0 with F = K dbar^1.5 (1 + lambda rate), dbar = (d0 - g F + delta_n-1) / 2: bisection
  // on the monotone residual
  double SolveForce(double d0, double g) const {
    if (d0 + delta_prev_ <= 0.0) return 0.0;
    const auto residual = [&](double f) {
      const double next = d0 - g * f;
      const double d = 0.5 * (next + delta_prev_);
      if (d <= 0.0) return f;
      const double rate_factor =
          1.0 + config_.hunt_crossley_s_m * (next - delta_prev_) / (2.0 * h_);
      return f - spec_.stiffness_n_m15 * d * std::sqrt(d) * std::max(rate_factor, 0.0);
    };
    double lo = 0.0, hi = (d0 + delta_prev_) / g;
    for (int it = 0; it < 100 && hi - lo > 1e-14 * hi; ++it) {
      const double mid = 0.5 * (lo + hi);
      (residual(mid) > 0.0 ? hi : lo) = mid;
    }
    return 0.5 * (lo + hi);
  }

  // the force's audio-rate means and the contact's figures; ends the impact once apart for the
  // separation window with the rigid parts not closing
  void Record(int64_t step, double force, double delta_next) {
    ContactForce& r = result_;
    ++r.substeps;
    const double t = static_cast<double>(step) * h_;  // the force's time
    const int64_t sample = step / over_;
    const int64_t j = sample - r.first_sample;
    if (force > 0.0 && j >= 0) {
      if (static_cast<int64_t>(r.force_n.size()) <= j) r.force_n.resize(static_cast<size_t>(j + 1));
      r.force_n[static_cast<size_t>(j)] += force / static_cast<double>(over_);
    }
    r.impulse_ns += force * h_;
    r.peak_force_n = std::max(r.peak_force_n, force);
    if (force > 0.0 && !touching_) {
      ++r.touches;
      if (r.touches == 1) first_touch_s_ = t;
    }
    if (force <= 0.0 && touching_) {
      release_s_ = t;
      if (r.touches == 1 && r.first_closure_s == 0.0) r.first_closure_s = t - first_touch_s_;
      r.duration_s = t - first_touch_s_;
      r.rebound_speed_m_s = (delta_prev_ - delta_next) / (2.0 * h_);
    }
    touching_ = force > 0.0;
    const double closing = (tube_ - tube_prev_) - (striker_ - striker_prev_);
    if (!touching_ && r.touches > 0 && t - release_s_ >= config_.separation_window_s &&
        closing <= 0.0) {
      done_ = true;
    }
    if (!done_ && t - spec_.time_s > config_.max_duration_s) {
      throw NumericalError(fmt::format(
          "FD impact at t = {} s (z = {} m) is still closed after "
          "acoustics.contact.max_duration_s = {} s",
          spec_.time_s, spec_.z_m, config_.max_duration_s));
    }
  }

  FdImpact spec_;
  ContactConfig config_;
  double h_;
  int64_t over_;
  Terms nodes_;                   // the wall point: outward weights of the four nodes
  double wall_compliance_{0.0};   // sum w^2 (step gain): the wall's give within a step, m/N
  double tube_inv_mass_{0.0}, striker_inv_mass_{0.0};
  std::vector<Eigen::Index> modes_;  // the striker's modes stepped
  int64_t start_step_{0};
  double tube_{0.0}, tube_prev_{0.0}, striker_{0.0}, striker_prev_{0.0};
  Eigen::VectorXd q_, q_prev_;  // (modes) striker modal coordinates
  Eigen::VectorXd q_free_;      // (modes) scratch: the coordinates a step gives without force
  Eigen::VectorXd q_gain_;      // (modes) h^2 phi / (1 + zeta omega h): a step's response to F
  double modes_compliance_{0.0};  // sum phi q_gain: the striker modes' give within a step, m/N
  double wall_ref_{0.0}, delta_{0.0}, delta_prev_{0.0};  // compressions at n and n - 1, m
  bool touching_{false}, done_{false};
  double first_touch_s_{0.0}, release_s_{0.0};
  ContactForce result_;
};

// Zero-phase anti-aliasing decimator: a Blackman-windowed sinc over 64 audio samples at the
// substep rate, cut-off 0.45 of the audio rate, fed one substep at a time
class Decimator {
 public:
  Decimator(int64_t over, Eigen::Index outputs)
      : over_(over), half_(32 * over), taps_(2 * half_ + 1), ring_(outputs, 2 * half_ + 1) {
    const double cutoff = 0.45 / static_cast<double>(over);  // cycles per substep
    const auto n = static_cast<double>(taps_.size() - 1);
    double sum = 0.0;
    for (Eigen::Index j = 0; j < taps_.size(); ++j) {
      const double m = static_cast<double>(j - half_);
      const double sinc = m == 0.0 ? 1.0 : std::sin(2 * kPi * cutoff * m) / (2 * kPi * cutoff * m);
      const double window = 0.42 - 0.5 * std::cos(2 * kPi * j / n) + 0.08 * std::cos(4 * kPi * j / n);
      taps_[j] = sinc * window;
      sum += taps_[j];
    }
    taps_ /= sum;
    ring_.setZero();
  }
  int64_t delay() const { return half_; }

  // s = the outputs at substep n (pushed in order from 0); writes the audio sample it completes
  void Push(int64_t n, const Eigen::VectorXd& s, Eigen::MatrixXd* out) {
    const Eigen::Index width = ring_.cols();
    ring_.col(n % width) = s;
    if (n < half_ || (n - half_) % over_ != 0) return;
    const int64_t k = (n - half_) / over_;
    if (k >= out->cols()) return;
    // y[k] = sum_j taps[j] s[n - 2 half + j], summed in place (no allocation per sample)
    auto y = out->col(k);
    y.setZero();
    for (Eigen::Index j = 0; j < width; ++j) {
      const int64_t m = n - 2 * half_ + j;
      if (m >= 0) y += taps_[j] * ring_.col(m % width);
    }
  }

 private:
  int64_t over_, half_;
  Eigen::VectorXd taps_;  // (2 half + 1)
  Eigen::MatrixXd ring_;  // (outputs x 2 half + 1) the last substeps' outputs
};

}  // namespace

FdRun FdRender(const ShellModel& model, const ShellFd& fd, std::span<const ForceInput> forces,
               std::span<const FdImpact> impacts, const ContactConfig& contact,
               const Eigen::MatrixXd& sensor_rows, int64_t samples, double decay_floor_db) {
  const int64_t over = fd.oversampling();
  const double fs = 1.0 / (fd.timestep_s() * static_cast<double>(over));
  // each prescribed force's nodal weights (the four w nodes around its point)
  std::vector<Terms> weights;
  int64_t load_end = 0;  // audio sample after the last prescribed force
  for (const ForceInput& f : forces) {
    weights.push_back(SparseRow(model.RadialForceWeights(f.z_m, f.theta_rad)));
    load_end = std::max<int64_t>(load_end,
                                 f.first_sample + static_cast<int64_t>(f.force_n.size()));
  }
  std::vector<WallImpact> walls;
  for (const FdImpact& i : impacts) walls.emplace_back(i, model, fd, contact, fs);
  std::vector<Terms> sensors;
  for (Eigen::Index r = 0; r < sensor_rows.rows(); ++r)
    sensors.push_back(SparseRow(sensor_rows.row(r).transpose()));

  FdRun run;
  run.strain = Eigen::MatrixXd::Zero(sensor_rows.rows(), samples);
  Decimator decimator(over, sensor_rows.rows());
  ShellFdState state = fd.Rest();
  Eigen::VectorXd nodal = Eigen::VectorXd::Zero(model.dofs());
  Eigen::VectorXd s(sensor_rows.rows());  // (outputs) at one substep
  const auto push = [&](int64_t n) {
    for (size_t r = 0; r < sensors.size(); ++r)
      s[static_cast<Eigen::Index>(r)] = Dot(sensors[r], state.current);
    decimator.Push(n, s, &run.strain);
  };
  const double energy_floor = std::pow(10.0, decay_floor_db / 10.0);
  double peak_energy = 0.0;
  // the substeps whose outputs the last audio sample's filter reads
  const int64_t last = (samples - 1) * over + decimator.delay();
  int64_t n = 0;
  for (; n < last; ++n) {
    push(n);
    const double t = static_cast<double>(n) / static_cast<double>(over);  // audio samples
    for (size_t e = 0; e < forces.size(); ++e) {
      const double f = ForceAt(forces[e], t);
      // a positive force pushes the wall inward: against the outward weights
      for (const auto& [d, w] : weights[e]) nodal[d] -= w * f;
    }
    fd.Step(&state, nodal);
    for (const Terms& terms : weights) {
      for (const auto& [d, w] : terms) nodal[d] = 0.0;
    }
    for (WallImpact& wall : walls) wall.Close(n + 1, state.previous, &state.current, fd.force_gain());
    // once every load is over, stop when the energy has decayed past the floor
    if (n % (1024 * over) == 1024 * over - 1) {
      const double energy = fd.Energy(state);
      peak_energy = std::max(peak_energy, energy);
      const bool loaded = t < static_cast<double>(load_end) ||
                          std::any_of(walls.begin(), walls.end(),
                                      [](const WallImpact& w) { return !w.done(); });
      if (!loaded && energy < energy_floor * peak_energy) break;
    }
  }
  // flush the filter with the (decayed) state held at rest
  if (n < last) {
    state.current.setZero();
    for (const int64_t end = std::min(last, n + 2 * decimator.delay()); n < end; ++n) push(n);
  } else {
    push(n);
  }
  for (const WallImpact& wall : walls) run.impacts.push_back(wall.result());
  return run;
}

Eigen::MatrixXd FdRender(const ShellModel& model, const ShellFd& fd,
                         std::span<const ForceInput> forces, const Eigen::MatrixXd& sensor_rows,
                         int64_t samples, double decay_floor_db) {
  return FdRender(model, fd, forces, {}, ContactConfig{}, sensor_rows, samples, decay_floor_db)
      .strain;
}

}  // namespace sonicboom::acoustics
