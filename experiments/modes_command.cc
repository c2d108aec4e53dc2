// `modes`: natural frequencies of the tube, closed form or numerical.
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <numbers>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/dsp/features.h"

#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

using nlohmann::json;

CommandResult RunModes(const GlobalOptions& g, TubeEnds ends, bool ideal, int64_t count) {
  SonicBoomConfig config = Resolve(g);
  if (count < 1 || count > 5000)
    throw ConfigError(fmt::format("--count must be in [1, 5000], got {}", count));
  const std::string boundary(NameOf(ends));
  config.shell.ends = ends;
  if (ideal) config.shell.ideal = true;
  const acoustics::ShellModel model(config.tube, config.material, config.shell);
  bool cached = false;
  const acoustics::ShellModes modes = acoustics::CachedShellModes(
      model, 0.0, count, false, config.acoustics.ModeCacheDir(), &cached);
  spdlog::info("modes {} the cache ({})", cached ? "read from" : "computed and stored in",
               config.acoustics.ModeCacheDir());
  std::vector<double> f(static_cast<size_t>(modes.omega_rad_s.size()));
  for (size_t k = 0; k < f.size(); ++k)
    f[k] = modes.omega_rad_s[static_cast<Eigen::Index>(k)] / (2.0 * std::numbers::pi);
  json j = {{"frequencies_hz", f},
            {"boundary", boundary},
            {"ideal", config.shell.ideal},
            {"model",
             "numerical shell: Sanders theory on a staggered (z, theta) grid (acoustics/shell.h)"},
            {"grid_points", {model.axial_points(), model.circumferential_points()}},
            {"dofs", model.dofs()},
            {"rigid_body_modes", modes.rigid_body_modes},
            {"from_cache", cached}};
  std::string text = fmt::format(
      "{} lowest elastic modes, {} ends, {} tube ({} x {} grid, {} DOFs; {} rigid-body modes not "
      "listed; pairs listed twice):\n",
      f.size(), boundary, config.shell.ideal ? "ideal" : "seamed", model.axial_points(),
      model.circumferential_points(), model.dofs(), modes.rigid_body_modes);
  for (size_t i = 0; i < f.size(); ++i) text += fmt::format("{:4d}  {:10.1f} Hz\n", i + 1, f[i]);
  return {j.dump(), text};
}

void RegisterModes(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    TubeEnds ends = TubeEnds::kSimplySupported;
    bool ideal = false;
    int64_t count = 20;
  };
  auto o = std::make_shared<Options>();
  auto* modes = app.add_subcommand("modes", "natural frequencies of the tube");
  AddEnumOption(modes, "--boundary", &o->ends, "simply-supported | free");
  modes->add_flag("--ideal", o->ideal, "ideal uniform tube (no seam, no holes)");
  modes->add_option("--count", o->count, "number of modes (pairs count twice)");
  modes->callback(
      [&g, run, o] { *run = [&g, o] { return RunModes(g, o->ends, o->ideal, o->count); }; });
}

}  // namespace sonicboom::experiments
