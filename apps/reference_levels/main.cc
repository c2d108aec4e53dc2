// reference_levels: the meshes of `sonicboom reference` solved without the CLI (no libtorch,
// MuJoCo or Embree), for a machine that has many cores and none of those. It takes the default
// config's tube, material, discs and structure and writes each solved level into --cache-dir,
// where `sonicboom reference --cache-dir DIR` with the same options reads it back instead of
// solving (docs/reference_model.md).
#include <CLI/CLI.hpp>

#include <cmath>
#include <cstdio>
#include <string>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "internal/reference_levels.h"
#include "sonicboom/acoustics/shell.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/solid/convergence.h"

namespace {

struct Options : sonicboom::experiments::ReferenceLevelOptions {
  int64_t only_level = -1;  // >= 0: solve this level of the sequence alone
  std::string cache_dir;
};

int Run(const Options& o) {
  using namespace sonicboom;
  // the default config's tube, material, discs and structure, as `sonicboom reference` takes them
  const std::vector<solid::ConvergenceRequest> requests = experiments::ReferenceLevelRequests(
      o, TubeConfig{}, MaterialConfig{}, MicArrayConfig{}, acoustics::ShellConfig{}, o.cache_dir);
  if (o.only_level >= static_cast<int64_t>(requests.size()))
    throw ConfigError(
        fmt::format("--only-level {} names none of the {} levels", o.only_level, requests.size()));
  for (size_t l = 0; l < requests.size(); ++l) {
    if (o.only_level >= 0 && static_cast<int64_t>(l) != o.only_level) continue;
    const solid::ConvergenceLevel level = solid::SolveConvergenceLevel(requests[l]);
    // one line per level on stdout, as soon as it is kept
    std::printf(
        "level %zu: h = %.2f mm, %lld DOFs, %zu modes to %.0f Hz, built %.1f s, solved %.1f s%s\n",
        l, 1e3 * level.h_m, static_cast<long long>(level.dofs), level.f_hz.size(),
        o.max_frequency_hz, level.build_s, level.solve_s, level.from_cache ? " (cached)" : "");
    std::fflush(stdout);
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  Options o;
  CLI::App app{"the reference solid's convergence levels of `sonicboom reference`, default config"};
  sonicboom::experiments::AddReferenceLevelOptions(&app, &o);
  app.add_option("--only-level", o.only_level,
                 "solve this level (0 = coarsest) alone, e.g. one process per level")
      ->check(CLI::Range(0, 5));
  app.add_option("--cache-dir", o.cache_dir, "where each solved level is written")->required();
  CLI11_PARSE(app, argc, argv);
  try {
    return Run(o);
  } catch (const std::exception& e) {
    spdlog::error("{}", e.what());
    return 1;
  }
}
