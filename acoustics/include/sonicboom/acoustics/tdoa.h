#pragma once
/// An analytic, dispersion-aware time-difference-of-arrival locator (docs/baselines.md): the
/// baseline that needs no training. Steered response over a (z, theta) grid of the contact
/// region: per frequency band and microphone pair, the envelope of the band-limited GCC-PHAT is
/// read at the lag that the candidate point predicts, and the sum over bands and pairs is
/// maximized, then refined locally.
///
/// Wave model: Kirchhoff flexural (bending) waves of a flat plate of the wall's thickness,
/// c_phase = (D w^2 / (rho h))^(1/4), D = E h^3 / (12 (1 - nu^2)), group velocity 2 c_phase
/// (docs/physics.md, "Flexural waves"); a band's speed is the inverse of its mean group slowness
/// under the band weight (2.4 % above the value at the centre of an octave band). That is the
/// wall's regime above the ring frequency c_L / (2 pi R) (4.84 kHz for the default tube). Below it
/// the curvature's membrane stiffness lowers the bending group velocity of oblique paths (to zero
/// at cut-off), which the plate model ignores: one global speed scale can be fitted instead.
/// Paths: the shortest route on the unrolled mid-surface cylinder, sqrt(dz^2 + (R dphi)^2); on a
/// seamed tube a path may cross a saw cut only at a bolt (shell.seam_theta_deg, shell.bolt_z_m).
/// Time base and signs follow GccPhat (features.h): a positive lag means the first microphone of
/// the pair, in combinations order, receives later.

#include <Eigen/Core>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "sonicboom/acoustics/shell.h"
#include "sonicboom/core/tube.h"

namespace sonicboom::acoustics {

/// Kirchhoff plate flexural phase velocity (D w^2 / (rho h))^(1/4), m/s, at frequency_hz.
double FlexuralPhaseVelocity(double frequency_hz, const MaterialConfig& material,
                             double thickness_m);
/// Kirchhoff plate flexural group velocity, twice the phase velocity, m/s.
double FlexuralGroupVelocity(double frequency_hz, const MaterialConfig& material,
                             double thickness_m);

/// Where waves travel and where the microphones and the contact region are.
struct TdoaGeometry {
  double radius_m{0.05202};  // wave path radius: the wall's mid-surface
  double wall_thickness_m{0.00305};
  MaterialConfig material;
  double z_min_m{-0.1015};  // search region (the contact region)
  double z_max_m{0.1015};
  std::vector<double> mic_z_m;  // per microphone (channel order)
  std::vector<double> mic_theta_rad;
  std::vector<double> seam_theta_rad;  // saw cuts along the tube; empty: a closed tube
  std::vector<double> bolt_z_m;        // where every seam is bolted across (paths cross here)

  /// Throws ConfigError naming the field as "tdoa.<field>".
  void Validate() const;
};

/// The geometry of a tube, its material and microphones; `shell` gives the seams and bolts
/// (none for an ideal shell).
TdoaGeometry MakeTdoaGeometry(const TubeConfig& tube, const MaterialConfig& material,
                              const MicArrayConfig& mics, const ShellConfig& shell);

/// Length of the shortest surface path between two points (z, theta) on the geometry's
/// mid-surface, m: a straight line on the unrolled cylinder, and on a seamed tube the shortest
/// chain of such lines that crosses saw cuts only at bolts.
double SurfacePathLength(const TdoaGeometry& geometry, double z1_m, double theta1_rad, double z2_m,
                         double theta2_rad);

/// SurfacePathLength from every point (z_m[i], theta_rad[i]) to one point (z2, theta2), m; the
/// seam graph built once.
std::vector<double> SurfacePathLengths(const TdoaGeometry& geometry, const std::vector<double>& z_m,
                                       const std::vector<double>& theta_rad, double z2_m,
                                       double theta2_rad);

/// Bands, speeds, analysis window and search grid.
struct TdoaConfig {
  /// Band b spans [band_edges_hz[b], band_edges_hz[b+1]]: a cos^2 weight in log frequency,
  /// centred at the geometric mean, half power at the edges (neighbouring bands sum to one).
  std::vector<double> band_edges_hz{1000.0, 2000.0, 4000.0, 8000.0, 16000.0};
  std::vector<double> band_weights;  // per band (empty: all 1)
  bool dispersive{true};             // per-band group velocity; false: one speed for all
  double speed_m_s{0.0};             // the non-dispersive speed (0: group velocity at the
                                     // geometric centre of all bands)
  double speed_scale{1.0};           // multiplies every band's speed
  double min_speed_scale{0.25};      // lags are kept for speeds down to this scale
  double pre_onset_s{0.003};         // analysis window around the onset
  double post_onset_s{0.005};
  double taper_s{0.0005};       // raised-cosine ends of the analysis window
  int64_t upsample{4};          // lag grid step 1 / upsample samples
  double grid_z_step_m{0.002};  // coarse search grid
  double grid_theta_step_deg{2.0};
  double refine_tolerance_m{5e-5};  // local refinement stops at this step (arc for theta)

