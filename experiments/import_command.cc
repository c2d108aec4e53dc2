// `import`: recorded strikes (the published trial layout or our capture layout) into a dataset
// (docs/captures.md).
#include <CLI/CLI.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <memory>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "internal/report.h"
#include "internal/subcommands.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/experiments/commands.h"
#include "sonicboom/hardware/import.h"

namespace sonicboom::experiments {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// The rig as an import sees it, from the resolved config.
hardware::ImportSettings SettingsFor(const SonicBoomConfig& config, const ImportOptions& o,
                                     int threads) {
  hardware::ImportSettings s;
  s.layout = o.layout;
  s.angle = o.angle_convention;
  s.sample_rate_hz = config.audio.sample_rate_hz;
  s.channels = config.mics.count();
  s.record_frames = config.audio.num_samples();
  if (!(o.min_duration_s > 0.0) || !std::isfinite(o.min_duration_s)) {
    throw ConfigError(fmt::format("--min-duration-s {} must be positive", o.min_duration_s));
  }
  s.min_duration_s = o.min_duration_s;
  s.proprio_rows = config.strike.proprio_rows;
  s.outer_radius_m = config.tube.outer_radius_m;
  s.z_limit_m = 0.5 * config.tube.length_m;
  s.skip_bad = o.skip_bad;
  s.invert_polarity = o.invert_polarity;
  s.threads = threads;
  // the tube's orientation from the joint log where x_t.npy has none
  s.tube_pose_from_joints = PandaTubePose(config.tube.center_from_flange_m);
  // labels from geometry: the object prepared once for every trial
  if (!o.object.empty()) {
    if (s.layout != hardware::Layout::kTrial) {
      throw ConfigError("--object labels trials from their joint logs: it needs --layout trial");
    }
    hardware::ContactRule rule;
    rule.outer_radius_m = config.tube.outer_radius_m;
    rule.length_m = config.tube.length_m;
    rule.tolerance_m = o.contact_tolerance_m;
    s.labeler = std::make_shared<const hardware::ContactLabeler>(
        hardware::ReadObjectGeometry(o.object, o.object_scale), rule);
  }
  return s;
}

// Captures longer than the record are imported as their first record: said, with both lengths.
void WarnTrimmed(const std::vector<hardware::TrimmedCapture>& trimmed, double record_s) {
  if (trimmed.size() == 1) {
    spdlog::warn(
        "{}: {:.3f} s long, longer than the record (audio.record_duration_s = {:.3f} s): imported "
        "as its first {:.3f} s",
        trimmed[0].file, trimmed[0].captured_s, record_s, record_s);
  } else if (!trimmed.empty()) {
    const auto longest =
        std::max_element(trimmed.begin(), trimmed.end(),
                         [](const auto& a, const auto& b) { return a.captured_s < b.captured_s; });
    spdlog::warn(
        "{} captures are longer than the record (audio.record_duration_s = {:.3f} s) and were "
        "imported as their first {:.3f} s; the longest, {}, is {:.3f} s",
        trimmed.size(), record_s, record_s, longest->file, longest->captured_s);
  }
}

}  // namespace

