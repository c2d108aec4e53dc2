#include "sonicboom/acoustics/shell_modes.h"

#include <Eigen/SparseCholesky>
#include <Spectra/SymEigsShiftSolver.h>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "sonicboom/core/errors.h"

namespace sonicboom::acoustics {
namespace {

constexpr double kPi = std::numbers::pi;
constexpr int64_t kMaxModes = 20000;
// modes sought per shift-invert slice
constexpr Eigen::Index kSliceModes = 48;
// eigenvalues within this relative distance of a slice's farthest one are left to the next slice
// (a degenerate pair is never split between slices)
constexpr double kEdgeTolerance = 1e-6;

using SpMat = Eigen::SparseMatrix<double>;
using Ldlt = Eigen::SimplicialLDLT<SpMat, Eigen::Lower, Eigen::AMDOrdering<int>>;

// A - sigma I
SpMat Shifted(const SpMat& a, double sigma) {
  SpMat shifted = a;
  for (Eigen::Index i = 0; i < a.rows(); ++i) shifted.coeffRef(i, i) -= sigma;
  return shifted;
}

// Number of eigenvalues of A below sigma: negative pivots of LDL^T(A - sigma I)
int64_t NegativePivots(const SpMat& a, double sigma) {
  Ldlt ldlt(Shifted(a, sigma));
  SONICBOOM_DEMAND(ldlt.info() == Eigen::Success);
  return (ldlt.vectorD().array() < 0.0).count();
}

// Spectra operator y = (A - sigma I)^-1 x by a sparse LDL^T factorization
class ShiftInvert {
 public:
  using Scalar = double;
  explicit ShiftInvert(const SpMat& a) : a_(a) {}
  Eigen::Index rows() const { return a_.rows(); }
  Eigen::Index cols() const { return a_.cols(); }
  void set_shift(double sigma) {
    ldlt_.compute(Shifted(a_, sigma));
    if (ldlt_.info() != Eigen::Success) {
      throw Error(fmt::format("shell modes: the factorization at shift {} Hz failed",
                              std::sqrt(std::abs(sigma)) / (2.0 * kPi)));
    }
  }
  // Found eigenvectors (orthonormal columns) to project out: P (A - sigma I)^-1 P with
  // P = I - Q Q^T maps them to 0, so a slice finds only modes not yet found (a Lanczos run can
  // miss copies of a repeated eigenvalue; a run with the found ones deflated recovers them)
  void set_deflation(Eigen::MatrixXd q) { q_ = std::move(q); }
  void perform_op(const double* x_in, double* y_out) const {
    Eigen::Map<const Eigen::VectorXd> x(x_in, a_.rows());
    Eigen::Map<Eigen::VectorXd> y(y_out, a_.rows());
    if (q_.cols() == 0) {
      y = ldlt_.solve(x);
      return;
    }
    const Eigen::VectorXd px = x - q_ * (q_.transpose() * x);
    y = ldlt_.solve(px);
    y -= q_ * (q_.transpose() * y);
  }

