// Speed of the shell FD solver (ShellFd::Step) against the machine's measured limits, one core:
// a STREAM-style triad gives the memory bandwidth (in DRAM and at the FD operator's own working
// set), a register-resident multiply-add loop gives the peak flop rate, and the step rate is
// compared with min(bandwidth / bytes_per_step, peak_flops / flops_per_step).
//
//   ./build-fd/bin/fd_bench --benchmark_filter=FdStep --benchmark_repetitions=5
//
// Bytes are counted as the minimum one step must move: the CSR stiffness (8 B value + 4 B column
// index per nonzero, 4 B row pointer per row) and every per-DOF vector once (u, u-, force, the
// mass coefficient read; u+ written: 5 x 8 B per DOF). The triad counts 24 B per element (two
// reads, one write) like STREAM; with write-allocate the wire carries 32 B, the same convention
// as the FD's one written vector, so the two compare like for like. K is symmetric, so a solver
// may stream only its upper triangle (ShellFd does): the *_sym counters bound that format.
//
// Timing is CPU time of this thread (the machine is shared; Google Benchmark's rates are per CPU
// second too). The fractions compare the best of interleaved ~20 ms bursts of FD steps and of
// triad at the same working set (STREAM's best-of convention, applied to both alike), so load
// from other processes that comes and goes cancels instead of biasing one side.
#include <benchmark/benchmark.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <ctime>
#include <map>
#include <memory>
#include <vector>

#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_fd.h"
#include "sonicboom/core/tube.h"

