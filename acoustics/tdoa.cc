#include "sonicboom/acoustics/tdoa.h"

#include "sonicboom/core/constants.h"
#include "sonicboom/dsp/band_weights.h"

#include <fmt/format.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>

#include <algorithm>
#include <cmath>
#include <complex>
#include <limits>
#include <numbers>
#include <unsupported/Eigen/FFT>
#include <utility>

#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();

// angle mapped into [base, base + 2 pi)
double MapFrom(double theta, double base) {
  double t = std::fmod(theta - base, 2.0 * kPi);
  if (t < 0.0) t += 2.0 * kPi;
  return base + t;
}

// wrapped angle difference in [-pi, pi]
double WrappedDelta(double a, double b) {
  return std::remainder(a - b, 2.0 * kPi);
}

int64_t NextPowerOfTwo(int64_t n) {
  int64_t m = 1;
  while (m < n) m *= 2;
  return m;
}

}  // namespace

double FlexuralPhaseVelocity(double frequency_hz, const MaterialConfig& material,
                             double thickness_m) {
  const double nu = material.poisson_ratio;
  const double d = material.youngs_modulus_pa * thickness_m * thickness_m * thickness_m /
                   (12.0 * (1.0 - nu * nu));
  const double omega = 2.0 * kPi * frequency_hz;
  return std::pow(d * omega * omega / (material.density_kg_m3 * thickness_m), 0.25);
}

double FlexuralGroupVelocity(double frequency_hz, const MaterialConfig& material,
                             double thickness_m) {
  return 2.0 * FlexuralPhaseVelocity(frequency_hz, material, thickness_m);
}

// ---------------------------------------------------------------------------------------------
// Geometry and surface paths

void TdoaGeometry::Validate() const {
  auto fail = [](const std::string& message) { throw ConfigError("tdoa." + message); };
  if (!(radius_m > 0.0)) fail(fmt::format("radius_m must be > 0, got {}", radius_m));
  if (!(wall_thickness_m > 0.0)) {
    fail(fmt::format("wall_thickness_m must be > 0, got {}", wall_thickness_m));
  }
  if (!(material.youngs_modulus_pa > 0.0 && material.density_kg_m3 > 0.0 &&
        material.poisson_ratio > -1.0 && material.poisson_ratio < 0.5)) {
    fail(
        fmt::format("material needs E > 0, rho > 0 and -1 < nu < 0.5, got E = {}, rho = {}, "
                    "nu = {}",
                    material.youngs_modulus_pa, material.density_kg_m3, material.poisson_ratio));
  }
  if (!(z_min_m < z_max_m)) {
    fail(fmt::format("z_min_m must be < z_max_m, got [{}, {}]", z_min_m, z_max_m));
  }
  if (mic_z_m.size() < 2 || mic_z_m.size() != mic_theta_rad.size()) {
    fail(fmt::format("mic_z_m and mic_theta_rad need >= 2 entries each, got {} and {}",
                     mic_z_m.size(), mic_theta_rad.size()));
  }
  if (!seam_theta_rad.empty() && bolt_z_m.empty()) {
    fail("bolt_z_m must not be empty on a seamed tube (its halves would not be connected)");
  }
}

TdoaGeometry MakeTdoaGeometry(const TubeConfig& tube, const MaterialConfig& material,
                              const MicArrayConfig& mics, const ShellConfig& shell) {
  TdoaGeometry g;
  g.radius_m = tube.mid_radius_m();
  g.wall_thickness_m = tube.wall_thickness_m;
  g.material = material;
  g.z_min_m = tube.contact_z_min_m;
  g.z_max_m = tube.contact_z_max_m;
  g.mic_z_m = mics.z_m;
  for (double deg : mics.theta_deg) g.mic_theta_rad.push_back(deg * kPi / 180.0);
  if (!shell.ideal) {
    for (double deg : shell.seam_theta_deg) g.seam_theta_rad.push_back(deg * kPi / 180.0);
    g.bolt_z_m = shell.bolt_z_m;
  }
  return g;
}

