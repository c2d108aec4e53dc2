#include "sonicboom/acoustics/arrival.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <numbers>

#include <fmt/format.h>

#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

void Require(bool ok, const char* field, double value, const char* rule) {
  if (!ok) throw ConfigError(fmt::format("arrival.{} = {} {}", field, value, rule));
}

// second-order Butterworth high-pass (bilinear transform) coefficients
struct Biquad {
  double b0, b1, b2, a1, a2;
};

Biquad ButterworthHighPass(double corner_hz, double fs) {
  const double k = std::tan(kPi * corner_hz / fs);
  const double norm = 1.0 / (1.0 + std::sqrt(2.0) * k + k * k);
  return {norm, -2.0 * norm, norm, 2.0 * (k * k - 1.0) * norm,
          (1.0 - std::sqrt(2.0) * k + k * k) * norm};
}

}  // namespace

void ArrivalConfig::Serialize(Archive* a) {
  a->Visit("highpass_hz", &highpass_hz, Bounds::Positive());
  a->Visit("pre_onset_s", &pre_onset_s, Bounds::Positive());
  a->Visit("post_onset_s", &post_onset_s, Bounds::Positive());
  a->Visit("noise_window_s", &noise_window_s, Bounds::Positive());
  a->Visit("noise_sigmas", &noise_sigmas, Bounds::NonNegative());
  a->Visit("peak_fraction", &peak_fraction, Bounds::Positive());
  a->Visit("min_speed_m_s", &min_speed_m_s, Bounds::Positive());
  a->Visit("max_speed_m_s", &max_speed_m_s, Bounds::Positive());
  a->Visit("grid_z_step_m", &grid_z_step_m, Bounds::Positive());
  a->Visit("grid_theta_step_deg", &grid_theta_step_deg, Bounds::Positive());
}

void ArrivalConfig::Validate(double sample_rate_hz) const {
  Require(highpass_hz > 0 && highpass_hz < 0.45 * sample_rate_hz, "highpass_hz", highpass_hz,
          "must lie in (0, 0.45 x the sample rate)");
  Require(pre_onset_s > 0 && pre_onset_s <= 0.1, "pre_onset_s", pre_onset_s,
          "must lie in (0, 0.1] s");
  Require(post_onset_s > 0 && post_onset_s <= 0.1, "post_onset_s", post_onset_s,
          "must lie in (0, 0.1] s");
  Require(noise_window_s > 0 && noise_window_s <= 1.0, "noise_window_s", noise_window_s,
          "must lie in (0, 1] s");
  Require(noise_sigmas >= 0, "noise_sigmas", noise_sigmas, "must not be negative");
  Require(peak_fraction > 0 && peak_fraction < 1, "peak_fraction", peak_fraction,
          "must lie in (0, 1)");
  Require(min_speed_m_s > 0 && min_speed_m_s < max_speed_m_s, "min_speed_m_s", min_speed_m_s,
          "must be positive and below arrival.max_speed_m_s");
  Require(grid_z_step_m > 0, "grid_z_step_m", grid_z_step_m, "must be positive");
  Require(grid_theta_step_deg > 0 && grid_theta_step_deg <= 30, "grid_theta_step_deg",
          grid_theta_step_deg, "must lie in (0, 30]");
}

struct ArrivalLocator::Impl {
  ArrivalConfig c;
  double fs{0.0};
  int mics{0};
  Biquad hp{};
  std::vector<double> grid_z, grid_theta;  // (points) the search grid
  Eigen::MatrixXd centred_m;  // (mics x points) surface path to each microphone, less its mean
  Eigen::VectorXd spread_m2;  // (points) squared norm of each column of centred_m
};

ArrivalLocator::ArrivalLocator(const TdoaGeometry& geometry, const ArrivalConfig& config,
                               double sample_rate_hz)
    : impl_(std::make_unique<Impl>()) {
  geometry.Validate();
  config.Validate(sample_rate_hz);
  Impl& m = *impl_;
  m.c = config;
  m.fs = sample_rate_hz;
  m.mics = static_cast<int>(geometry.mic_z_m.size());
  m.hp = ButterworthHighPass(config.highpass_hz, sample_rate_hz);
  // the contact region on a z x theta grid, and every grid point's path to every microphone
  const int nz =
      static_cast<int>(std::floor((geometry.z_max_m - geometry.z_min_m) / config.grid_z_step_m)) +
      1;
  const int nt = static_cast<int>(std::lround(360.0 / config.grid_theta_step_deg));
  for (int i = 0; i < nz; ++i) {
    for (int j = 0; j < nt; ++j) {
      m.grid_z.push_back(geometry.z_min_m + i * config.grid_z_step_m);
      m.grid_theta.push_back(-kPi + (j + 0.5) * 2 * kPi / nt);
    }
  }
  const Eigen::Index points = static_cast<Eigen::Index>(m.grid_z.size());
  m.centred_m.resize(m.mics, points);
  for (int k = 0; k < m.mics; ++k) {
    const std::vector<double> d = SurfacePathLengths(
        geometry, m.grid_z, m.grid_theta, geometry.mic_z_m[k], geometry.mic_theta_rad[k]);
    m.centred_m.row(k) = Eigen::Map<const Eigen::RowVectorXd>(d.data(), points);
  }
  // the fit below is on centred times and paths (t0 drops out): centre each point's paths once
  m.centred_m.rowwise() -= m.centred_m.colwise().mean();
  m.spread_m2 = m.centred_m.colwise().squaredNorm().transpose();
}

