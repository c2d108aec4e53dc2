#include "sonicboom/solid/convergence.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <tuple>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>
#include <Eigen/QR>

#include "sonicboom/core/cache_file.h"
#include "sonicboom/core/constants.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/solid/reference_tube.h"
#include "sonicboom/solid/solid_modes.h"
#include "sonicboom/solid/solid_response.h"

namespace sonicboom::solid {
namespace {

// bump when what a level computes changes (the modes' own version is in ReferenceCacheKey)
constexpr int kConvergenceVersion = 2;  // 2: the shape signatures
constexpr char kMagic[8] = {'S', 'B', 'C', 'O', 'N', 'V', '0', '2'};
// modes closer than this (relative) are one degenerate set: a mesh may return any basis of it
constexpr double kDegenerate = 1e-4;

// where a level of `key` is kept in cache_dir
std::string LevelPath(const std::string& cache_dir, const std::string& key) {
  return (std::filesystem::path(cache_dir) /
          fmt::format("level-{:016x}.bin", internal::Fnv1a(key.data(), key.size())))
      .string();
}

// the level's file: header {modes, probes, sensors, dofs, signature rows}, {h, build, solve}, f,
// arrivals, signature
bool ReadLevel(const ConvergenceRequest& r, const std::string& key, ConvergenceLevel* level) {
  internal::CacheFileReader in;
  int64_t header[5] = {0, 0, 0, 0, 0};
  if (!in.Open(LevelPath(r.solid.cache_dir, key), kMagic, key, header, 5)) return false;
  const int64_t probes = static_cast<int64_t>(r.probes.size()), sensors = r.solid.mics.count();
  if (header[0] < 0 || header[0] > (1 << 20) || header[1] != probes || header[2] != sensors ||
      header[4] != 3 * r.signature_points)
    return false;
  double times[3] = {0.0, 0.0, 0.0};
  level->f_hz.resize(header[0]);
  std::vector<double> t(probes * sensors);
  level->signature.resize(header[4], header[0]);
  in.Read(times, sizeof(times));
  in.Read(level->f_hz.data(), sizeof(double) * level->f_hz.size());
  in.Read(t.data(), sizeof(double) * t.size());
  in.Read(level->signature.data(), sizeof(double) * level->signature.size());
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
       r.solid.mics.count(), level.dofs, level.signature.rows()},
      {{times, sizeof(times)},
       {level.f_hz.data(), sizeof(double) * level.f_hz.size()},
       {t.data(), sizeof(double) * t.size()},
       {level.signature.data(), sizeof(double) * level.signature.size()}});
}

}  // namespace

std::vector<ConvergenceProbe> DefaultConvergenceProbes() {
  return {{0.0, 60.0}, {0.05, 180.0}, {-0.07, 300.0}, {0.09, 20.0}};
}

std::string ConvergenceLevelKey(const ConvergenceRequest& r) {
  std::vector<std::string> probes;
  for (const ConvergenceProbe& p : r.probes)
    probes.push_back(fmt::format("{:.17g}@{:.17g}", p.z_m, p.theta_deg));
  return fmt::format("convergence v{} {} loss {:.17g} probes {} signature {}", kConvergenceVersion,
                     ReferenceCacheKey(r.solid), r.solid.material.loss_factor,
                     fmt::join(probes, ","), r.signature_points);
}

std::vector<std::pair<double, double>> SignaturePoints(const TubeConfig& tube, int64_t count) {
  // z evenly over the middle 0.9 of the length, theta advancing by the golden angle
  const double golden_rad = kPi * (3.0 - std::sqrt(5.0));
  std::vector<std::pair<double, double>> points;
  for (int64_t i = 0; i < count; ++i) {
    const double z = 0.45 * tube.length_m * (2.0 * (i + 0.5) / count - 1.0);
    points.emplace_back(z, std::fmod(golden_rad * i, 2.0 * kPi));
  }
  return points;
}