namespace {

// The seamed surface: sectors between saw cuts, joined only at bolt nodes.
class SurfacePaths {
 public:
  explicit SurfacePaths(const TdoaGeometry& g) : radius_(g.radius_m) {
    seams_ = g.seam_theta_rad;
    for (double& s : seams_) s = MapFrom(s, 0.0);
    std::sort(seams_.begin(), seams_.end());
    seams_.erase(std::unique(seams_.begin(), seams_.end()), seams_.end());
    if (seams_.empty()) return;
    const int k = static_cast<int>(seams_.size());
    for (int j = 0; j < k; ++j) {
      for (double z : g.bolt_z_m) nodes_.push_back({j, z});
    }
    // bolt to bolt: directly inside a sector both border, then all-pairs shortest paths
    const size_t n = nodes_.size();
    between_.assign(n, std::vector<double>(n, kInf));
    for (size_t a = 0; a < n; ++a) {
      for (size_t b = 0; b < n; ++b) {
        for (int sector = 0; sector < k; ++sector) {
          for (double ta : BoundaryAngles(nodes_[a].seam, sector)) {
            for (double tb : BoundaryAngles(nodes_[b].seam, sector)) {
              between_[a][b] = std::min(between_[a][b],
                                        std::hypot(nodes_[a].z - nodes_[b].z, radius_ * (ta - tb)));
            }
          }
        }
      }
    }
    for (size_t m = 0; m < n; ++m) {
      for (size_t a = 0; a < n; ++a) {
        for (size_t b = 0; b < n; ++b) {
          between_[a][b] = std::min(between_[a][b], between_[a][m] + between_[m][b]);
        }
      }
    }
  }

  double Length(double z1, double t1, double z2, double t2) const {
    if (seams_.empty()) return std::hypot(z1 - z2, radius_ * WrappedDelta(t1, t2));
    const int s1 = Sector(t1), s2 = Sector(t2);
    const double a1 = MapFrom(t1, seams_[s1]), a2 = MapFrom(t2, seams_[s2]);
    double best = s1 == s2 ? std::hypot(z1 - z2, radius_ * (a1 - a2)) : kInf;
    // through bolts: point -> bolt a -> ... -> bolt b -> point
    const size_t n = nodes_.size();
    std::vector<double> to_first(n), to_last(n);
    for (size_t a = 0; a < n; ++a) {
      to_first[a] = ToNode(z1, a1, s1, a);
      to_last[a] = ToNode(z2, a2, s2, a);
    }
    for (size_t a = 0; a < n; ++a) {
      if (to_first[a] == kInf) continue;
      for (size_t b = 0; b < n; ++b) {
        best = std::min(best, to_first[a] + between_[a][b] + to_last[b]);
      }
    }
    return best;
  }

 private:
  struct Node {
    int seam;
    double z;
  };

  // sector of an angle: sector j spans [seam j, seam j+1)
  int Sector(double theta) const {
    const double t = MapFrom(theta, seams_[0]);
    const int k = static_cast<int>(seams_.size());
    int sector = 0;
    for (int j = 1; j < k; ++j) {
      if (t >= seams_[j]) sector = j;
    }
    return sector;
  }

  // angles, in sector coordinates [seam s, seam s + width], at which seam j bounds the sector
  std::vector<double> BoundaryAngles(int seam, int sector) const {
    const int k = static_cast<int>(seams_.size());
    std::vector<double> out;
    const double start = seams_[sector];
    const double end = sector + 1 < k ? seams_[sector + 1] : seams_[0] + 2.0 * kPi;
    if (seam == sector) out.push_back(start);
    if (seam == (sector + 1) % k) out.push_back(end);
    return out;
  }

