#pragma once
/// Pieces of command set-up and output shared by several subcommands (report.cc).

#include <nlohmann/json.hpp>

#include <chrono>
#include <string>

#include "sonicboom/core/tube.h"
#include "sonicboom/experiments/commands.h"
#include "sonicboom/hardware/capture.h"
#include "sonicboom/hardware/import.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::experiments {

/// The config of this invocation: defaults, --config files, --set overrides.
SonicBoomConfig Resolve(const GlobalOptions& g);

/// The test dataset's own config as the base layer, then --config files and --set overrides.
SonicBoomConfig ResolveWithDataset(const GlobalOptions& g, const std::string& data);

/// Writes the resolved config beside an output file (OUTPUT.config.yaml).
void WriteConfigBeside(const std::string& output, const SonicBoomConfig& config);

/// IoError unless the parent directory of an output exists.
void RequireParentDir(const std::string& path);

/// A path a command reads (a file or a run or capture directory) and the option that named it.
struct ReadPath {
  std::string path;
  std::string option;  // e.g. "--data", for messages
};

/// A path a command is about to write (a file, or a directory it replaces).
struct Output {
  std::string path;
  std::string option{"--out"};
  bool force{false};  // an existing output is replaced once the new one is complete
};

/// IoError when OUT.config.yaml exists beside no OUT and `out` is not forced: a sidecar obeys
/// --force as its output does (CheckOutput covers it where OUT exists).
void CheckConfigSidecar(const Output& out);

/// The one rule for every command's outputs: the output (and its OUT.config.yaml sidecar) may not
/// be an input, an input's config sidecar, or lie inside an input directory, and may not hold an
/// input (a directory the command would replace), with or without --force; `reads` are the
/// command's inputs, the --config files of `g` added. Its parent directory must exist, and an
/// existing output is replaced only with force. IoError naming both paths otherwise.
void CheckOutput(const GlobalOptions& g, const Output& out, std::vector<ReadPath> reads);

/// The interpreter of the plotting script: Debian's, which sees python3-matplotlib.
inline constexpr const char* kPlotPython = "/usr/bin/python3";

/// Draws `png` from `data` (JSON) with `script` (scripts/plot.py) of `kind` under kPlotPython,
/// started from an argument vector (no shell); IoError naming both files and what failed (the
/// exit status or signal and the script's last stderr line, or a missing matplotlib) when it
/// fails (`advice`: what the caller's user can do about it).
void DrawFigure(const std::string& script, const std::string& kind, const std::string& data,
                const std::string& png, const std::string& advice);

/// CheckOutput's rule about inputs alone, for commands with their own rule for an existing
/// output (generate resumes its own .partial; import and export write new directories).
void RefuseWritingOverInputs(const GlobalOptions& g, const Output& out,
                             std::vector<ReadPath> reads);

/// What a recorded strike must be for this config (hardware::LoadCapture): one channel per mic,
/// the audio rate, and at least as long as the shorter of the record and the analysis window.
hardware::CaptureChecks CaptureChecksFor(const SonicBoomConfig& config);

/// The Panda's tube pose for joint angles, the tube centre `tube_center_from_flange_m` along the
/// flange axis: how `import` and `geometry-check` place the tube from a joint log.
hardware::TubePoseFromJoints PandaTubePose(double tube_center_from_flange_m);

/// A label as JSON; NaN (no labelled strike) prints as null.
nlohmann::json LabelJson(const ContactLabel& l);

/// Milliseconds since `start` on the steady clock.
double MillisecondsSince(std::chrono::steady_clock::time_point start);

/// Features -> train/val split -> training, writing into run_dir.
learning::Metrics TrainOnDataset(const SonicBoomConfig& config, const std::string& data,
                                 const std::string& run_dir, bool resume, int threads, bool quiet,
                                 const learning::FineTune& fine_tune = {});

/// A run directory's own config (RUN/config.yaml) as the base layer, then --config and --set:
/// what eval, localize, listen and a fine-tune resolve. IoError when the run is missing.
SonicBoomConfig ResolveWithRun(const GlobalOptions& g, const std::string& run_dir);

/// Metrics as the JSON object `sonicboom eval --json` prints.
nlohmann::json MetricsJson(const learning::Metrics& m);

/// `ablate`'s rows (its results.json "ablations") as a Markdown table: what each varies and its
/// errors on the first test set, then, with several test sets, the MED on each (a column named
/// by the file's stem, "test_" dropped), then each layer's description where `descriptions`.
/// A row whose training diverged ("diverged": its error; "test" null) reads "diverged†" in its
/// error cells, with the error as a footnote.
std::string AblationTableMarkdown(const nlohmann::json& rows, bool descriptions);

/// One localization as `localize` and `listen` print it: z, θ, the surface point in the tube
/// frame and, from a model with one, the predictive distribution (std, κ, 90 % intervals; null
/// otherwise). Appends the same in words to `text`.
nlohmann::json PredictionJson(const learning::Prediction& p, const TubeConfig& tube,
                              std::string* text);

}  // namespace sonicboom::experiments