std::vector<ModeMatch> MatchModesByShape(const std::vector<double>& f_from_hz,
                                         const Eigen::MatrixXd& from,
                                         const std::vector<double>& f_to_hz,
                                         const Eigen::MatrixXd& to, double window) {
  SONICBOOM_DEMAND(from.cols() == static_cast<Eigen::Index>(f_from_hz.size()) &&
                   to.cols() == static_cast<Eigen::Index>(f_to_hz.size()) &&
                   from.rows() == to.rows());
  // each `from` mode's span: an orthonormal basis of its own signature and those of the modes
  // degenerate with it (within kDegenerate), whose shapes any mesh may mix
  const size_t n_from = f_from_hz.size();
  std::vector<Eigen::MatrixXd> span(n_from);
  for (size_t i = 0, first = 0; i < n_from; ++i) {
    while (f_from_hz[first] < f_from_hz[i] * (1.0 - kDegenerate)) ++first;
    size_t last = i;
    while (last + 1 < n_from && f_from_hz[last + 1] <= f_from_hz[i] * (1.0 + kDegenerate)) ++last;
    const Eigen::MatrixXd cols = from.middleCols(first, last - first + 1);
    const Eigen::ColPivHouseholderQR<Eigen::MatrixXd> qr(cols);
    const Eigen::MatrixXd q =
        qr.householderQ() * Eigen::MatrixXd::Identity(cols.rows(), cols.cols());
    span[i] = q.leftCols(qr.rank());
  }
  // every pair within the window (both lists ascending), as (MAC, to, from)
  std::vector<std::tuple<double, int64_t, int64_t>> pairs;
  size_t lo = 0;
  for (size_t j = 0; j < f_to_hz.size(); ++j) {
    while (lo < n_from && f_from_hz[lo] < f_to_hz[j] * (1.0 - window)) ++lo;
    const double norm_sq = to.col(j).squaredNorm();
    for (size_t i = lo; i < n_from && f_from_hz[i] <= f_to_hz[j] * (1.0 + window); ++i) {
      const double in_span = (span[i].transpose() * to.col(j)).squaredNorm();
      pairs.emplace_back(norm_sq > 0.0 ? in_span / norm_sq : 0.0, j, i);
    }
  }
  // the best pairs first; ties by frequency order, so the result does not depend on the sort
  std::sort(pairs.begin(), pairs.end(), [](const auto& a, const auto& b) {
    if (std::get<0>(a) != std::get<0>(b)) return std::get<0>(a) > std::get<0>(b);
    return std::make_pair(std::get<1>(a), std::get<2>(a)) <
           std::make_pair(std::get<1>(b), std::get<2>(b));
  });
  std::vector<ModeMatch> match(f_to_hz.size());
  std::vector<bool> used(f_from_hz.size(), false);
  for (const auto& [mac, j, i] : pairs) {
    if (match[j].from >= 0 || used[i] || mac <= 0.0) continue;
    match[j] = {i, mac};
    used[i] = true;
  }
  return match;
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
  // (discs + 3 probes + 3 signature points) x dofs: the discs, the probes' radial drive (the
  // first of each point's three rows) and the signature
  std::vector<std::pair<double, double>> points;
  for (const ConvergenceProbe& p : r.probes) points.emplace_back(p.z_m, p.theta_deg * kPi / 180.0);
  const std::vector<std::pair<double, double>> signature =
      SignaturePoints(c.tube, r.signature_points);
  points.insert(points.end(), signature.begin(), signature.end());
  const Eigen::SparseMatrix<double, Eigen::RowMajor> surface = model.SurfacePointRows(points);
  const Eigen::SparseMatrix<double, Eigen::RowMajor> sensors =
      model.SensorRows(c.mics).sparseView();
  request.projection_rows.resize(discs + surface.rows(), model.dofs());
  request.projection_rows.topRows(discs) = sensors;
  request.projection_rows.bottomRows(surface.rows()) = surface;
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
  Eigen::MatrixXd drive(probes, modes.omega_rad_s.size());  // (probes x modes) radial drive
  for (int64_t p = 0; p < probes; ++p) drive.row(p) = modes.projections.row(discs + 3 * p);
  level.t_s = ProbeArrivals(modes.omega_rad_s, modes.projections.topRows(discs), drive,
                            c.material.loss_factor);
  level.signature = modes.projections.bottomRows(3 * r.signature_points);
  if (!c.cache_dir.empty()) WriteLevel(r, key, level);
  return level;
}

}  // namespace sonicboom::solid