  // a point of `sector` (angle in its coordinates) to a bolt node, inf when the node's seam does
  // not bound the sector
  double ToNode(double z, double angle, int sector, size_t node) const {
    double best = kInf;
    for (double t : BoundaryAngles(nodes_[node].seam, sector)) {
      best = std::min(best, std::hypot(z - nodes_[node].z, radius_ * (angle - t)));
    }
    return best;
  }

  double radius_;
  std::vector<double> seams_;  // sorted, in [0, 2 pi)
  std::vector<Node> nodes_;
  std::vector<std::vector<double>> between_;  // bolt to bolt shortest paths
};

}  // namespace

double SurfacePathLength(const TdoaGeometry& geometry, double z1_m, double theta1_rad, double z2_m,
                         double theta2_rad) {
  geometry.Validate();
  return SurfacePaths(geometry).Length(z1_m, theta1_rad, z2_m, theta2_rad);
}

std::vector<double> SurfacePathLengths(const TdoaGeometry& geometry, const std::vector<double>& z_m,
                                       const std::vector<double>& theta_rad, double z2_m,
                                       double theta2_rad) {
  SONICBOOM_DEMAND(z_m.size() == theta_rad.size());
  geometry.Validate();
  const SurfacePaths paths(geometry);
  std::vector<double> out(z_m.size());
  for (size_t i = 0; i < z_m.size(); ++i)
    out[i] = paths.Length(z_m[i], theta_rad[i], z2_m, theta2_rad);
  return out;
}

// ---------------------------------------------------------------------------------------------
// Config

void TdoaConfig::Validate() const {
  auto fail = [](const std::string& message) { throw ConfigError("tdoa." + message); };
  if (band_edges_hz.size() < 2) {
    fail(fmt::format("band_edges_hz needs >= 2 edges (one band), got {}", band_edges_hz.size()));
  }
  for (size_t i = 0; i < band_edges_hz.size(); ++i) {
    if (!(band_edges_hz[i] > 0.0) || (i > 0 && !(band_edges_hz[i] > band_edges_hz[i - 1]))) {
      fail(fmt::format("band_edges_hz must be positive and increasing, got {} at {}",
                       band_edges_hz[i], i));
    }
  }
  if (!band_weights.empty() && band_weights.size() + 1 != band_edges_hz.size()) {
    fail(fmt::format("band_weights needs one entry per band ({}), got {}", band_edges_hz.size() - 1,
                     band_weights.size()));
  }
  for (double w : band_weights) {
    if (!(w >= 0.0) || !std::isfinite(w)) fail(fmt::format("band_weights must be >= 0, got {}", w));
  }
  if (!(speed_m_s >= 0.0)) fail(fmt::format("speed_m_s must be >= 0, got {}", speed_m_s));
  if (!(min_speed_scale > 0.0)) {
    fail(fmt::format("min_speed_scale must be > 0, got {}", min_speed_scale));
  }
  if (!(speed_scale >= min_speed_scale)) {
    fail(fmt::format("speed_scale must be >= min_speed_scale ({}), got {}", min_speed_scale,
                     speed_scale));
  }
  if (!(pre_onset_s >= 0.0)) fail(fmt::format("pre_onset_s must be >= 0, got {}", pre_onset_s));
  if (!(post_onset_s > 0.0)) fail(fmt::format("post_onset_s must be > 0, got {}", post_onset_s));
  if (!(taper_s >= 0.0 && 2.0 * taper_s <= pre_onset_s + post_onset_s)) {
    fail(fmt::format("taper_s must be in [0, half the window], got {}", taper_s));
  }
  if (upsample < 1 || upsample > 64)
    fail(fmt::format("upsample must be in [1, 64], got {}", upsample));
  if (!(grid_z_step_m > 0.0)) fail(fmt::format("grid_z_step_m must be > 0, got {}", grid_z_step_m));
  if (!(grid_theta_step_deg > 0.0 && grid_theta_step_deg <= 90.0)) {
    fail(fmt::format("grid_theta_step_deg must be in (0, 90], got {}", grid_theta_step_deg));
  }
  if (!(refine_tolerance_m > 0.0)) {
    fail(fmt::format("refine_tolerance_m must be > 0, got {}", refine_tolerance_m));
  }
}