namespace sonicboom {
namespace {

using acoustics::ShellConfig;
using acoustics::ShellFd;
using acoustics::ShellFdState;
using acoustics::ShellModel;

constexpr double kDramArrayBytes = 64.0 * 1024 * 1024;  // per triad array: 3 x 64 MB >> LLC
constexpr double kAudioRateHz = 44100.0;

// CPU seconds of this thread: the machine is shared, and Google Benchmark's rates are per CPU
// second too, so the limits and the step rate are timed alike
double ThreadSeconds() {
  timespec t{};
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return static_cast<double>(t.tv_sec) + 1e-9 * static_cast<double>(t.tv_nsec);
}

// ---- kernels -------------------------------------------------------------------------------

// a[i] = b[i] + s c[i] over n doubles (24 B and 2 flops per element)
__attribute__((noinline)) void Triad(double* __restrict a, const double* __restrict b,
                                     const double* __restrict c, double s, int64_t n) {
  for (int64_t i = 0; i < n; ++i) a[i] = b[i] + s * c[i];
}

// 24 independent multiply-add chains held in registers, `rounds` times (48 flops per round)
constexpr int kChains = 24;
__attribute__((noinline)) void MulAddChains(double* acc, double m, double c, int64_t rounds) {
  double x[kChains];
  for (int j = 0; j < kChains; ++j) x[j] = acc[j];
  for (int64_t r = 0; r < rounds; ++r) {
    for (int j = 0; j < kChains; ++j) x[j] = x[j] * m + c;
  }
  for (int j = 0; j < kChains; ++j) acc[j] = x[j];
}

// three triad arrays of n doubles each, touched once so their pages exist
struct TriadArrays {
  explicit TriadArrays(int64_t n) : a(n, 0.0), b(n, 1.0), c(n, 2.0) {}
  int64_t size() const { return static_cast<int64_t>(a.size()); }
  std::vector<double> a, b, c;
};

// ---- measured limits (cached: the FD benchmarks use them even when run alone) ---------------

// Triad bandwidth, B/s at 24 B per element, for three arrays totalling working_set_bytes: the
// best of 7 timed bursts of >= 50 ms each (the best excludes the other core's interference)
double TriadBandwidth(double working_set_bytes) {
  static std::map<int64_t, double> cache;
  const int64_t n = std::max<int64_t>(64, static_cast<int64_t>(working_set_bytes / 24.0));
  if (auto it = cache.find(n); it != cache.end()) return it->second;
  TriadArrays t(n);
  // passes per burst so that one burst moves >= 1.2 GB (>= 50 ms at 24 GB/s)
  const int64_t passes = std::max<int64_t>(1, static_cast<int64_t>(1.2e9 / (24.0 * n)));
  for (int64_t p = 0; p < std::min<int64_t>(passes, 4); ++p)
    Triad(t.a.data(), t.b.data(), t.c.data(), 0.5, n);
  double best = 0.0;
  for (int burst = 0; burst < 7; ++burst) {
    const double start = ThreadSeconds();
    for (int64_t p = 0; p < passes; ++p) {
      Triad(t.a.data(), t.b.data(), t.c.data(), 0.5, n);
      benchmark::ClobberMemory();
    }
    const double s = ThreadSeconds() - start;
    best = std::max(best, 24.0 * static_cast<double>(n * passes) / s);
  }
  cache[n] = best;
  return best;
}

// Peak double flop rate of this build's vector ISA (no -march flags: SSE2), flop/s, best of 7
double PeakFlops() {
  static const double peak = [] {
    double acc[kChains];
    for (int j = 0; j < kChains; ++j) acc[j] = 1.0 + 0.01 * j;
    const int64_t rounds = 5'000'000;
    double best = 0.0;
    for (int burst = 0; burst < 7; ++burst) {
      const double start = ThreadSeconds();
      MulAddChains(acc, 0.999999, 1e-6, rounds);
      benchmark::DoNotOptimize(acc);
      const double s = ThreadSeconds() - start;
      best = std::max(best, 2.0 * kChains * static_cast<double>(rounds) / s);
    }
    return best;
  }();
  return peak;
}

// ---- the FD grids ---------------------------------------------------------------------------

// One discretized tube with its solver and the minimum traffic and work of one step
struct FdGrid {
  std::unique_ptr<ShellModel> model;
  std::unique_ptr<ShellFd> fd;
  double dofs{0}, nnz{0}, nnz_upper{0}, nodes{0};
  double bytes_per_step{0}, bytes_per_step_sym{0}, flops_per_step{0};
};

// grid 0: the default seamed tube (ShellConfig{}); grid 1: a coarse 5 mm x 10 mm grid of it
const FdGrid& Grid(int which) {
  static std::map<int, std::unique_ptr<FdGrid>> grids;
  if (auto it = grids.find(which); it != grids.end()) return *it->second;
  auto g = std::make_unique<FdGrid>();
  ShellConfig shell;
  if (which == 1) {
    shell.grid_spacing_m = 0.005;
    shell.axial_spacing_m = 0.01;
  }
  g->model = std::make_unique<ShellModel>(TubeConfig{}, MaterialConfig{}, shell);
  g->fd = std::make_unique<ShellFd>(*g->model, kAudioRateHz, 0);
  const Eigen::SparseMatrix<double>& k = g->model->stiffness();
  g->dofs = static_cast<double>(k.rows());
  g->nnz = static_cast<double>(k.nonZeros());
  // upper triangle with the diagonal: (nnz + dofs) / 2 when every diagonal entry is stored
  for (Eigen::Index c = 0; c < k.outerSize(); ++c) {
    for (Eigen::SparseMatrix<double>::InnerIterator it(k, c); it; ++it)
      g->nnz_upper += it.row() <= it.col();
  }
  g->nodes = static_cast<double>(g->model->axial_points()) * g->model->circumferential_points();
  // CSR values + column indices + row pointers, then u, u-, force, mass coefficient, u+
  const double vectors = 4.0 * (g->dofs + 1) + 5.0 * 8.0 * g->dofs;
  g->bytes_per_step = 12.0 * g->nnz + vectors;
  g->bytes_per_step_sym = 12.0 * g->nnz_upper + vectors;
  // 2 per nonzero; per DOF 3 for v = u + b (u - u-) and 6 for the update with combined coefficients
  g->flops_per_step = 2.0 * g->nnz + 9.0 * g->dofs;
  return *grids.emplace(which, std::move(g)).first->second;
}

// ---- benchmarks -----------------------------------------------------------------------------

// Sustained DRAM bandwidth: triad over 3 x 64 MB
void BM_TriadDram(benchmark::State& state) {
  const int64_t n = static_cast<int64_t>(kDramArrayBytes / 8.0);
  TriadArrays t(n);
  for (auto _ : state) {
    Triad(t.a.data(), t.b.data(), t.c.data(), 0.5, n);
    benchmark::ClobberMemory();
  }
  using benchmark::Counter;
  state.counters["working_set_MB"] = 24.0 * n / 1e6;
  state.counters["GB_per_s_24B"] = Counter(24.0 * n * state.iterations() / 1e9, Counter::kIsRate);
  state.counters["GB_per_s_32B_wa"] =
      Counter(32.0 * n * state.iterations() / 1e9, Counter::kIsRate);
}
BENCHMARK(BM_TriadDram)->Unit(benchmark::kMillisecond)->MinTime(1.0);

// In-cache triad; arg = working set in KiB (24 KiB: L1, 768 KiB: L2)
void BM_TriadInCache(benchmark::State& state) {
  const int64_t n = state.range(0) * 1024 / 24;
  TriadArrays t(n);
  for (auto _ : state) {
    Triad(t.a.data(), t.b.data(), t.c.data(), 0.5, n);
    benchmark::ClobberMemory();
  }
  using benchmark::Counter;
  state.counters["working_set_MB"] = 24.0 * n / 1e6;
  state.counters["GB_per_s_24B"] = Counter(24.0 * n * state.iterations() / 1e9, Counter::kIsRate);
  state.counters["GFlop_per_s"] = Counter(2.0 * n * state.iterations() / 1e9, Counter::kIsRate);
}
BENCHMARK(BM_TriadInCache)->Arg(24)->Arg(768)->Unit(benchmark::kMicrosecond);

// Triad at an FD working set; args = grid, format (0: full CSR bytes_per_step, 1: upper triangle)
void BM_TriadAtFdWorkingSet(benchmark::State& state) {
  const FdGrid& g = Grid(static_cast<int>(state.range(0)));
  const double bytes = state.range(1) == 0 ? g.bytes_per_step : g.bytes_per_step_sym;
  const int64_t n = static_cast<int64_t>(bytes / 24.0);
  TriadArrays t(n);
  for (auto _ : state) {
    Triad(t.a.data(), t.b.data(), t.c.data(), 0.5, n);
    benchmark::ClobberMemory();
  }
  using benchmark::Counter;
  state.counters["working_set_MB"] = 24.0 * n / 1e6;
  state.counters["GB_per_s_24B"] = Counter(24.0 * n * state.iterations() / 1e9, Counter::kIsRate);
}
BENCHMARK(BM_TriadAtFdWorkingSet)
    ->Args({0, 0})
    ->Args({0, 1})
    ->Args({1, 0})
    ->Args({1, 1})
    ->Unit(benchmark::kMicrosecond);

// Peak flop rate of register-resident multiply-adds
void BM_PeakFlops(benchmark::State& state) {
  double acc[kChains];
  for (int j = 0; j < kChains; ++j) acc[j] = 1.0 + 0.01 * j;
  const int64_t rounds = 100'000;
  for (auto _ : state) {
    MulAddChains(acc, 0.999999, 1e-6, rounds);
    benchmark::DoNotOptimize(acc);
  }
  using benchmark::Counter;
  state.counters["GFlop_per_s"] =
      Counter(2.0 * kChains * rounds * state.iterations() / 1e9, Counter::kIsRate);
}
BENCHMARK(BM_PeakFlops)->Unit(benchmark::kMicrosecond);

// Best rates of interleaved bursts: FD steps/s and triad B/s at both working sets
struct PairedBest {
  double steps_per_s{0}, ws_bytes_per_s{0}, ws_sym_bytes_per_s{0};
};

// 15 rounds of (~20 ms of FD steps, ~20 ms of triad at bytes_per_step, the same at the upper
// triangle's bytes); steps_hint = a rough step rate to size the bursts
PairedBest InterleavedBursts(const FdGrid& g, ShellFdState* s, const Eigen::VectorXd& force,
                             double steps_hint) {
  constexpr double kBurstS = 0.02;
  const int64_t steps = std::max<int64_t>(5, static_cast<int64_t>(kBurstS * steps_hint));
  TriadArrays full(static_cast<int64_t>(g.bytes_per_step / 24.0));
  TriadArrays sym(static_cast<int64_t>(g.bytes_per_step_sym / 24.0));
  // triad passes per burst, sized from a 20 GB/s guess
  const auto passes = [&](const TriadArrays& t) {
    return std::max<int64_t>(1, static_cast<int64_t>(kBurstS * 20e9 / (24.0 * t.size())));
  };
  const auto triad_rate = [&](TriadArrays& t) {
    const int64_t p = passes(t);
    const double start = ThreadSeconds();
    for (int64_t k = 0; k < p; ++k) {
      Triad(t.a.data(), t.b.data(), t.c.data(), 0.5, t.size());
      benchmark::ClobberMemory();
    }
    return 24.0 * static_cast<double>(t.size() * p) / (ThreadSeconds() - start);
  };
  PairedBest best;
  for (int round = 0; round < 15; ++round) {
    const double start = ThreadSeconds();
    for (int64_t k = 0; k < steps; ++k) g.fd->Step(s, force);
    benchmark::DoNotOptimize(s->current.data());
    best.steps_per_s =
        std::max(best.steps_per_s, static_cast<double>(steps) / (ThreadSeconds() - start));
    best.ws_bytes_per_s = std::max(best.ws_bytes_per_s, triad_rate(full));
    best.ws_sym_bytes_per_s = std::max(best.ws_sym_bytes_per_s, triad_rate(sym));
  }
  return best;
}

// ShellFd::Step at the automatic timestep; arg = grid (0 default, 1 coarse). The applicable
// bound uses the triad at the operator's own working set (where the operator lives between
// steps: it fits in L3); the DRAM bound is given for reference
void BM_FdStep(benchmark::State& state) {
  const FdGrid& g = Grid(static_cast<int>(state.range(0)));
  // a struck, ringing state (the step cost does not depend on the values)
  ShellFdState s = g.fd->Rest();
  const Eigen::VectorXd push = g.model->RadialForceWeights(0.03, 0.4);
  for (int n = 0; n < 20; ++n) g.fd->Step(&s, 10.0 * push);
  const Eigen::VectorXd zero = Eigen::VectorXd::Zero(g.model->dofs());
  const double start = ThreadSeconds();
  for (auto _ : state) {
    g.fd->Step(&s, zero);
    benchmark::DoNotOptimize(s.current.data());
  }
  const double mean_rate = static_cast<double>(state.iterations()) / (ThreadSeconds() - start);
  // measured limits, after the timed loop so that they do not disturb it
  const PairedBest best = InterleavedBursts(g, &s, zero, mean_rate);
  const double bw_dram = TriadBandwidth(3.0 * kDramArrayBytes);
  const double peak = PeakFlops();
  const double compute = peak / g.flops_per_step;
  const double bound = std::min(best.ws_bytes_per_s / g.bytes_per_step, compute);
  const double bound_sym = std::min(best.ws_sym_bytes_per_s / g.bytes_per_step_sym, compute);
  const double bound_dram = std::min(bw_dram / g.bytes_per_step, compute);
  const double steps = static_cast<double>(state.iterations());
  using benchmark::Counter;
  state.counters["dofs"] = g.dofs;
  state.counters["nnz"] = g.nnz;
  state.counters["bytes_per_step"] = g.bytes_per_step;
  state.counters["bytes_per_step_sym"] = g.bytes_per_step_sym;
  state.counters["flops_per_step"] = g.flops_per_step;
  state.counters["oversampling"] = static_cast<double>(g.fd->oversampling());
  state.counters["steps_per_s"] = Counter(steps, Counter::kIsRate);
  state.counters["best_steps_per_s"] = best.steps_per_s;
  state.counters["dof_updates_per_s"] = Counter(steps * g.dofs, Counter::kIsRate);
  state.counters["node_updates_per_s"] = Counter(steps * g.nodes, Counter::kIsRate);
  state.counters["ws_GB_per_s"] = best.ws_bytes_per_s / 1e9;
  state.counters["ws_sym_GB_per_s"] = best.ws_sym_bytes_per_s / 1e9;
  state.counters["dram_GB_per_s"] = bw_dram / 1e9;
  state.counters["peak_GFlop_per_s"] = peak / 1e9;
  state.counters["bound_steps_per_s"] = bound;
  state.counters["fraction_of_bound"] = best.steps_per_s / bound;
  state.counters["bound_sym_steps_per_s"] = bound_sym;
  state.counters["fraction_of_sym_bound"] = best.steps_per_s / bound_sym;
  state.counters["bound_dram_steps_per_s"] = bound_dram;
  state.counters["fraction_of_dram_bound"] = best.steps_per_s / bound_dram;
  // simulated seconds per CPU second at 44.1 kHz x oversampling
  state.counters["x_real_time"] =
      Counter(steps / (kAudioRateHz * g.fd->oversampling()), Counter::kIsRate);
}
BENCHMARK(BM_FdStep)->Arg(0)->Arg(1)->Unit(benchmark::kMicrosecond)->MinTime(1.0);

}  // namespace
}  // namespace sonicboom
