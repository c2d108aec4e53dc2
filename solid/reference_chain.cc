#include "sonicboom/solid/reference_chain.h"

#include <algorithm>
#include <cmath>
#include <numbers>

#include "sonicboom/core/errors.h"

namespace sonicboom::solid {
namespace {

// first-order sections by the bilinear transform with pre-warped corner: y = b0 x + b1 x1 - a1 y1
struct FirstOrder {
  double b0, b1, a1;
};
FirstOrder HighPass(double corner_hz, double fs) {
  const double k = std::tan(std::numbers::pi * corner_hz / fs);
  return {1.0 / (1.0 + k), -1.0 / (1.0 + k), (k - 1.0) / (k + 1.0)};
}
FirstOrder LowPass(double corner_hz, double fs) {
  const double k = std::tan(std::numbers::pi * corner_hz / fs);
  return {k / (1.0 + k), k / (1.0 + k), (k - 1.0) / (k + 1.0)};
}

}  // namespace

ReferenceChainDraw DrawReferenceChain(Rng* rng, int mics) {
  ReferenceChainDraw d;
  d.full_scale_strain = 1e-3 * std::pow(10.0, rng->Uniform(-6.0, 6.0) / 20.0);
  for (int m = 0; m < mics; ++m) {
    d.gain_db.push_back(rng->Uniform(-3.0, 3.0));
    d.high_pass_hz.push_back(20.0 * std::pow(20.0, rng->Uniform()));  // 20-400 Hz
  }
  d.low_pass_hz = rng->Uniform(10000.0, 20000.0);
  d.noise_dbfs = rng->Uniform(-80.0, -60.0);
  return d;
}

Eigen::MatrixXf ApplyReferenceChain(const Eigen::MatrixXd& strain, const ReferenceChainDraw& draw,
                                    double sample_rate_hz, Rng* noise, bool* clipped) {
  SONICBOOM_DEMAND(static_cast<Eigen::Index>(draw.gain_db.size()) == strain.rows());
  const double low = std::min(draw.low_pass_hz, 0.45 * sample_rate_hz);
  const FirstOrder lp = LowPass(low, sample_rate_hz);
  const double noise_rms = std::pow(10.0, draw.noise_dbfs / 20.0);
  Eigen::MatrixXf out(strain.rows(), strain.cols());
  *clipped = false;
  for (Eigen::Index m = 0; m < strain.rows(); ++m) {
    const FirstOrder hp = HighPass(draw.high_pass_hz[m], sample_rate_hz);
    const double gain = std::pow(10.0, draw.gain_db[m] / 20.0) / draw.full_scale_strain;
    double hx = 0.0, hy = 0.0, lx = 0.0, ly = 0.0;
    for (Eigen::Index k = 0; k < strain.cols(); ++k) {
      const double x = gain * strain(m, k);
      const double h = hp.b0 * x + hp.b1 * hx - hp.a1 * hy;
      hx = x;
      hy = h;
      const double l = lp.b0 * h + lp.b1 * lx - lp.a1 * ly;
      lx = h;
      ly = l;
      double y = l + noise_rms * noise->Normal();
      if (std::abs(y) >= 1.0) {
        *clipped = true;
        y = std::clamp(y, -1.0, 1.0);
      }
      out(m, k) = static_cast<float>(y);
    }
  }
  return out;
}

}  // namespace sonicboom::solid