// ---------------------------------------------------------------------------------------------
// TdoaLocator

struct TdoaLocator::Impl {
  TdoaGeometry geometry;
  TdoaConfig config;
  double fs{0.0};
  std::unique_ptr<SurfacePaths> paths;
  int mics{0};
  std::vector<std::pair<int, int>> pairs;  // combinations order
  std::vector<double> band_centre_hz;
  std::vector<double> band_speed;  // m/s at scale 1
  std::vector<double> band_weight;
  int64_t pre{0}, post{0}, n{0};  // analysis window, samples
  std::vector<float> taper;       // (n)
  int64_t max_lag{0};
  int64_t fft_size{0};                          // N: linear correlation up to max_lag
  std::vector<std::vector<double>> bin_weight;  // per band, bins 0..N/2
  std::vector<double> bin_weight_sum;
  // coarse grid: candidate c = iz * n_theta + it; path differences (candidates x pairs), m
  int64_t n_z{0}, n_theta{0};
  double theta_step{0.0};
  std::vector<double> grid_z, grid_theta;
  Eigen::MatrixXd path_diff;  // (pairs x candidates)

  std::vector<double> PathLengths(double z, double theta) const {
    std::vector<double> out(static_cast<size_t>(mics));
    for (int m = 0; m < mics; ++m) {
      out[m] = paths->Length(z, theta, geometry.mic_z_m[m], geometry.mic_theta_rad[m]);
    }
    return out;
  }

  // envelope of band b, pair p at a lag in samples (linear interpolation, 0 outside)
  static double Sample(const TdoaCorrelations& c, int b, int p, double lag) {
    const double u = (lag + static_cast<double>(c.max_lag)) * static_cast<double>(c.upsample);
    const Eigen::MatrixXf& env = c.envelope[b];
    if (!(u >= 0.0) || u > static_cast<double>(env.cols() - 1)) return 0.0;
    const int64_t i = std::min<int64_t>(static_cast<int64_t>(u), env.cols() - 2);
    const double f = u - static_cast<double>(i);
    return (1.0 - f) * env(p, i) + f * env(p, i + 1);
  }

  // steered response of path differences `diff` (per pair, m)
  double Score(const TdoaCorrelations& c, const double* diff, double scale) const {
    double total = 0.0;
    for (size_t b = 0; b < band_speed.size(); ++b) {
      if (band_weight[b] == 0.0) continue;
      const double samples_per_m = fs / (scale * band_speed[b]);
      double sum = 0.0;
      for (size_t p = 0; p < pairs.size(); ++p) {
        sum += Sample(c, static_cast<int>(b), static_cast<int>(p), diff[p] * samples_per_m);
      }
      total += band_weight[b] * sum;
    }
    return total;
  }

  double ScoreAt(const TdoaCorrelations& c, double z, double theta, double scale) const {
    const std::vector<double> len = PathLengths(z, theta);
    std::vector<double> diff(pairs.size());
    for (size_t p = 0; p < pairs.size(); ++p) diff[p] = len[pairs[p].first] - len[pairs[p].second];
    return Score(c, diff.data(), scale);
  }
};