 private:
  const SpMat& a_;
  Ldlt ldlt_;
  Eigen::MatrixXd q_;  // (dofs x found)
};

}  // namespace

int64_t CountModesBelow(const ShellModel& model, double f_hz) {
  const double omega = 2.0 * kPi * f_hz;
  return NegativePivots(model.MassScaledStiffness(), omega * omega);
}

ShellModes SolveShellModes(const ShellModel& model, double max_frequency_hz, int64_t max_count,
                           bool with_shapes) {
  if (!(max_frequency_hz > 0.0) && max_count <= 0) {
    throw ConfigError("shell modes need a frequency limit or a mode count");
  }
  if (max_count > kMaxModes) {
    throw ConfigError(fmt::format("shell modes: {} modes requested, at most {}", max_count, kMaxModes));
  }
  const SpMat a = model.MassScaledStiffness();
  const Eigen::Index n = a.rows();
  const double rigid_lambda = std::pow(2.0 * kPi * kRigidBodyHz, 2);
  const double cut_lambda =
      max_frequency_hz > 0.0 ? std::pow(2.0 * kPi * max_frequency_hz, 2) : 0.0;
  int64_t below_cut = -1;
  if (cut_lambda > 0.0) {
    below_cut = NegativePivots(a, cut_lambda);
    if (below_cut - 12 > kMaxModes) {
      throw ConfigError(fmt::format("shell modes: {} modes lie below {} Hz, at most {}; lower the "
                                    "band or coarsen shell.grid_spacing_m",
                                    below_cut, max_frequency_hz, kMaxModes));
    }
  }

  // walk up the spectrum: each slice finds the eigenvalues nearest its shift (the last accepted
  // one) and accepts those above it, short of the farthest (which may have an unfound twin)
  std::vector<double> lambdas;
  std::vector<Eigen::VectorXd> vectors;
  ShiftInvert op(a);
  double lo = -rigid_lambda;  // below every eigenvalue of the PSD A
  double next_above = std::numeric_limits<double>::infinity();
  int64_t elastic = 0;
  auto done = [&] {
    if (max_count > 0 && elastic >= max_count) return true;
    if (below_cut >= 0 && static_cast<int64_t>(lambdas.size()) >= below_cut) return true;
    return static_cast<Eigen::Index>(lambdas.size()) >= n;
  };
  // one Lanczos run near sigma: (eigenvalues ascending, eigenvectors)
  auto slice = [&](double sigma, Eigen::Index nev) {
    const Eigen::Index ncv = std::min<Eigen::Index>(n, 3 * nev + 20);
    Spectra::SymEigsShiftSolver<ShiftInvert> solver(op, nev, ncv, sigma);
    solver.init();
    solver.compute(Spectra::SortRule::LargestMagn, 2000, 1e-9, Spectra::SortRule::SmallestAlge);
    if (solver.info() != Spectra::CompInfo::Successful) {
      throw Error(fmt::format("shell modes: Lanczos did not converge near {:.1f} Hz",
                              std::sqrt(std::max(sigma, 0.0)) / (2.0 * kPi)));
    }
    return std::pair{Eigen::VectorXd(solver.eigenvalues()), Eigen::MatrixXd(solver.eigenvectors())};
  };
  // the found vectors with eigenvalues from `from` up, as deflation
  auto deflate_from = [&](double from) {
    std::vector<Eigen::Index> cols;
    for (size_t k = 0; k < lambdas.size(); ++k) {
      if (lambdas[k] >= from) cols.push_back(static_cast<Eigen::Index>(k));
    }
    Eigen::MatrixXd q(n, static_cast<Eigen::Index>(cols.size()));
    for (size_t c = 0; c < cols.size(); ++c) q.col(static_cast<Eigen::Index>(c)) = vectors[static_cast<size_t>(cols[c])];
    op.set_deflation(std::move(q));
  };
  auto accept = [&](double v, const Eigen::VectorXd& vec) {
    lambdas.push_back(v);
    vectors.push_back(vec);
    if (v >= rigid_lambda) ++elastic;
  };
  double slice_start = lo;
  while (!done()) {
    // modes still wanted (a few more, for the edge and the rigid-body ones)
    int64_t wanted = kSliceModes;
    if (max_count > 0) wanted = std::min<int64_t>(wanted, max_count - elastic + 12);
    if (below_cut >= 0) wanted = std::min<int64_t>(wanted, below_cut - static_cast<int64_t>(lambdas.size()) + 12);
    const Eigen::Index nev = std::min<Eigen::Index>(std::max<int64_t>(wanted, 8), n - 1);
    deflate_from(slice_start);
    const auto [values, vecs] = slice(lo, nev);
    const double farthest = values.maxCoeff();
    const double edge = farthest - kEdgeTolerance * std::max(std::abs(farthest), 1.0);
    const double floor = lo + kEdgeTolerance * std::max(std::abs(lo), 1.0);
    double new_lo = lo;
    next_above = std::numeric_limits<double>::infinity();
    for (Eigen::Index k = 0; k < values.size(); ++k) {
      const double v = values[k];
      if (v <= floor && !lambdas.empty()) continue;
      if (v >= edge) {
        next_above = std::min(next_above, v);
        continue;
      }
      // once enough are found, only the twins of the last accepted one are still taken
      const bool twin = !lambdas.empty() &&
                        v - new_lo <= kEdgeTolerance * std::max(std::abs(new_lo), 1.0);
      if (done() && !twin) {
        next_above = std::min(next_above, v);
        continue;
      }
      accept(v, vecs.col(k));
      new_lo = std::max(new_lo, v);
    }
    if (new_lo == lo) {
      throw Error(fmt::format("shell modes: no progress past {:.1f} Hz",
                              std::sqrt(std::max(lo, 0.0)) / (2.0 * kPi)));
    }
    // completeness up to the gap above new_lo: Lanczos can miss copies of a repeated
    // eigenvalue; rerun with everything found in this range deflated until the count is right
    const double probe = std::isfinite(next_above) ? 0.5 * (new_lo + next_above)
                                                   : new_lo + kEdgeTolerance * std::max(std::abs(new_lo), 1.0);
    for (int attempt = 0;; ++attempt) {
      const int64_t expected = NegativePivots(a, probe);
      const int64_t have = static_cast<int64_t>(lambdas.size());
      if (expected == have) break;
      if (attempt == 3 || expected < have) {
        throw Error(fmt::format("shell modes: {} modes found below {:.2f} Hz but the inertia count "
                                "is {}", have, std::sqrt(std::max(probe, 0.0)) / (2.0 * kPi), expected));
      }
      deflate_from(slice_start);
      const auto [more, more_vecs] = slice(lo, std::min<Eigen::Index>(expected - have + 8, n - 1));
      for (Eigen::Index k = 0; k < more.size(); ++k) {
        if (more[k] < probe && have + k < expected) accept(more[k], more_vecs.col(k));
      }
    }
    slice_start = lo;
    lo = new_lo;
  }
  op.set_deflation(Eigen::MatrixXd());

  // completeness: exactly the accepted modes lie below the gap after the last one
  std::vector<size_t> order(lambdas.size());
  for (size_t k = 0; k < order.size(); ++k) order[k] = k;
  std::stable_sort(order.begin(), order.end(), [&](size_t x, size_t y) { return lambdas[x] < lambdas[y]; });
  ShellModes out;
  std::vector<size_t> kept;
  for (size_t k : order) {
    if (lambdas[k] < rigid_lambda) {
      ++out.rigid_body_modes;
    } else if (cut_lambda <= 0.0 || lambdas[k] <= cut_lambda) {
      kept.push_back(k);
    }
  }
  if (max_count > 0 && static_cast<int64_t>(kept.size()) > max_count) kept.resize(static_cast<size_t>(max_count));
  out.omega_rad_s.resize(static_cast<Eigen::Index>(kept.size()));
  if (with_shapes) out.shapes.resize(n, static_cast<Eigen::Index>(kept.size()));
  const Eigen::VectorXd inv_sqrt_mass = model.mass_kg().cwiseSqrt().cwiseInverse();
  for (size_t c = 0; c < kept.size(); ++c) {
    out.omega_rad_s[static_cast<Eigen::Index>(c)] = std::sqrt(std::max(lambdas[kept[c]], 0.0));
    if (with_shapes) {
      out.shapes.col(static_cast<Eigen::Index>(c)) = inv_sqrt_mass.cwiseProduct(vectors[kept[c]]);
    }
  }
  return out;
}

namespace {

constexpr char kCacheMagic[8] = {'S', 'B', 'M', 'O', 'D', 'E', 'S', '1'};

uint64_t Fnv1a(const std::string& text) {
  uint64_t h = 1469598103934665603ull;
  for (unsigned char c : text) {
    h ^= c;
    h *= 1099511628211ull;
  }
  return h;
}

// file layout: magic, key length, key, rigid, modes, rows, omega (modes), shapes (rows x modes)
bool ReadModes(const std::string& path, const std::string& key, ShellModes* out) {
  std::ifstream in(path, std::ios::binary);
  if (!in) return false;
  char magic[8];
  uint64_t key_size = 0;
  in.read(magic, 8);
  in.read(reinterpret_cast<char*>(&key_size), sizeof key_size);
  if (!in || std::memcmp(magic, kCacheMagic, 8) != 0 || key_size != key.size()) return false;
  std::string stored(key_size, '\0');
  in.read(stored.data(), static_cast<std::streamsize>(key_size));
  int64_t header[3];
  in.read(reinterpret_cast<char*>(header), sizeof header);
  if (!in || stored != key || header[1] < 0 || header[2] < 0) return false;
  out->rigid_body_modes = header[0];
  out->omega_rad_s.resize(header[1]);
  out->shapes.resize(header[2], header[2] > 0 ? header[1] : 0);
  in.read(reinterpret_cast<char*>(out->omega_rad_s.data()),
          static_cast<std::streamsize>(sizeof(double) * out->omega_rad_s.size()));
  in.read(reinterpret_cast<char*>(out->shapes.data()),
          static_cast<std::streamsize>(sizeof(double) * out->shapes.size()));
  return static_cast<bool>(in) && in.peek() == std::char_traits<char>::eof();
}

void WriteModes(const std::string& path, const std::string& key, const ShellModes& modes) {
  const std::string partial = path + ".partial";
  {
    std::ofstream out(partial, std::ios::binary | std::ios::trunc);
    const uint64_t key_size = key.size();
    const int64_t header[3] = {modes.rigid_body_modes, modes.omega_rad_s.size(), modes.shapes.rows()};
    out.write(kCacheMagic, 8);
    out.write(reinterpret_cast<const char*>(&key_size), sizeof key_size);
    out.write(key.data(), static_cast<std::streamsize>(key.size()));
    out.write(reinterpret_cast<const char*>(header), sizeof header);
    out.write(reinterpret_cast<const char*>(modes.omega_rad_s.data()),
              static_cast<std::streamsize>(sizeof(double) * modes.omega_rad_s.size()));
    out.write(reinterpret_cast<const char*>(modes.shapes.data()),
              static_cast<std::streamsize>(sizeof(double) * modes.shapes.size()));
    if (!out) {
      spdlog::warn("mode cache: cannot write {}; continuing without it", partial);
      std::error_code ec;
      std::filesystem::remove(partial, ec);
      return;
    }
  }
  std::error_code ec;
  std::filesystem::rename(partial, path, ec);
  if (ec) spdlog::warn("mode cache: cannot rename {} to {}: {}", partial, path, ec.message());
}

}  // namespace

std::string DefaultModeCacheDir() {
  if (const char* dir = std::getenv("SONICBOOM_CACHE_DIR"); dir != nullptr && *dir != '\0') return dir;
  if (const char* home = std::getenv("HOME"); home != nullptr && *home != '\0') {
    return (std::filesystem::path(home) / ".cache" / "sonicboom" / "modes").string();
  }
  return "";
}

ShellModes CachedShellModes(const ShellModel& model, double max_frequency_hz, int64_t max_count,
                            bool with_shapes, const std::string& cache_dir, bool* hit) {
  if (hit != nullptr) *hit = false;
  if (cache_dir.empty()) return SolveShellModes(model, max_frequency_hz, max_count, with_shapes);
  const std::string key = fmt::format("{} | band={:.17g} count={} shapes={}", model.key(),
                                      max_frequency_hz, max_count, with_shapes);
  const std::string path =
      (std::filesystem::path(cache_dir) / fmt::format("modes-{:016x}.bin", Fnv1a(key))).string();
  ShellModes modes;
  if (ReadModes(path, key, &modes)) {
    if (hit != nullptr) *hit = true;
    return modes;
  }
  modes = SolveShellModes(model, max_frequency_hz, max_count, with_shapes);
  std::error_code ec;
  std::filesystem::create_directories(cache_dir, ec);
  if (ec) {
    spdlog::warn("mode cache: cannot create {}: {}; continuing without it", cache_dir, ec.message());
  } else {
    WriteModes(path, key, modes);
  }
  return modes;
}

}  // namespace sonicboom::acoustics
