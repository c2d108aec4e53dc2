// docs/fidelity.md's text around the measured ladder: its opening, rows, recommendations and
// damping section (internal/fidelity_ladder.h).
#include <numbers>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "internal/fidelity_ladder.h"
#include "sonicboom/acoustics/shell.h"

namespace sonicboom::experiments {

using nlohmann::json;

std::string TableHead(const TableFacts& f) {
  return fmt::format(
      "# Fidelity ladder: speed against accuracy\n\n"
      "Made by `sonicboom fidelity --out docs/fidelity.md{}` (experiments/fidelity.cc); do not "
      "edit by hand. One core, {} Hz. The figure (docs/fidelity_pareto.png) and the numbers "
      "(docs/fidelity.json) come with it.\n\n"
      "The yardstick is the reference solid (docs/reference_model.md): the tube as a 3-D elastic "
      "solid on spectral elements, another theory and discretization than the shell's, with the "
      "same seam, bolts, holes and mounts. Every rung renders the same {} strikes (wooden rod, "
      "0.05–1 m/s; contact forces solved once against the default rung's wall, so that rungs "
      "differ in the vibration model alone; the row 'FD, contact on its own wall' instead closes "
      "each impact against the FD grid in its run, an FD strike independent of the modal rung) "
      "and is damped by the same Rayleigh curve (the closed "
      "form, the ideal simply supported tube of acoustics.model = modal-closed-form, by its own "
      "constant loss factor, the curve's value at shell.loss_low_hz). The FD rungs run on the "
      "configured arc spacing with twice its axial spacing and coarser (an explicit step shrinks "
      "with the square of the spacing: on 2.5 x 2.5 mm one strike-second takes about 40 minutes "
      "of one core).\n\n"
      "Columns. Time: the vibration model for 1 s of 6 channels of one strike (FD: timed on the "
      "{:.0f} ms window and scaled; its cost per sample is constant; the solid: its modal sum "
      "after the solve below). Frequency: the modes below {:.0f} kHz matched by rank with the "
      "yardstick's, median / max |error| (%), with the count of modes each holds there (an FD "
      "rung's are its grid's modes). Signals: sensor strain over the first {:.0f} ms after the "
      "onset, both low-passed at {:.0f} kHz (the yardstick's band), averaged over the strikes: "
      "first-arrival error (20 % of each channel's peak; mean over channels and strikes / median, "
      "and how many channels are more than 50 µs off: there the threshold caught another wave "
      "packet, because the direct wave's share of the channel's peak differs between the "
      "models, and such a hop dominates a mean), inter-channel delay error (mean over the 15 "
      "pairs and the strikes / median / worst pair), the same from aligned wavefronts (each "
      "channel's first {:.0f} ms after the onset shifted against the yardstick's same channel to "
      "their best cross-correlation, within ±{:.1f} ms; a pair's error is the difference of its "
      "channels' shifts: mean / median / worst pair, and the median |shift|: a timing that reads "
      "the whole early waveform and so does not hop), relative L2 error, octave-band energy error "
      "(250 Hz–16 kHz, mean |dB|).\n\n{}\n"
      "| rung | discretization | DOFs | modes / oversampling | ms per strike | strikes/s | "
      "frequency error (%) | arrival error mean / median (µs) (channels > 50 µs off) | delay error "
      "mean / median / max (µs) | wavefront delay error mean / median / max (µs) (shift) | "
      "relative error | band-energy error (dB) |\n"
      "|---|---|---|---|---|---|---|---|---|---|---|---|\n",
      f.quick ? " --quick" : "", f.sample_rate_hz, f.strikes, f.window_s * 1e3,
      f.frequency_max_hz / 1e3, f.window_s * 1e3, f.yardstick_band_hz / 1e3,
      1e3 * kWavefrontAfterOnsetS, 1e3 * kMaxWavefrontShiftS, f.solves_md);
}

json DampingSection(const SonicBoomConfig& config, std::string* md) {
  json damping_json = json::array();
  if (config.shell.damping != acoustics::DampingModel::kLaw) return damping_json;
  const acoustics::ShellModel law(config.tube, config.material, config.shell);
  *md +=
      "\nDamping: the modal rung gives every mode the loss law's eta(f); the FD rung's Rayleigh "
      "curve (C = alpha M + beta K) meets it at shell.loss_low_hz and shell.loss_high_hz:\n\n"
      "| f (Hz) | law eta | FD (Rayleigh) eta | ratio |\n|---|---|---|---|\n";
  for (double f : {100.0, 220.0, 500.0, 1000.0, 2000.0, 5000.0, 10000.0, 20000.0}) {
    const double w = 2.0 * std::numbers::pi * f;
    const double eta_law = 2.0 * law.DampingRatio(w), eta_fd = 2.0 * law.RayleighDampingRatio(w);
    *md += fmt::format("| {:.0f} | {:.4f} | {:.4f} | {:.2f} |\n", f, eta_law, eta_fd,
                       eta_fd / eta_law);
    damping_json.push_back({{"frequency_hz", f}, {"law_eta", eta_law}, {"fd_eta", eta_fd}});
  }
  return damping_json;
}

void LadderRows(const std::vector<RungEntry>& rungs, const std::vector<RungResult>& results,
                std::string* md, json* rows_json) {
  for (size_t i = 0; i < rungs.size(); ++i) {
    const RungEntry& rung = rungs[i];
    const RungResult& r = results[i];
    const std::string size = r.oversampling > 0 ? fmt::format("{:.0f}x", r.oversampling)
                                                : fmt::format("{:.0f}", r.modes);
    const FrequencyError& f = r.frequency;
    const std::string freq =
        i == 0 ? "—"
               : fmt::format("{:.2f} / {:.2f} ({} / {}){}", f.median_pct, f.max_pct, f.modes,
                             f.reference_modes, r.frequency_of_grid ? " grid" : "");
    auto err = [&](double v, const char* spec) {
      return i == 0 ? std::string("—") : fmt::format(fmt::runtime(spec), v);
    };
    *md += fmt::format(
        "| {} | {} | {:.0f} | {} | {:.3g} | {:.3g} | {} | {} | {} | {} | {} | {} |\n", rung.name,
        rung.grid, r.dofs, size, r.ms_per_strike, 1e3 / r.ms_per_strike, freq,
        i == 0 ? "—"
               : fmt::format("{:.1f} / {:.1f} ({}/{})", r.arrival_us, r.arrival_median_us, r.hops,
                             r.channels),
        i == 0 ? "—"
               : fmt::format("{:.1f} / {:.1f} / {:.0f}", r.delay_us, r.delay_median_us,
                             r.delay_max_us),
        i == 0 ? "—"
               : fmt::format("{:.1f} / {:.1f} / {:.0f} ({:.1f})", r.aligned_delay_us,
                             r.aligned_delay_median_us, r.aligned_delay_max_us, r.shift_median_us),
        err(r.rel_error, "{:.3f}"), err(r.band_error_db, "{:.2f}"));
    rows_json->push_back({{"rung", rung.name},
                          {"kind", rung.kind},
                          {"grid", rung.grid},
                          {"dofs", r.dofs},
                          {"modes", r.modes},
                          {"oversampling", r.oversampling},
                          {"ms_per_strike", r.ms_per_strike},
                          {"frequency_median_pct", f.median_pct},
                          {"frequency_max_pct", f.max_pct},
                          {"frequency_modes", f.modes},
                          {"frequency_reference_modes", f.reference_modes},
                          {"frequency_of_grid", r.frequency_of_grid},
                          {"arrival_error_us", r.arrival_us},
                          {"delay_error_us", r.delay_us},
                          {"delay_error_max_us", r.delay_max_us},
                          {"arrival_error_median_us", r.arrival_median_us},
                          {"delay_error_median_us", r.delay_median_us},
                          {"wavefront_shift_us", r.shift_us},
                          {"wavefront_shift_median_us", r.shift_median_us},
                          {"wavefront_delay_error_us", r.aligned_delay_us},
                          {"wavefront_delay_error_median_us", r.aligned_delay_median_us},
                          {"wavefront_delay_error_max_us", r.aligned_delay_max_us},
                          {"arrival_hops", r.hops},
                          {"arrival_channels", r.channels},
                          {"relative_error", r.rel_error},
                          {"band_energy_error_db", r.band_error_db}});
  }
}

std::string Recommendations(const std::vector<RungEntry>& rungs,
                            const std::vector<RungResult>& results) {
  auto cheapest = [&](auto&& meets) -> int {
    int best = -1;
    for (size_t i = 1; i < rungs.size(); ++i) {
      if (!meets(rungs[i], results[i])) continue;
      if (best < 0 || results[i].ms_per_strike < results[best].ms_per_strike)
        best = static_cast<int>(i);
    }
    return best;
  };
  auto shell = [](const RungEntry& e) { return e.kind != "solid"; };
  auto describe = [&](int i) {
    return fmt::format(
        "{} on {} ({:.3g} ms per strike; frequency error {:.2f} % median; wavefront delay error "
        "{:.1f} µs mean, {:.1f} µs worst pair; threshold delay error {:.1f} µs mean, {:.1f} µs "
        "median; band energy {:.2f} dB)",
        rungs[i].name, rungs[i].grid, results[i].ms_per_strike, results[i].frequency.median_pct,
        results[i].aligned_delay_us, results[i].aligned_delay_max_us, results[i].delay_us,
        results[i].delay_median_us, results[i].band_error_db);
  };
  // ... and holds the band: about as many modes below 10 kHz as the yardstick
  auto localization = [](const RungResult& r) {
    return r.aligned_delay_us <= kLocalizationDelayUs &&
           r.frequency.median_pct <= kLocalizationFrequencyPct &&
           r.frequency.modes >= kLocalizationModeShare * r.frequency.reference_modes;
  };
  std::string md = "\nWhich rung for which job (the cheapest that meets the job's need):\n\n";
  const int timing = cheapest(
      [&](const RungEntry& e, const RungResult& r) { return shell(e) && localization(r); });
  const int closest = cheapest([&](const RungEntry& e, const RungResult& r) {
    if (!shell(e)) return false;
    for (size_t j = 1; j < rungs.size(); ++j)
      if (shell(rungs[j]) && results[j].aligned_delay_us < r.aligned_delay_us) return false;
    return true;
  });
  const std::string need = fmt::format(
      "wavefront inter-channel delay within {:.0f} µs and frequencies within {:.0f} % of the "
      "reference, with at least {:.0f} % of its modes below 10 kHz",
      kLocalizationDelayUs, kLocalizationFrequencyPct, 100 * kLocalizationModeShare);
  md += timing >= 0 ? fmt::format("- Localization datasets ({}): {}.\n", need, describe(timing))
                    : fmt::format(
                          "- Localization datasets: no shell rung has {}; the closest in delay is "
                          "{}. Strikes timed like the reference come from `sonicboom "
                          "rerender`.\n",
                          need, describe(closest));
  const int spectra = cheapest(
      [&](const RungEntry& e, const RungResult& r) { return shell(e) && r.band_error_db <= 1.0; });
  if (spectra >= 0)
    md += fmt::format("- Spectra and ringing (octave-band energy within 1 dB): {}.\n",
                      describe(spectra));
  const int smoke = cheapest([&](const RungEntry& e, const RungResult&) { return shell(e); });
  md += fmt::format("- Smoke tests and quick checks of the pipeline: {}.\n", describe(smoke));
  const int second =
      cheapest([&](const RungEntry& e, const RungResult&) { return e.kind == "solid"; });
  if (second >= 0)
    md += fmt::format("- A second theory (held-out test strikes, cross-checks): {}.\n",
                      describe(second));
  md +=
      "\nA rung's keys: its grid is shell.grid_spacing_m x shell.axial_spacing_m (arc x axial); "
      "'thick-plate' is shell.dispersion: thick-plate (docs/shell.md, \"Dispersion\"); 'all "
      "modes' is acoustics.max_frequency_hz: 20000 (the solved band), 'N kHz' acoustics."
      "max_frequency_hz: N000, 'derived band' 0 (from the contact); 'N modes' "
      "acoustics.mode_count; 'no residual' acoustics.residual: false; 'N kHz, derived grid' "
      "acoustics.max_frequency_hz: N000 with shell.grid_spacing_m: 0 and shell.axial_spacing_m: 0 "
      "(its modes solved to 1.25 x N kHz; the section 'the mode band and the grid' below); FD is "
      "acoustics.model: fd.\n";
  return md;
}

}  // namespace sonicboom::experiments