TdoaLocator::TdoaLocator(const TdoaGeometry& geometry, const TdoaConfig& config,
                         double sample_rate_hz)
    : impl_(std::make_unique<Impl>()) {
  geometry.Validate();
  config.Validate();
  if (!(sample_rate_hz > 0.0)) {
    throw ConfigError(fmt::format("tdoa: sample rate must be > 0 Hz, got {}", sample_rate_hz));
  }
  if (config.band_edges_hz.back() > sample_rate_hz / 2.0) {
    throw ConfigError(fmt::format("tdoa.band_edges_hz: the top edge {} Hz is above Nyquist ({} Hz)",
                                  config.band_edges_hz.back(), sample_rate_hz / 2.0));
  }
  Impl& m = *impl_;
  m.geometry = geometry;
  m.config = config;
  m.fs = sample_rate_hz;
  m.paths = std::make_unique<SurfacePaths>(geometry);
  m.mics = static_cast<int>(geometry.mic_z_m.size());
  for (int i = 0; i < m.mics; ++i) {
    for (int j = i + 1; j < m.mics; ++j) m.pairs.emplace_back(i, j);
  }

  // bands: centre, speed, weight
  const size_t bands = config.band_edges_hz.size() - 1;
  const double all_centre = std::sqrt(config.band_edges_hz.front() * config.band_edges_hz.back());
  const double single_speed =
      config.speed_m_s > 0.0
          ? config.speed_m_s
          : FlexuralGroupVelocity(all_centre, geometry.material, geometry.wall_thickness_m);
  for (size_t b = 0; b < bands; ++b) {
    const double centre = std::sqrt(config.band_edges_hz[b] * config.band_edges_hz[b + 1]);
    m.band_centre_hz.push_back(centre);
    // the band's group velocity: the inverse of its mean group slowness under the band weight
    // over linear frequency (as the FFT bins sample it); the envelope of the band GCC peaks at
    // that mean group delay. For an octave band it is 2.4 % above the value at the centre.
    const double half_width = std::log2(config.band_edges_hz[b + 1] / config.band_edges_hz[b]);
    const double f_lo = centre * std::exp2(-half_width);
    const double f_hi = std::min(centre * std::exp2(half_width), 0.5 * sample_rate_hz);
    double slowness = 0.0, weight = 0.0;
    constexpr int kSteps = 4096;
    for (int i = 0; i < kSteps; ++i) {
      const double f = f_lo + (f_hi - f_lo) * (i + 0.5) / kSteps;
      const double c = std::cos(0.5 * kPi * std::log2(f / centre) / half_width);
      slowness += c * c / FlexuralGroupVelocity(f, geometry.material, geometry.wall_thickness_m);
      weight += c * c;
    }
    m.band_speed.push_back(config.dispersive ? weight / slowness : single_speed);
    m.band_weight.push_back(config.band_weights.empty() ? 1.0 : config.band_weights[b]);
  }

  // analysis window with raised-cosine ends
  m.pre = std::llround(config.pre_onset_s * sample_rate_hz);
  m.post = std::max<int64_t>(1, std::llround(config.post_onset_s * sample_rate_hz));
  m.n = m.pre + m.post;
  const int64_t ramp = std::min<int64_t>(std::llround(config.taper_s * sample_rate_hz), m.n / 2);
  m.taper.assign(static_cast<size_t>(m.n), 1.0f);
  for (int64_t t = 0; t < ramp; ++t) {
    const float w = static_cast<float>(0.5 - 0.5 * std::cos(kPi * (t + 0.5) / ramp));
    m.taper[t] = w;
    m.taper[m.n - 1 - t] = w;
  }

  // coarse grid and its path differences
  m.n_z = std::max<int64_t>(
      2, std::llround((geometry.z_max_m - geometry.z_min_m) / config.grid_z_step_m) + 1);
  m.n_theta = std::max<int64_t>(4, std::llround(360.0 / config.grid_theta_step_deg));
  m.theta_step = 2.0 * kPi / static_cast<double>(m.n_theta);
  for (int64_t i = 0; i < m.n_z; ++i) {
    m.grid_z.push_back(geometry.z_min_m +
                       (geometry.z_max_m - geometry.z_min_m) * i / static_cast<double>(m.n_z - 1));
  }
  for (int64_t j = 0; j < m.n_theta; ++j) m.grid_theta.push_back(-kPi + j * m.theta_step);
  const int64_t candidates = m.n_z * m.n_theta;
  m.path_diff.resize(static_cast<int64_t>(m.pairs.size()), candidates);
  double max_diff = 0.0;
  for (int64_t c = 0; c < candidates; ++c) {
    const std::vector<double> len =
        m.PathLengths(m.grid_z[c / m.n_theta], m.grid_theta[c % m.n_theta]);
    for (size_t p = 0; p < m.pairs.size(); ++p) {
      const double d = len[m.pairs[p].first] - len[m.pairs[p].second];
      m.path_diff(static_cast<int64_t>(p), c) = d;
      if (std::isfinite(d)) max_diff = std::max(max_diff, std::abs(d));
    }
  }

  // lags kept: the largest path difference at the slowest speed and scale; FFT size for a
  // linear (not circular) correlation up to that lag
  const double slowest = *std::min_element(m.band_speed.begin(), m.band_speed.end());
  m.max_lag = static_cast<int64_t>(
                  std::ceil(max_diff * sample_rate_hz / (config.min_speed_scale * slowest))) +
              2;
  m.fft_size = NextPowerOfTwo(m.n + m.max_lag);

  // per band: cos^2 weight in log2 frequency, half power at the band edges
  for (size_t b = 0; b < bands; ++b) {
    std::vector<double> w =
        dsp::LogBandWeights(config.band_edges_hz[b], config.band_edges_hz[b + 1], m.fft_size,
                            sample_rate_hz, "tdoa.band_edges_hz");
    double sum = 0.0;
    for (double x : w) sum += x;
    m.bin_weight.push_back(std::move(w));
    m.bin_weight_sum.push_back(sum);
  }
}