ArrivalLocator::~ArrivalLocator() = default;

std::vector<double> ArrivalLocator::PickArrivals(const Eigen::MatrixXf& record,
                                                 int64_t onset_sample) const {
  const Impl& m = *impl_;
  if (record.rows() != m.mics) {
    throw Error(fmt::format("arrival locator: record has {} channels, the geometry {} microphones",
                            record.rows(), m.mics));
  }
  if (!record.allFinite()) {
    throw NumericalError("arrival locator: the record holds non-finite samples");
  }
  const int64_t T = record.cols();
  const int64_t start = onset_sample - static_cast<int64_t>(std::lround(m.c.pre_onset_s * m.fs));
  const int64_t end = onset_sample + static_cast<int64_t>(std::lround(m.c.post_onset_s * m.fs));
  const int64_t noise = static_cast<int64_t>(std::lround(m.c.noise_window_s * m.fs));
  const int64_t warmup = static_cast<int64_t>(std::lround(0.01 * m.fs));  // filter settles
  const int64_t first = start - noise - warmup;
  std::vector<double> y(static_cast<size_t>(end - first));  // one channel, high-passed
  std::vector<double> arrivals(static_cast<size_t>(m.mics), 0.0);
  for (int ch = 0; ch < m.mics; ++ch) {
    // high-pass from `first` (samples outside the record are zero)
    double x1 = 0, x2 = 0, y1 = 0, y2 = 0;
    for (int64_t k = first; k < end; ++k) {
      const double x = k >= 0 && k < T ? record(ch, k) : 0.0;
      const double v = m.hp.b0 * x + m.hp.b1 * x1 + m.hp.b2 * x2 - m.hp.a1 * y1 - m.hp.a2 * y2;
      x2 = x1, x1 = x, y2 = y1, y1 = v;
      y[static_cast<size_t>(k - first)] = v;
    }
    // noise rms before the window, the channel's peak inside it, and the threshold
    double power = 0.0;
    for (int64_t k = start - noise; k < start; ++k) power += y[k - first] * y[k - first];
    const double sigma = std::sqrt(power / static_cast<double>(noise));
    double peak = 0.0;
    for (int64_t k = start; k < end; ++k) peak = std::max(peak, std::abs(y[k - first]));
    const double threshold = std::max(m.c.noise_sigmas * sigma, m.c.peak_fraction * peak);
    // the first crossing, interpolated between samples
    double arrival = static_cast<double>(end - start) / m.fs;
    for (int64_t k = start; k < end; ++k) {
      const double a = std::abs(y[k - first]);
      if (a < threshold || a == 0.0) continue;
      const double before = k > start ? std::abs(y[k - 1 - first]) : 0.0;
      const double frac = a > before ? (threshold - before) / (a - before) : 1.0;
      arrival = (static_cast<double>(k - start) - 1.0 + std::clamp(frac, 0.0, 1.0)) / m.fs;
      break;
    }
    if (!(peak > 0.0)) {
      throw NumericalError(
          fmt::format("arrival locator: channel {} is silent around the onset "
                      "(sample {}): no arrival to pick",
                      ch, onset_sample));
    }
    arrivals[static_cast<size_t>(ch)] = arrival;
  }
  return arrivals;
}

ArrivalEstimate ArrivalLocator::Locate(const std::vector<double>& arrival_s) const {
  const Impl& m = *impl_;
  SONICBOOM_DEMAND(static_cast<int>(arrival_s.size()) == m.mics);
  const Eigen::Map<const Eigen::VectorXd> t(arrival_s.data(), m.mics);
  const double t_mean = t.mean();
  const Eigen::VectorXd tc = t.array() - t_mean;
  const double s_lo = 1.0 / m.c.max_speed_m_s, s_hi = 1.0 / m.c.min_speed_m_s;
  // per grid point: least-squares t = t0 + s d with the slowness s clamped; its residual
  // |tc - s dc|^2 expanded, so that a point costs one dot product of length mics
  ArrivalEstimate best;
  best.arrival_s = arrival_s;
  const double tt = tc.squaredNorm();
  double best_ss = std::numeric_limits<double>::infinity();
  double best_s = s_lo;
  Eigen::Index best_p = 0;
  for (Eigen::Index p = 0; p < m.centred_m.cols(); ++p) {
    const double dt = m.centred_m.col(p).dot(tc), dd = m.spread_m2[p];
    const double s = std::clamp(dd > 0 ? dt / dd : s_lo, s_lo, s_hi);
    const double ss = tt - 2.0 * s * dt + s * s * dd;
    if (ss < best_ss) {
      best_ss = ss;
      best_s = s;
      best_p = p;
    }
  }
  best.z_m = m.grid_z[static_cast<size_t>(best_p)];
  best.theta_rad = m.grid_theta[static_cast<size_t>(best_p)];
  // the winner's residual summed directly (the expansion above cancels at a near-exact fit)
  best_ss = (tc - best_s * m.centred_m.col(best_p)).squaredNorm();
  best.speed_m_s = 1.0 / best_s;
  best.residual_s = std::sqrt(best_ss / m.mics);
  return best;
}

ArrivalEstimate ArrivalLocator::Locate(const Eigen::MatrixXf& record, int64_t onset_sample) const {
  return Locate(PickArrivals(record, onset_sample));
}

}  // namespace sonicboom::acoustics
