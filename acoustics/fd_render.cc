#include "sonicboom/acoustics/fd_render.h"

#include <algorithm>
#include <cmath>
#include <utility>
#include <vector>

namespace sonicboom::acoustics {

Eigen::MatrixXd FdRender(const ShellModel& model, const ShellFd& fd,
                         std::span<const ForceInput> forces, const Eigen::MatrixXd& sensor_rows,
                         int64_t samples, double decay_floor_db) {
  const int64_t over = fd.oversampling();
  // each force's nodal weights (sparse: the four w nodes around its point)
  std::vector<std::vector<std::pair<int64_t, double>>> weights(forces.size());
  int64_t force_end = 0;
  for (size_t e = 0; e < forces.size(); ++e) {
    const Eigen::VectorXd w = model.RadialForceWeights(forces[e].z_m, forces[e].theta_rad);
    for (Eigen::Index d = 0; d < w.size(); ++d) {
      if (w[d] != 0.0) weights[e].push_back({d, w[d]});
    }
    force_end = std::max<int64_t>(
        force_end, forces[e].first_sample + static_cast<int64_t>(forces[e].force_n.size()));
  }
  // a force sample is the mean over its sample interval: place it mid-sample, linear between
  auto force_at = [&](const ForceInput& f, double t_samples) {
    const double x = t_samples - 0.5 - static_cast<double>(f.first_sample);
    const int64_t i = static_cast<int64_t>(std::floor(x));
    const double frac = x - std::floor(x);
    auto at = [&](int64_t j) {
      return j >= 0 && j < static_cast<int64_t>(f.force_n.size())
                 ? f.force_n[static_cast<size_t>(j)]
                 : 0.0;
    };
    return (1 - frac) * at(i) + frac * at(i + 1);
  };
  ShellFdState state = fd.Rest();
  Eigen::VectorXd nodal = Eigen::VectorXd::Zero(model.dofs());
  Eigen::MatrixXd strain = Eigen::MatrixXd::Zero(sensor_rows.rows(), samples);
  const double energy_floor = std::pow(10.0, decay_floor_db / 10.0);
  double peak_energy = 0.0;
  for (int64_t k = 0; k < samples; ++k) {
    strain.col(k) = sensor_rows * state.current;
    for (int64_t s = 0; s < over; ++s) {
      const double t = k + static_cast<double>(s) / over;
      for (size_t e = 0; e < forces.size(); ++e) {
        const double f = force_at(forces[e], t);
        // a positive force pushes the wall inward: against the outward weights
        for (const auto& [d, w] : weights[e]) nodal[d] -= w * f;
      }
      fd.Step(&state, nodal);
      for (size_t e = 0; e < forces.size(); ++e) {
        for (const auto& [d, w] : weights[e]) nodal[d] = 0.0;
      }
    }
    // after the last force, stop once the energy has decayed past the floor
    if ((k & 1023) == 1023) {
      const double energy = fd.Energy(state);
      peak_energy = std::max(peak_energy, energy);
      if (k > force_end && energy < energy_floor * peak_energy) break;
    }
  }
  return strain;
}

}  // namespace sonicboom::acoustics