TdoaLocator::~TdoaLocator() = default;

int TdoaLocator::bands() const {
  return static_cast<int>(impl_->band_speed.size());
}
int TdoaLocator::pairs() const {
  return static_cast<int>(impl_->pairs.size());
}
double TdoaLocator::sample_rate_hz() const {
  return impl_->fs;
}
const TdoaConfig& TdoaLocator::config() const {
  return impl_->config;
}
const TdoaGeometry& TdoaLocator::geometry() const {
  return impl_->geometry;
}

double TdoaLocator::BandSpeed(int band) const {
  if (band < 0 || band >= bands()) {
    throw Error(fmt::format("tdoa: band {} out of range [0, {})", band, bands()));
  }
  return impl_->band_speed[band];
}

double TdoaLocator::PredictedLag(double z_m, double theta_rad, int pair, int band) const {
  const Impl& m = *impl_;
  if (pair < 0 || pair >= pairs()) {
    throw Error(fmt::format("tdoa: pair {} out of range [0, {})", pair, pairs()));
  }
  const std::vector<double> len = m.PathLengths(z_m, theta_rad);
  return (len[m.pairs[pair].first] - len[m.pairs[pair].second]) * m.fs / BandSpeed(band);
}

TdoaCorrelations TdoaLocator::Correlate(const Eigen::MatrixXf& record, int64_t onset_sample) const {
  const Impl& m = *impl_;
  if (record.rows() != m.mics) {
    throw Error(fmt::format("tdoa: the record has {} channels, the geometry {} microphones",
                            record.rows(), m.mics));
  }
  const int64_t n_fft = m.fft_size;
  const int64_t bins = n_fft / 2 + 1;
  const int64_t fine = n_fft * m.config.upsample;
  Eigen::FFT<double> fft;
  fft.SetFlag(Eigen::FFT<double>::HalfSpectrum);
  fft.SetFlag(Eigen::FFT<double>::Unscaled);

  // spectra of the tapered window of every channel, zero-padded to the FFT size
  std::vector<std::vector<std::complex<double>>> spectra(static_cast<size_t>(m.mics));
  std::vector<double> frame(static_cast<size_t>(n_fft));
  const int64_t start = onset_sample - m.pre;
  for (int c = 0; c < m.mics; ++c) {
    std::fill(frame.begin(), frame.end(), 0.0);
    for (int64_t t = 0; t < m.n; ++t) {
      const int64_t i = start + t;
      if (i >= 0 && i < record.cols()) frame[t] = static_cast<double>(record(c, i)) * m.taper[t];
    }
    spectra[c].resize(static_cast<size_t>(bins));
    fft.fwd(spectra[c].data(), frame.data(), n_fft);
  }

  // per pair: PHAT-weighted cross spectrum; per band: its positive-frequency part, inverse
  // transformed on a lag grid `upsample` times finer, magnitude = envelope
  TdoaCorrelations out;
  out.max_lag = m.max_lag;
  out.upsample = m.config.upsample;
  const int64_t lags = 2 * m.max_lag * m.config.upsample + 1;
  out.envelope.assign(m.band_speed.size(), Eigen::MatrixXf::Zero(m.pairs.size(), lags));
  std::vector<std::complex<double>> cross(static_cast<size_t>(bins));
  std::vector<std::complex<double>> spectrum(static_cast<size_t>(fine));
  std::vector<std::complex<double>> corr(static_cast<size_t>(fine));
  for (size_t p = 0; p < m.pairs.size(); ++p) {
    const auto& x = spectra[m.pairs[p].first];
    const auto& y = spectra[m.pairs[p].second];
    for (int64_t k = 0; k < bins; ++k) {
      const std::complex<double> g = x[k] * std::conj(y[k]);
      const double mag = std::abs(g);
      cross[k] = mag > 0.0 ? g / mag : std::complex<double>(0.0, 0.0);
    }
    for (size_t b = 0; b < m.band_speed.size(); ++b) {
      std::fill(spectrum.begin(), spectrum.end(), std::complex<double>(0.0, 0.0));
      const std::vector<double>& w = m.bin_weight[b];
      for (int64_t k = 1; k < bins; ++k) spectrum[k] = w[k] * cross[k];
      // lag tau (samples) at fine index tau * upsample, negative lags wrapped to the end
      fft.inv(corr.data(), spectrum.data(), fine);
      const double norm = 1.0 / m.bin_weight_sum[b];
      for (int64_t u = 0; u < lags; ++u) {
        int64_t index = u - m.max_lag * m.config.upsample;
        if (index < 0) index += fine;
        out.envelope[b](static_cast<int64_t>(p), u) =
            static_cast<float>(std::abs(corr[index]) * norm);
      }
    }
  }
  return out;
}

