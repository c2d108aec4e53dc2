#pragma once
/// How the fidelity ladder (experiments/fidelity.cc) scores a rung's signal against the
/// reference's: signals are (channels x samples) sensor strain at one sample rate, both starting
/// at the same instant. Private to experiments.

#include <Eigen/Core>
#include <cstdint>
#include <vector>

#include "internal/statistics.h"

namespace sonicboom::experiments {

/// Relative L2 error over all channels, ||y - ref|| / ||ref||.
double RelativeError(const Eigen::MatrixXd& y, const Eigen::MatrixXd& ref);

/// Timing of y against ref, microseconds, from each channel's first arrival (the first time its
/// |signal| reaches 20 % of its own peak, solid::ThresholdArrivals): mean over channels of
/// |arrival error|, and mean and max over channel pairs of |inter-channel delay error|; and each
/// channel's and pair's error, for medians over many strikes (a threshold that lands on another
/// wave packet in one channel moves its arrival by hundreds of microseconds and dominates a mean).
///
/// The same by alignment of the early wavefront (AlignedShifts over `wavefront`): each channel's
/// shift against the reference's same channel, and each pair's difference of shifts. A whole
/// early waveform is compared, not one level crossing, so a later packet that the two models
/// weigh differently does not move it.
struct WavefrontWindow {
  int64_t samples{0};     // compared from the start of the record
  double max_lag_s{0.0};  // shifts searched within +-max_lag_s
};
struct TimingError {
  double arrival_us{0.0};
  double delay_us{0.0};
  double delay_max_us{0.0};
  std::vector<double> arrival_errors_us;        // (channels) |arrival error|
  std::vector<double> delay_errors_us;          // (pairs) |inter-channel delay error|
  std::vector<double> shift_errors_us;          // (channels) |aligned shift|
  std::vector<double> aligned_delay_errors_us;  // (pairs) |difference of aligned shifts|
};
TimingError TimingErrorUs(const Eigen::MatrixXd& y, const Eigen::MatrixXd& ref,
                          double sample_rate_hz, const WavefrontWindow& wavefront);

/// Each channel of y against the same channel of ref (both channels x samples, band-limited
/// below Nyquist): the lag (s; positive, y later) within +-max_lag_s that maximizes their
/// cross-correlation over the first `samples` samples (zero outside), between samples from the
/// correlation interpolated by a windowed sinc. (channels)
Eigen::VectorXd AlignedShifts(const Eigen::MatrixXd& y, const Eigen::MatrixXd& ref,
                              double sample_rate_hz, const WavefrontWindow& wavefront);

/// (7) octave-band energies (centres 250 Hz to 16 kHz) summed over channels.
Eigen::VectorXd OctaveEnergies(const Eigen::MatrixXd& y, double sample_rate_hz);

/// Mean |dB| difference over the bands that hold energy in the reference.
double BandEnergyErrorDb(const Eigen::VectorXd& e, const Eigen::VectorXd& ref);

/// y low-passed at cutoff_hz by a zero-phase windowed-sinc FIR (Blackman, `taps` odd), so that
/// two models of different bands are compared in the band both hold; zero outside the record.
Eigen::MatrixXd LowPass(const Eigen::MatrixXd& y, double cutoff_hz, double sample_rate_hz,
                        int64_t taps = 101);

/// Mode frequencies of a rung against the reference's, matched by rank below max_hz: the modes
/// each holds there, and the median and max |f / f_ref - 1| (%) over the ranks both hold.
struct FrequencyError {
  int64_t modes{0}, reference_modes{0};
  double median_pct{0.0}, max_pct{0.0};
};
FrequencyError RankedFrequencyError(const Eigen::VectorXd& f_hz, const Eigen::VectorXd& ref_hz,
                                    double max_hz);

}  // namespace sonicboom::experiments
