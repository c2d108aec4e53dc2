#pragma once
/// The fidelity ladder's rows, shared by its measurement (fidelity.cc) and its written table
/// (fidelity_table.cc). Private to experiments.

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "internal/fidelity_metrics.h"
#include "sonicboom/experiments/config.h"

namespace sonicboom::experiments {

class LadderRung;  // what the ladder asks of a rung (fidelity.cc)

// an arrival this far off the yardstick's has caught another wave packet, us
inline constexpr double kHopUs = 50.0;
// the early wavefront aligned channel by channel: its span after the onset, and the largest
// shift searched, s
inline constexpr double kWavefrontAfterOnsetS = 0.002;
inline constexpr double kMaxWavefrontShiftS = 0.0003;
// what a localization dataset needs of a rung against the yardstick (issue 31's targets): the
// wavefront's inter-channel delays within this many us on average, and mode frequencies to
// 10 kHz within this many % at the median
inline constexpr double kLocalizationDelayUs = 20.0;
inline constexpr double kLocalizationFrequencyPct = 1.0;
inline constexpr double kLocalizationModeShare = 0.95;

// one row of the ladder: what it is, and how to build it
struct RungEntry {
  std::string name;
  std::string kind;  // "solid", "modal", "fd" or "closed-form"
  std::string grid;  // its discretization, as the table prints it
  std::function<std::unique_ptr<LadderRung>()> build;
};

struct RungResult {
  double ms_per_strike{0}, rel_error{0}, arrival_us{0}, delay_us{0}, delay_max_us{0};
  // over every channel (pair) of every strike: medians, and the channels whose arrival is more
  // than kHopUs off (the threshold caught another wave packet)
  double arrival_median_us{0}, delay_median_us{0};
  int64_t hops{0}, channels{0};
  // the same from aligned early wavefronts: per channel |shift|, per pair |difference|
  double shift_us{0}, shift_median_us{0};
  double aligned_delay_us{0}, aligned_delay_median_us{0}, aligned_delay_max_us{0};
  double band_error_db{0}, modes{0}, dofs{0}, oversampling{0};
  FrequencyError frequency;
  FrequencyError grid_frequency;  // the grid's as solved (what an FD rung on it integrates)
  bool frequency_of_grid{false};  // an FD rung: its grid's modal frequencies
};

// What the table's opening paragraphs state of the run.
struct TableFacts {
  bool quick{false};
  double sample_rate_hz{0.0};
  int64_t strikes{0};
  double window_s{0.0};           // compared signal after the onset
  double frequency_max_hz{0.0};   // modes compared below this
  double yardstick_band_hz{0.0};  // the comparison's low-pass
  std::string solves_md;          // the yardstick's and the grids' solves, as markdown
};
/// docs/fidelity.md up to the table's header row: how it was made, the yardstick, the columns.
std::string TableHead(const TableFacts& facts);

/// The table's rows, appended to `md` and `rows_json` (the first rung is the yardstick).
void LadderRows(const std::vector<RungEntry>& rungs, const std::vector<RungResult>& results,
                std::string* md, nlohmann::json* rows_json);

/// Which rung for which job, from the measured rows: the cheapest that meets each job's need.
std::string Recommendations(const std::vector<RungEntry>& rungs,
                            const std::vector<RungResult>& results);

/// The FD rung's damping against the loss law (shell.damping = law): the Rayleigh curve meets the
/// law at shell.loss_low_hz and loss_high_hz and departs from it elsewhere. Appends the section
/// to `md`; returns its rows (empty for Rayleigh damping).
nlohmann::json DampingSection(const SonicBoomConfig& config, std::string* md);

}  // namespace sonicboom::experiments