TdoaEstimate TdoaLocator::Locate(const TdoaCorrelations& correlations, double speed_scale) const {
  const Impl& m = *impl_;
  if (!(speed_scale >= m.config.min_speed_scale)) {
    throw ConfigError(fmt::format("tdoa: speed scale {} is below min_speed_scale {}", speed_scale,
                                  m.config.min_speed_scale));
  }
  if (correlations.envelope.size() != m.band_speed.size() || correlations.max_lag != m.max_lag ||
      correlations.upsample != m.config.upsample) {
    throw Error("tdoa: correlations were made by a locator of another config");
  }

  // coarse grid: the best candidate, ties to the lower index
  const int64_t candidates = m.n_z * m.n_theta;
  int64_t best = 0;
  double best_score = -kInf;
  for (int64_t c = 0; c < candidates; ++c) {
    const double s = m.Score(correlations, m.path_diff.col(c).data(), speed_scale);
    if (s > best_score) {
      best_score = s;
      best = c;
    }
  }

  // local pattern search: the best of the 8 neighbours, halving the steps when none is better
  double z = m.grid_z[best / m.n_theta], theta = m.grid_theta[best % m.n_theta];
  double step_z = 0.5 * m.config.grid_z_step_m, step_t = 0.5 * m.theta_step;
  const double tol_t = m.config.refine_tolerance_m / m.geometry.radius_m;
  for (int iteration = 0; iteration < 400; ++iteration) {
    if (step_z < m.config.refine_tolerance_m && step_t < tol_t) break;
    double next_z = z, next_t = theta, next_score = best_score;
    for (int dz = -1; dz <= 1; ++dz) {
      for (int dt = -1; dt <= 1; ++dt) {
        if (dz == 0 && dt == 0) continue;
        const double cz = std::clamp(z + dz * step_z, m.geometry.z_min_m, m.geometry.z_max_m);
        const double ct = theta + dt * step_t;
        const double s = m.ScoreAt(correlations, cz, ct, speed_scale);
        if (s > next_score) {
          next_score = s;
          next_z = cz;
          next_t = ct;
        }
      }
    }
    if (next_score > best_score) {
      z = next_z;
      theta = next_t;
      best_score = next_score;
    } else {
      step_z *= 0.5;
      step_t *= 0.5;
    }
  }
  return {z, WrapAngle(theta), best_score};
}

