// `export`: any dataset in the published trial layout (docs/captures.md).
#include <CLI/CLI.hpp>

#include <cmath>
#include <filesystem>
#include <memory>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "internal/report.h"
#include "internal/subcommands.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/experiments/commands.h"
#include "sonicboom/hardware/import.h"

namespace sonicboom::experiments {

namespace fs = std::filesystem;
using nlohmann::json;

CommandResult RunExport(const GlobalOptions& g, const std::string& in, const std::string& out,
                        hardware::AngleConvention angle) {
  if (!fs::exists(in)) throw IoError(fmt::format("{}: no such dataset (--in)", in));
  RefuseWritingOverInputs(g, {out}, {{in, "--in"}});
  const int64_t n = hardware::ExportTrials(in, out, angle);
  const json j = {{"out", out}, {"trials", n}};
  return {j.dump(), fmt::format("wrote {} trials of {} to {}\n", n, in, out)};
}

void RegisterExport(CLI::App& app, GlobalOptions& g, Runner* run) {
  struct Options {
    hardware::Layout layout = hardware::Layout::kTrial;
    std::string in, out;
    hardware::AngleConvention angle_convention = hardware::AngleConvention::kTube;
  };
  auto o = std::make_shared<Options>();
  auto* export_cmd = app.add_subcommand("export", "a dataset in the published trial layout");
  AddEnumOption(export_cmd, "--layout", &o->layout, "trial (the only layout written)");
  export_cmd->add_option("--in", o->in, "dataset (.h5)")->required();
  export_cmd->add_option("--out", o->out, "new directory")->required();
  AddEnumOption(export_cmd, "--angle-convention", &o->angle_convention, "tube | j7");
  export_cmd->callback([&g, run, o] {
    *run = [&g, o] {
      if (o->layout != hardware::Layout::kTrial) {
        throw ConfigError("export --layout capture: only the trial layout is written");
      }
      return RunExport(g, o->in, o->out, o->angle_convention);
    };
  });
}

}  // namespace sonicboom::experiments
