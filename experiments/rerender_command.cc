// `rerender`: a dataset's strikes rendered again by the reference solid (solid/): same labels,
// proprioception and contacts, new audio from another theory with its own contact, damping and
// sensor chain drawn per strike from its own ranges (docs/reference_model.md). Its use: a held-out
// family that shares nothing of the shell model's physics.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <tbb/parallel_for.h>
#include <nlohmann/json.hpp>

#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/progress.h"
#include "sonicboom/core/rng.h"
#include "sonicboom/experiments/commands.h"
#include "sonicboom/solid/reference_chain.h"
#include "sonicboom/solid/reference_render.h"
#include "sonicboom/solid/reference_tube.h"

#include "internal/reference.h"
#include "internal/report.h"
#include "internal/subcommands.h"
#include "internal/unknown_fields.h"

namespace sonicboom::experiments {
using nlohmann::json;

namespace {

// Every valid strike of the first n has what the reference render takes from it (contact,
// time, approach speed, striker mass), checked before the tube is solved: an imported capture
// has none of the last three (NaN). SchemaError naming the file, the sample row and the column.
void CheckRenderable(const DatasetReader& reader, const std::string& file, int64_t n) {
  const bool imported = reader.info().source == "hardware";
  const std::string need =
      "rerender strikes the tube again where, when, how fast and with what mass the label says";
  for (int64_t r = 0; r < n; ++r) {
    const StrikeSample m = reader.ReadMeta(r);
    if (!m.valid) continue;
    KnownValue(m.label.z_m, file, r, m, "label/z_m", need);
    KnownValue(m.label.theta_rad, file, r, m, "label/theta_rad", need);
    KnownValue(m.label.time_s, file, r, m, "label/time_s", need, imported);
    KnownValue(m.label.normal_speed_m_s, file, r, m, "label/normal_speed_m_s", need, imported);
    if (!m.contacts.empty()) {
      KnownValue(m.contacts.front().effective_mass_kg, file, r, m, "contacts/effective_mass_kg",
                 need, imported);
    }
  }
}

}  // namespace

CommandResult RunRerender(const GlobalOptions& g, const RerenderOptions& o) {
  CheckOutput(g, {o.out, "--out", o.force}, {{o.in, "--in"}});
  CheckConfigSidecar({o.out, "--out", o.force});
  if (o.count < 0) throw ConfigError(fmt::format("--count must be >= 0, got {}", o.count));
  const SonicBoomConfig config = ResolveWithDataset(g, o.in);
  DatasetReader reader(o.in);
  DatasetInfo info = reader.info();
  CheckReferenceBand(o.max_frequency_hz, info.sample_rate_hz, "--max-frequency", o.in);
  const int64_t n = o.count > 0 ? std::min(o.count, reader.size()) : reader.size();
  CheckRenderable(reader, o.in, n);

  // the reference tube: solved once (or read from the mode cache)
  const auto t0 = std::chrono::steady_clock::now();
  const solid::SolidMeshConfig defaults;
  const solid::ReferenceTube tube(
      ReferenceTubeOf(config,
                      ReferenceMesh(o.element_m, defaults.degree_wall, defaults.degree_thickness,
                                    config.tube, "--element-m"),
                      o.max_frequency_hz, o.ideal, config.acoustics.ModeCacheDir()));
  const double solve_s = MillisecondsSince(t0) / 1e3;
  spdlog::info("reference tube: {} modes to {} Hz, {} ({:.1f} s)", tube.omega_rad_s().size(),
               o.max_frequency_hz, tube.from_cache() ? "from the cache" : "solved", solve_s);

  info.config_yaml += fmt::format(
      "\n# audio rendered again by the reference solid (sonicboom rerender --max-frequency {} "
      "--element-m {}{}) from {}\n",
      o.max_frequency_hz, o.element_m, o.ideal ? " --ideal" : "", o.in);
  info.variation_names = ReferenceVariationNames();
  info.num_samples = 0;
  DatasetWriter writer(o.out, info);
  const auto t1 = std::chrono::steady_clock::now();
  constexpr int64_t kBlock = 16;
  Progress progress("rerender", n);
  for (int64_t first = 0; first < n; first += kBlock) {
    const int64_t count = std::min(kBlock, n - first);
    std::vector<StrikeSample> block(count);
    for (int64_t i = 0; i < count; ++i) block[i] = reader.ReadMeta(first + i);
    std::vector<DatasetWriter::EncodedSample> encoded(count);
    tbb::parallel_for(int64_t{0}, count, [&](int64_t i) {
      StrikeSample& s = block[i];
      if (s.valid) {
        s.variation = RenderReferenceSample(tube, info.sample_rate_hz, info.audio_frames, &s);
      } else {
        s.audio = Eigen::MatrixXf::Zero(info.channels, info.audio_frames);
        s.variation.assign(ReferenceVariationNames().size(), 0.0);
      }
      encoded[i] = writer.Encode(s);
    });
    for (auto& e : encoded) writer.AppendEncoded(e);
    progress.Add(count);
  }
  progress.Finish();
  writer.Finish();
  WriteConfigBeside(o.out, config);
  const double render_s = MillisecondsSince(t1) / 1e3;
  json j = {{"out", o.out},
            {"samples", n},
            {"modes", tube.omega_rad_s().size()},
            {"max_frequency_hz", o.max_frequency_hz},
            {"modes_from_cache", tube.from_cache()},
            {"solve_s", solve_s},
            {"render_s", render_s},
            {"ms_per_strike", n > 0 ? 1e3 * render_s / n : 0.0}};
  const std::string text = fmt::format(
      "{}: {} strikes rendered by the reference solid ({} modes to {} Hz{}), {:.1f} ms per "
      "strike\n",
      o.out, n, tube.omega_rad_s().size(), o.max_frequency_hz,
      tube.from_cache() ? ", from the cache" : fmt::format(", solved in {:.0f} s", solve_s),
      n > 0 ? 1e3 * render_s / n : 0.0);
  return {j.dump(), text};
}

void RegisterRerender(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto o = std::make_shared<RerenderOptions>();
  auto* cmd = app.add_subcommand(
      "rerender", "a dataset's strikes with audio from the reference solid (another theory)");
  cmd->add_option("--in", o->in, "dataset whose strikes to render")->required();
  cmd->add_option("--out", o->out, "output dataset")->required();
  cmd->add_option("--count", o->count, "first N samples (0 = all)");
  cmd->add_option("--max-frequency", o->max_frequency_hz, "modes of the reference up to here (Hz)");
  cmd->add_option("--element-m", o->element_m, "element length of the reference mesh (m)");
  cmd->add_flag("--force", o->force, "replace an existing output");
  cmd->add_flag("--ideal", o->ideal,
                "render a uniform tube (no seams, holes, bolts or mounts): a diagnostic");
  cmd->callback([&g, run, o] { *run = [&g, o] { return RunRerender(g, *o); }; });
}

}  // namespace sonicboom::experiments