TdoaEstimate TdoaLocator::Locate(const Eigen::MatrixXf& record, int64_t onset_sample) const {
  return Locate(Correlate(record, onset_sample), impl_->config.speed_scale);
}

double FitSpeedScale(const TdoaLocator& locator, const std::vector<TdoaCorrelations>& strikes,
                     const std::vector<double>& z_m, const std::vector<double>& theta_rad,
                     double surface_radius_m, double lo, double hi, int threads,
                     double* best_med_m) {
  if (strikes.empty() || strikes.size() != z_m.size() || z_m.size() != theta_rad.size()) {
    throw Error(fmt::format("tdoa speed fit: {} strikes with {} heights and {} angles",
                            strikes.size(), z_m.size(), theta_rad.size()));
  }
  if (!(lo >= locator.config().min_speed_scale && hi > lo)) {
    throw ConfigError(
        fmt::format("tdoa speed fit: the range [{}, {}] must lie above "
                    "min_speed_scale {} and not be empty",
                    lo, hi, locator.config().min_speed_scale));
  }
  tbb::task_arena arena(threads > 0 ? threads : tbb::task_arena::automatic);
  // mean surface distance at one scale; per-strike slots summed in order (deterministic)
  auto med = [&](double scale) {
    std::vector<double> dist(strikes.size());
    arena.execute([&] {
      tbb::parallel_for(size_t{0}, strikes.size(), [&](size_t i) {
        const TdoaEstimate e = locator.Locate(strikes[i], scale);
        // chord between the surface points, as learning::ComputeMetrics measures it
        const double dx = surface_radius_m * (std::cos(e.theta_rad) - std::cos(theta_rad[i]));
        const double dy = surface_radius_m * (std::sin(e.theta_rad) - std::sin(theta_rad[i]));
        dist[i] = std::sqrt(dx * dx + dy * dy + (e.z_m - z_m[i]) * (e.z_m - z_m[i]));
      });
    });
    double sum = 0.0;
    for (double d : dist) sum += d;
    return sum / static_cast<double>(dist.size());
  };
  // coarse log scan, then a finer one around its best
  constexpr int kCoarse = 17, kFine = 9;
  const double ratio = std::pow(hi / lo, 1.0 / (kCoarse - 1));
  double best_scale = lo, best = kInf;
  for (int i = 0; i < kCoarse; ++i) {
    const double s = lo * std::pow(ratio, i);
    const double v = med(s);
    if (v < best) {
      best = v;
      best_scale = s;
    }
  }
  const double centre = best_scale;
  for (int i = 0; i < kFine; ++i) {
    const double s =
        std::max(lo, centre * std::pow(ratio, (i - (kFine - 1) / 2.0) / ((kFine - 1) / 2.0)));
    if (s == centre) continue;
    const double v = med(s);
    if (v < best) {
      best = v;
      best_scale = s;
    }
  }
  if (best_med_m) *best_med_m = best;
  return best_scale;
}

}  // namespace sonicboom::acoustics
