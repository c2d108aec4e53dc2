#pragma once
/// How the fidelity ladder (experiments/fidelity.cc) scores a rung's signal against the
/// reference's: signals are (channels x samples) sensor strain at one sample rate, both starting
/// at the same instant. Private to experiments.

#include <Eigen/Core>
#include <vector>
#include <cstdint>

#include "internal/statistics.h"

namespace sonicboom::experiments {

/// Relative L2 error over all channels, ||y - ref|| / ||ref||.
double RelativeError(const Eigen::MatrixXd& y, const Eigen::MatrixXd& ref);

/// Timing of y against ref, microseconds, from each channel's first arrival (the first time its
/// |signal| reaches 20 % of its own peak, solid::ThresholdArrivals): mean over channels of
/// |arrival error|, and mean and max over channel pairs of |inter-channel delay error|; and each
/// channel's and pair's error, for medians over many strikes (a threshold that lands on another
/// wave packet in one channel moves its arrival by hundreds of microseconds and dominates a mean).
struct TimingError {
  double arrival_us{0.0};
  double delay_us{0.0};
  double delay_max_us{0.0};
  std::vector<double> arrival_errors_us;  // (channels) |arrival error|
  std::vector<double> delay_errors_us;    // (pairs) |inter-channel delay error|
};
TimingError TimingErrorUs(const Eigen::MatrixXd& y, const Eigen::MatrixXd& ref,
                          double sample_rate_hz);

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
