#pragma once
/// The reference family's own sensor chain, drawn per strike from its own ranges (not the
/// ranges of acoustics/daq.h and acoustics/randomize.h): disc sensitivity, the disc's capacitance
/// into the input (a first-order high-pass), cable and preamp (a first-order low-pass), white
/// noise, clipping at full scale.

#include <Eigen/Core>
#include <vector>

#include "sonicboom/core/rng.h"

namespace sonicboom::solid {

struct ReferenceChainDraw {
  double full_scale_strain{1e-3};    // strain that reaches full scale at 0 dB
  std::vector<double> gain_db;       // (mics) each disc's sensitivity, dB
  std::vector<double> high_pass_hz;  // (mics) first-order high-pass corner
  double low_pass_hz{16000.0};       // first-order low-pass corner, every channel
  double noise_dbfs{-70.0};          // white noise, rms, dB re full scale
};

/// One draw: full scale 1e-3 strain x 10^(U(-6, 6) / 20), gains U(-3, 3) dB, high-pass corners
/// log-uniform in [20, 400] Hz, low-pass U(10, 20) kHz, noise U(-80, -60) dBFS.
ReferenceChainDraw DrawReferenceChain(Rng* rng, int mics);

/// (mics x samples) strain -> full-scale audio in [-1, 1]; noise from `noise`; *clipped tells
/// whether a sample hit full scale.
Eigen::MatrixXf ApplyReferenceChain(const Eigen::MatrixXd& strain, const ReferenceChainDraw& draw,
                                    double sample_rate_hz, Rng* noise, bool* clipped);

}  // namespace sonicboom::solid