CommandResult RunImport(const GlobalOptions& g, const ImportOptions& o) {
  const hardware::Layout layout = o.layout;
  if (!fs::is_directory(o.in)) throw IoError(fmt::format("{}: no such directory (--in)", o.in));
  const std::vector<ReadPath> reads = {{o.in, "--in"}, {o.object, "--object"}};
  CheckOutput(g, {o.out, "--out", o.force}, reads);
  // the capture's noise recording is kept beside the dataset
  RefuseWritingOverInputs(g, {o.out + ".noise.wav", "the noise recording beside --out"}, reads);

  // a capture directory's capture.yaml is the first layer over the defaults
  ConfigSources sources = g.sources;
  const fs::path rig = fs::path(o.in) / "capture.yaml";
  if (layout == hardware::Layout::kCapture) {
    if (!fs::exists(rig)) {
      throw IoError(
          fmt::format("{}: missing (a capture directory states its rig: sample rate, "
                      "mics, tube)",
                      rig.string()));
    }
    sources.files.insert(sources.files.begin(), rig.string());
    // the capture's own file names nothing outside it: a path it gives is refused here (the
    // import sets features.gating_noise_wav itself from the capture's noise.wav)
    ConfigSources rig_only;
    rig_only.files = {rig.string()};
    if (!ResolveConfig(rig_only).features.gating_noise_wav.empty()) {
      throw IoError(fmt::format(
          "{}: features.gating_noise_wav names a file; a capture's no-contact clip is its "
          "noise.wav, found by the import",
          rig.string()));
    }
  }
  SonicBoomConfig config = ResolveConfig(sources);
  if (layout == hardware::Layout::kCapture && fs::exists(fs::path(o.in) / "noise.wav")) {
    config.features.gating_noise_wav = fs::absolute(o.out + ".noise.wav").string();
  }
  const hardware::ImportSettings settings = SettingsFor(config, o, g.threads);

  DatasetInfo info;
  info.config_yaml = ConfigToYaml(config);
  const hardware::ImportReport report = hardware::ImportCaptures(o.in, o.out, settings, info);
  WriteTextAtomic(o.out + ".config.yaml", info.config_yaml);
  WarnTrimmed(report.trimmed, config.audio.record_duration_s);

  // the result, bad captures listed
  json bad = json::array();
  std::string text =
      fmt::format("imported {} captures from {} into {}", report.imported, o.in, o.out);
  text += report.bad.empty() ? "\n" : fmt::format(", {} bad ones skipped:\n", report.bad.size());
  for (const hardware::BadCapture& b : report.bad) {
    bad.push_back({{"file", b.file}, {"reason", b.reason}});
    text += "  " + b.reason + "\n";
  }
  if (!report.noise_wav.empty()) {
    text +=
        fmt::format("no-contact clip copied to {} (features.gating_noise_wav in {}.config.yaml)\n",
                    report.noise_wav, o.out);
  }
  json trimmed = json::array();
  for (const hardware::TrimmedCapture& t : report.trimmed) {
    trimmed.push_back({{"file", t.file}, {"captured_s", t.captured_s}});
  }
  const json j = {{"out", o.out},
                  {"imported", report.imported},
                  {"bad", bad},
                  {"trimmed", trimmed},
                  {"noise_wav", report.noise_wav}};
  return {j.dump(), text};
}

void RegisterImport(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto o = std::make_shared<ImportOptions>();
  auto* import_cmd = app.add_subcommand("import",
                                        "recorded strikes (published trial layout or our "
                                        "capture layout) into a dataset");
  AddEnumOption(import_cmd, "--layout", &o->layout, "trial | capture")->required();
  import_cmd->add_option("--in", o->in, "capture directory")->required();
  import_cmd->add_option("--out", o->out, "dataset file (.h5)")->required();
  AddEnumOption(import_cmd, "--angle-convention", &o->angle_convention,
                "tube (docs/conventions.md) | j7 (published joint-7 angle)");
  import_cmd->add_option("--min-duration-s", o->min_duration_s,
                         "shorter captures are bad (default 1.5)");
  import_cmd->add_option(
      "--object", o->object,
      "label trials from geometry: the object (ply, obj, stl, pts, xyz, robot base "
      "frame) met by the tube placed from each trial's q_t.npy");
  import_cmd->add_option("--object-scale", o->object_scale,
                         "object units to metres (0.001 for millimetres)");
  import_cmd->add_option("--contact-tolerance-m", o->contact_tolerance_m,
                         "contact when the object comes this close (default 0.002)");
  import_cmd->add_flag("--skip-bad", o->skip_bad,
                       "import the good captures when some are bad (they are listed)");
  import_cmd->add_flag("--invert-polarity", o->invert_polarity,
                       "negate every channel: discs wired the other way (docs/conventions.md)");
  import_cmd->add_flag("--force", o->force, "replace an existing output");
  import_cmd->callback([&g, run, o] { *run = [&g, o] { return RunImport(g, *o); }; });
}

}  // namespace sonicboom::experiments