  /// Throws ConfigError naming the field as "tdoa.<field>".
  void Validate() const;
};

/// Band GCC-PHAT envelopes of one strike: envelope[b] is (pairs x lags), column u is lag
/// (u / upsample - max_lag) samples, normalized so that a perfectly coherent pair reaches 1.
struct TdoaCorrelations {
  int64_t max_lag{0};  // samples each side
  int64_t upsample{1};
  std::vector<Eigen::MatrixXf> envelope;
};

/// A located contact.
struct TdoaEstimate {
  double z_m{0.0};
  double theta_rad{0.0};
  double score{0.0};  // steered response at the estimate
};

/// Immutable; every method is const and thread-safe.
class TdoaLocator {
 public:
  /// Throws ConfigError for a bad geometry or config (names the field), or when the bands do not
  /// fit below Nyquist.
  TdoaLocator(const TdoaGeometry& geometry, const TdoaConfig& config, double sample_rate_hz);
  ~TdoaLocator();
  TdoaLocator(const TdoaLocator&) = delete;
  TdoaLocator& operator=(const TdoaLocator&) = delete;

  /// Band GCC envelopes of the window [onset - pre, onset + post) of a (mics x T) record
  /// (samples outside the record are zero). Throws Error on a channel-count mismatch.
  TdoaCorrelations Correlate(const Eigen::MatrixXf& record, int64_t onset_sample) const;
  /// Steered-response maximum over the grid, refined locally, with every band speed times
  /// `speed_scale` (>= min_speed_scale).
  TdoaEstimate Locate(const TdoaCorrelations& correlations, double speed_scale) const;
  /// Correlate, then Locate at config().speed_scale.
  TdoaEstimate Locate(const Eigen::MatrixXf& record, int64_t onset_sample) const;

  /// Predicted lag of pair p (combinations order) in band b for a contact at (z, theta), in
  /// samples, at speed scale 1.
  double PredictedLag(double z_m, double theta_rad, int pair, int band) const;
  /// Speed used in band b at scale 1, m/s.
  double BandSpeed(int band) const;
  int bands() const;
  int pairs() const;
  double sample_rate_hz() const;
  const TdoaConfig& config() const;
  const TdoaGeometry& geometry() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/// Fits the one global speed scale that minimizes the mean 3-D surface distance (on a surface of
/// `surface_radius_m`) of the located strikes against their labels: a scan over
/// [lo, hi] in log steps, then a finer scan around the best. Returns the scale; `best_med_m`
/// (optional) receives its mean distance in metres. Deterministic for any thread count.
double FitSpeedScale(const TdoaLocator& locator, const std::vector<TdoaCorrelations>& strikes,
                     const std::vector<double>& z_m, const std::vector<double>& theta_rad,
                     double surface_radius_m, double lo, double hi, int threads,
                     double* best_med_m = nullptr);

}  // namespace sonicboom::acoustics
