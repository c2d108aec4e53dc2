// The whole production strike in the fidelity report: its time per strike, and what rendering
// only the span the features read (acoustics.render_span = features) saves and costs.
#include <algorithm>
#include <chrono>
#include <vector>

#include <fmt/format.h>

#include "internal/fidelity_strikes.h"
#include "internal/statistics.h"
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

}  // namespace sonicboom::experiments
