#include "sonicboom/solid/convergence.h"

#include <chrono>
#include <filesystem>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include "sonicboom/core/cache_file.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/solid/reference_tube.h"
#include "sonicboom/solid/solid_modes.h"
#include "sonicboom/solid/solid_response.h"

namespace sonicboom::solid {
namespace {

// bump when what a level computes changes (the modes' own version is in ReferenceCacheKey)
constexpr int kConvergenceVersion = 1;
constexpr char kMagic[8] = {'S', 'B', 'C', 'O', 'N', 'V', '0', '1'};

// where a level of `key` is kept in cache_dir
std::string LevelPath(const std::string& cache_dir, const std::string& key) {
  return (std::filesystem::path(cache_dir) /
          fmt::format("level-{:016x}.bin", internal::Fnv1a(key.data(), key.size())))
      .string();
}

// the level's file: header {modes, probes, sensors, dofs}, {h, build, solve}, f, arrivals
bool ReadLevel(const ConvergenceRequest& r, const std::string& key, ConvergenceLevel* level) {
  internal::CacheFileReader in;
  int64_t header[4] = {0, 0, 0, 0};
  if (!in.Open(LevelPath(r.solid.cache_dir, key), kMagic, key, header, 4)) return false;
  const int64_t probes = static_cast<int64_t>(r.probes.size()), sensors = r.solid.mics.count();
  if (header[0] < 0 || header[0] > (1 << 20) || header[1] != probes || header[2] != sensors)
    return false;
  double times[3] = {0.0, 0.0, 0.0};
  level->f_hz.resize(header[0]);
  std::vector<double> t(probes * sensors);
  in.Read(times, sizeof(times));
  in.Read(level->f_hz.data(), sizeof(double) * level->f_hz.size());
  in.Read(t.data(), sizeof(double) * t.size());
  if (!in.Finish()) return false;
  level->dofs = header[3];
  level->h_m = times[0];
  level->build_s = times[1];
  level->solve_s = times[2];
  level->t_s.assign(probes, std::vector<double>(sensors));
  for (int64_t p = 0; p < probes; ++p) {
    for (int64_t s = 0; s < sensors; ++s) level->t_s[p][s] = t[p * sensors + s];
  }
  level->from_cache = true;
  return true;
}

void WriteLevel(const ConvergenceRequest& r, const std::string& key,
                const ConvergenceLevel& level) {
  const double times[3] = {level.h_m, level.build_s, level.solve_s};
  std::vector<double> t;
  for (const auto& row : level.t_s) t.insert(t.end(), row.begin(), row.end());
  internal::WriteCacheFile(
      r.solid.cache_dir, LevelPath(r.solid.cache_dir, key), kMagic, key,
      {static_cast<int64_t>(level.f_hz.size()), static_cast<int64_t>(r.probes.size()),
       r.solid.mics.count(), level.dofs},
      {{times, sizeof(times)},
       {level.f_hz.data(), sizeof(double) * level.f_hz.size()},
       {t.data(), sizeof(double) * t.size()}});
}

}  // namespace

std::vector<ConvergenceProbe> DefaultConvergenceProbes() {
  return {{0.0, 60.0}, {0.05, 180.0}, {-0.07, 300.0}, {0.09, 20.0}};
}

std::string ConvergenceLevelKey(const ConvergenceRequest& r) {
  std::vector<std::string> probes;
  for (const ConvergenceProbe& p : r.probes)
    probes.push_back(fmt::format("{:.17g}@{:.17g}", p.z_m, p.theta_deg));
  return fmt::format("convergence v{} {} loss {:.17g} probes {}", kConvergenceVersion,
                     ReferenceCacheKey(r.solid), r.solid.material.loss_factor,
                     fmt::join(probes, ","));
}

std::vector<std::vector<double>> ProbeArrivals(const Eigen::VectorXd& omega_rad_s,
                                               const Eigen::MatrixXd& sensor_modal,
                                               const Eigen::MatrixXd& probe_modal,
                                               double loss_factor) {
  PulseResponseConfig pulse;
  pulse.loss_factor = loss_factor;
  std::vector<std::vector<double>> t;
  for (Eigen::Index p = 0; p < probe_modal.rows(); ++p) {
    const Eigen::MatrixXd y =
        PulseResponse(omega_rad_s, sensor_modal, probe_modal.row(p).transpose(), pulse);
    const Eigen::VectorXd a = ThresholdArrivals(y, pulse.sample_rate_hz, 0.2);
    t.emplace_back(a.data(), a.data() + a.size());
  }
  return t;
}

ConvergenceLevel SolveConvergenceLevel(const ConvergenceRequest& r) {
  const ReferenceTubeConfig& c = r.solid;
  const std::string key = c.cache_dir.empty() ? "" : ConvergenceLevelKey(r);
  ConvergenceLevel level;
  if (!c.cache_dir.empty() && ReadLevel(r, key, &level)) return level;
  // the model, its sensor rows and each probe's radial drive as projections of every shape
  const auto t0 = std::chrono::steady_clock::now();
  const SolidTubeModel model(c.tube, c.material, c.structure, c.mesh);
  const int64_t probes = static_cast<int64_t>(r.probes.size()), discs = c.mics.count();
  SolidModeRequest request;
  request.max_frequency_hz = c.max_frequency_hz;
  request.with_shapes = false;
  request.projection_rows.resize(discs + probes, model.dofs());
  request.projection_rows.topRows(discs) = model.SensorRows(c.mics);
  for (int64_t p = 0; p < probes; ++p) {
    request.projection_rows.row(discs + p) =
        model.RadialForceWeights(r.probes[p].z_m, r.probes[p].theta_deg * kPi / 180.0).transpose();
  }
  const auto t1 = std::chrono::steady_clock::now();
  const SolidModes modes = SolveSolidModes(model, request);
  const auto t2 = std::chrono::steady_clock::now();
  level.h_m = model.element_length_m();
  level.dofs = model.dofs();
  level.build_s = std::chrono::duration<double>(t1 - t0).count();
  level.solve_s = std::chrono::duration<double>(t2 - t1).count();
  for (Eigen::Index k = 0; k < modes.omega_rad_s.size(); ++k) {
    level.f_hz.push_back(modes.omega_rad_s(k) / (2.0 * kPi));
  }
  level.t_s = ProbeArrivals(modes.omega_rad_s, modes.projections.topRows(discs),
                            modes.projections.bottomRows(probes), c.material.loss_factor);
  if (!c.cache_dir.empty()) WriteLevel(r, key, level);
  return level;
}

}  // namespace sonicboom::solid
