// The whole production strike in the fidelity report: its time per strike, and what rendering
// only what a scene needs saves and costs: the span the features read (acoustics.render_span =
// features), and the mode band and grid of a scene that plays a fixed band.
#include <algorithm>
#include <chrono>
#include <vector>

#include <fmt/format.h>

#include "internal/fidelity_strikes.h"
#include "internal/statistics.h"
#include "sonicboom/acoustics/shell.h"
#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/acoustics/synth.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/sim/scene.h"

namespace sonicboom::experiments {

using nlohmann::json;

ContactEvent StrikeEvent(const TestStrike& s, double time_s) {
  ContactEvent c;
  c.time_s = time_s;
  c.z_m = s.z_m;
  c.theta_rad = s.theta_rad;
  c.normal_speed_m_s = s.speed_m_s;
  c.effective_mass_kg = s.mass_kg;
  c.striker_radius_m = 0.011;
  c.striker_youngs_modulus_pa = 1e9;
  c.striker_poisson_ratio = 0.35;
  return c;
}

namespace {

constexpr int64_t kReps = 40;  // renders timed per setting

// the 40 renders of `config`'s acoustics: their time, and the audio of the first `keep`
WholeStrikeTime TimeRenders(const WholeStrikeSetup& setup, const SonicBoomConfig& config,
                            int64_t keep, std::vector<Eigen::MatrixXf>* audio) {
  acoustics::AcousticModelConfig whole = AcousticModel(config);
  if (setup.quick) {
    whole.shell.grid_spacing_m = setup.arc_m;
    whole.shell.axial_spacing_m = setup.axial_m;
  }
  const acoustics::StrikeSynthesizer synth(whole);
  // each render timed alone; the medians, so that another process's burst moves nothing
  std::vector<double> total_ms, vibration_ms;
  for (int64_t i = 0; i < kReps; ++i) {
    ContactEvent ev = StrikeEvent(kStrikes[i % setup.strikes], config.audio.onset_time_s);
    sim::ObjectConfig rod;  // the default struck rod: its bending modes take part
    sim::DescribeStruckBeam(rod, rod.length_m - 0.05, &ev);
    const auto t0 = std::chrono::steady_clock::now();
    acoustics::RenderedStrike rs = synth.Render(ev, {}, 0.0, static_cast<uint64_t>(i));
    total_ms.push_back(
        1e3 * std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
    vibration_ms.push_back(1e3 * rs.vibration_s);
    if (audio != nullptr && i < keep) audio->push_back(std::move(rs.audio));
  }
  return {Median(total_ms), Median(vibration_ms)};
}

// largest |a - b| over the largest |a|, over every element of every record's array
double RelativeMaxDifference(const std::vector<std::vector<float>>& a,
                             const std::vector<std::vector<float>>& b) {
  double diff = 0.0, peak = 0.0;
  for (size_t r = 0; r < a.size(); ++r) {
    for (size_t k = 0; k < a[r].size(); ++k) {
      diff = std::max(diff, static_cast<double>(std::abs(a[r][k] - b[r][k])));
      peak = std::max(peak, static_cast<double>(std::abs(a[r][k])));
    }
  }
  return peak > 0.0 ? diff / peak : diff;
}

}  // namespace

WholeStrikeTime WholeStrikeMs(const WholeStrikeSetup& setup) {
  return TimeRenders(setup, *setup.config, 0, nullptr);
}

json RenderSpanSection(const WholeStrikeSetup& setup, std::string* md) {
  const SonicBoomConfig& config = *setup.config;
  // the feature sets: the configured one, and a 20 ms waveform window (configs/transfer.yaml)
  dsp::FeatureConfig wavefront = config.features;
  wavefront.window_s = 0.02;
  wavefront.audio_representation = dsp::AudioRepresentation::kWaveform;
  wavefront.gating = false;
  wavefront.gcc_max_lag = 96;
  wavefront.onset_frame_s = 0.0007;
  const std::pair<std::string, dsp::FeatureConfig> sets[] = {
      {fmt::format("configured ({:.3g} s window)", config.features.window_s), config.features},
      {"20 ms waveform window (configs/transfer.yaml)", wavefront}};
  *md += fmt::format(
      "\nWhat a scene needs (acoustics.render_span): the same {} renders over the whole {:.1f} s "
      "record (render_span: record, the default) and only as long after the contact as each "
      "feature set reads (render_span: features: half the window, an onset frame and 5 ms, then a "
      "{:.0f} ms fade; the sensor chain's noise runs on). Features: each set computed on both "
      "renders of the first {} strikes, largest difference over the largest value.\n\n"
      "| features | rendered after the contact (ms) | ms per strike (record / span; medians) | "
      "vibration model (ms, record / span; medians) | saved | mel or waveform difference | GCC-PHAT "
      "difference |\n|---|---|---|---|---|---|---|\n",
      kReps, config.audio.record_duration_s, 1e3 * acoustics::kSpanFadeS, setup.strikes);
  json rows = json::array();
  for (const auto& [name, features] : sets) {
    SonicBoomConfig record = config;
    record.features = features;
    record.acoustics.render_span = acoustics::RenderSpan::kRecord;
    SonicBoomConfig span = record;
    span.acoustics.render_span = acoustics::RenderSpan::kFeatures;
    std::vector<Eigen::MatrixXf> audio_record, audio_span;
    const WholeStrikeTime t_record = TimeRenders(setup, record, setup.strikes, &audio_record);
    const WholeStrikeTime t_span = TimeRenders(setup, span, setup.strikes, &audio_span);
    // the two configs differ in acoustics alone: one featurizer (gate clip, plans) serves both
    const RecordFeaturizer featurizer(record, config.audio.sample_rate_hz, config.mics.count());
    std::vector<std::vector<float>> mel_a, mel_b, gcc_a, gcc_b;
    for (size_t r = 0; r < audio_record.size(); ++r) {
      const learning::FeatureSet a = featurizer.Compute(audio_record[r], {});
      const learning::FeatureSet b = featurizer.Compute(audio_span[r], {});
      mel_a.push_back(a.mel);
      mel_b.push_back(b.mel);
      gcc_a.push_back(a.gcc);
      gcc_b.push_back(b.gcc);
    }
    const double after_ms = 1e3 * FeatureSpanAfterContact(features);
    const double mel_diff = RelativeMaxDifference(mel_a, mel_b);
    const double gcc_diff = RelativeMaxDifference(gcc_a, gcc_b);
    *md += fmt::format("| {} | {:.1f} | {:.2f} / {:.2f} | {:.2f} / {:.2f} | {:.0f} % | {:.2g} | "
                       "{:.2g} |\n",
                       name, after_ms, t_record.ms, t_span.ms, t_record.vibration_ms,
                       t_span.vibration_ms, 100.0 * (1.0 - t_span.ms / t_record.ms), mel_diff,
                       gcc_diff);
    rows.push_back({{"features", name},
                    {"window_s", features.window_s},
                    {"rendered_after_contact_ms", after_ms},
                    {"record_ms", t_record.ms},
                    {"span_ms", t_span.ms},
                    {"record_vibration_ms", t_record.vibration_ms},
                    {"span_vibration_ms", t_span.vibration_ms},
                    {"mel_relative_max_difference", mel_diff},
                    {"gcc_relative_max_difference", gcc_diff}});
  }
  return rows;
}

FixedBandScene SceneOfBand(const SonicBoomConfig& config, double band_hz) {
  SonicBoomConfig scene = config;
  scene.acoustics.max_frequency_hz = band_hz;
  scene.acoustics.mode_band_hz = 0.0;
  scene.shell.grid_spacing_m = scene.shell.axial_spacing_m = 0.0;
  ResolveDerivedGrid(&scene);
  const double solved_hz = acoustics::SolvedModeBandHz(
      scene.acoustics, scene.audio.sample_rate_hz, scene.randomize);
  return {std::move(scene), solved_hz};
}

json ModeBandSection(const WholeStrikeSetup& setup, std::string* md) {
  const SonicBoomConfig& config = *setup.config;
  // the configured scene, then each fixed band on its derived grid (the renderer's own settings)
  struct Scene {
    std::string name;
    SonicBoomConfig config;
  };
  std::vector<Scene> scenes{{"configured (band per strike)", config}};
  if (setup.quick) {
    scenes.front().config.shell.grid_spacing_m = setup.arc_m;
    scenes.front().config.shell.axial_spacing_m = setup.axial_m;
  }
  for (double band : kDerivedGridBandsHz) {
    scenes.push_back({fmt::format("fixed {:.0f} kHz, derived grid", band / 1000),
                      SceneOfBand(config, band).config});
  }
  *md += fmt::format(
      "\nWhat a scene needs (the mode band and the grid): a scene that plays a fixed band "
      "(acoustics.max_frequency_hz) solves its modes to 1.25 x that band (the thick-plate "
      "correction's headroom) instead of {:.0f} kHz, and shell.grid_spacing_m: 0 derives a "
      "square grid with {:.0f} points per flexural wavelength at that band (at most {:.0f} mm). "
      "Each scene's modes solved afresh (no cache) and timed; the whole strike as above (the "
      "median of 40 renders). The ladder's rows 'modal, N kHz, derived grid' give their errors "
      "against the reference.\n\n"
      "| scene | modes solved to (kHz) | grid | DOFs | modes | mode solve (s) | ms per strike "
      "(vibration model) |\n|---|---|---|---|---|---|---|\n",
      acoustics::SolvedModeBandHz(config.acoustics, config.audio.sample_rate_hz,
                                  config.randomize) /
          1000,
      acoustics::kGridPointsPerWavelength,
      1e3 * acoustics::kCoarsestDerivedSpacingM);
  json rows = json::array();
  for (const Scene& scene : scenes) {
    const acoustics::AcousticModelConfig a = AcousticModel(scene.config);
    const double solved_hz =
        acoustics::SolvedModeBandHz(a.synth, a.audio.sample_rate_hz, a.randomize);
    const acoustics::ShellModel shell(a.tube, a.material, a.shell);
    const auto t0 = std::chrono::steady_clock::now();
    const acoustics::ShellModes modes = acoustics::SolveShellModes(shell, solved_hz, 0);
    const double solve_s =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    WholeStrikeSetup one = setup;
    one.config = &scene.config;
    one.quick = false;  // the scene's own grid
    const WholeStrikeTime t = WholeStrikeMs(one);
    const std::string grid = fmt::format("{:.1f} x {:.1f} mm", 1e3 * a.shell.grid_spacing_m,
                                         1e3 * a.shell.AxialSpacing());
    *md += fmt::format("| {} | {:.2f} | {} | {} | {} | {:.1f} | {:.2f} ({:.2f}) |\n", scene.name,
                       solved_hz / 1000, grid, shell.dofs(), modes.omega_rad_s.size(), solve_s,
                       t.ms, t.vibration_ms);
    rows.push_back({{"scene", scene.name},
                    {"solved_band_hz", solved_hz},
                    {"arc_m", a.shell.grid_spacing_m},
                    {"axial_m", a.shell.AxialSpacing()},
                    {"dofs", shell.dofs()},
                    {"modes", modes.omega_rad_s.size()},
                    {"solve_s", solve_s},
                    {"strike_ms", t.ms},
                    {"strike_vibration_ms", t.vibration_ms}});
  }
  return rows;
}

}  // namespace sonicboom::experiments
