#pragma once
/// One function per CLI subcommand. Each returns its machine-readable result as a JSON string
/// and its human-readable report as text; the CLI prints one of the two on stdout.

#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "sonicboom/core/archive.h"
#include "sonicboom/core/tube.h"
#include "sonicboom/experiments/config.h"
#include "sonicboom/hardware/import.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::experiments {

class KnnFits;  // experiments/baselines.h

/// Options shared by every subcommand.
struct GlobalOptions {
  ConfigSources sources;
  int threads{0};  // 0 = all cores
  bool quiet{false};
  bool json{false};
};

/// What a command produced.
struct CommandResult {
  std::string json;  // one JSON object
  std::string text;  // human-readable report
};

CommandResult RunDemo(const GlobalOptions& g, const std::string& out_dir);
/// `generate`: shard_option is a shard number (of num_shards) or "auto" (ShardFromEnvironment);
/// "{shard}" in `out` becomes the shard number. An existing complete output of the same dataset
/// is skipped (a rerun of a finished shard); another existing output needs `force`.
CommandResult RunGenerate(const GlobalOptions& g, const std::string& out, int64_t count,
                          int64_t first_index, const std::string& shard_option, int64_t num_shards,
                          bool force);
/// `merge`: shards into one dataset, copied, or with virtual_audio an HDF5 virtual dataset over
/// the shards' audio. An existing output needs `force`.
CommandResult RunMerge(const GlobalOptions& g, const std::string& out,
                       const std::vector<std::string>& shards, bool virtual_audio, bool force);
CommandResult RunSynth(const GlobalOptions& g, const std::string& out_wav, int64_t index,
                       bool force);
CommandResult RunModes(const GlobalOptions& g, TubeEnds ends, bool ideal, int64_t count);
/// Options of `sonicboom fidelity`.
struct FidelityOptions {
  std::string out{"docs/fidelity.md"};  // markdown table; "" = print only
  int64_t strikes{4};                   // test strikes (1-6)
  double window_s{0.03};                // compared signal after the onset, s
  bool quick{false};                    // coarse grids and a coarse reference (a smoke run)
  // the yardstick: the reference solid's modes up to here, on elements of this size
  double reference_band_hz{15000.0};
  double reference_element_m{0.0135};
  // draws OUT's Pareto figure from OUT's JSON (/usr/bin/python3, matplotlib); "" = no figure
  std::string plot_script{"scripts/plot.py"};
  // "" = none; else every rung's compared signals, DIR/NN.npy (strikes x mics x samples, strain,
  // low-passed to the yardstick's band) with DIR/index.json naming each rung
  std::string signals_dir;
};
/// The fidelity ladder's speed-accuracy table (docs/fidelity.md): every rung of the shell
/// (modal, FD) and the reference solid at cheaper settings, timed and measured against the
/// reference solid (solid/) on the same contact forces. Writes OUT, OUT's .json and, with a plot
/// script, OUT's _pareto.png.
CommandResult RunFidelity(const GlobalOptions& g, const FidelityOptions& o);
/// The structure pool's Ritz path against full mode solves: the first `check` variants of the
/// configured pool are solved in full and compared in frequency, shape and signal; every
/// variant's projection is timed. Writes out_md when not empty.
CommandResult RunVariants(const GlobalOptions& g, int64_t check, const std::string& out_md);
/// Options of `sonicboom ablate`.
struct AblateOptions {
  std::string data;                              // training dataset (train/validation split)
  std::vector<std::string> tests;                // held-out datasets; the first is the table's
  std::string out;                               // one run directory per ablation + table.md
  std::string configs_dir{"configs/ablations"};  // one YAML layer per ablation
  std::vector<std::string> only;                 // names to run (empty = all)
  // finished runs trained on `data` (e.g. the scenario model): a variant whose resolved config
  // equals one's config.yaml copies that run instead of training the same network again
  std::vector<std::string> trained_runs;
};
/// Trains and evaluates every ablation of o.configs_dir (each layered after the --config files,
/// before the --set overrides); finished runs are reused, and a variant identical to one of
/// o.trained_runs is copied from it. Writes out/table.md, out/results.json.
CommandResult RunAblate(const GlobalOptions& g, const AblateOptions& o);
CommandResult RunFeatures(const GlobalOptions& g, const std::string& in, const std::string& out,
                          const std::string& proprio_csv, bool force);
/// A fine-tune's per-mic mel statistics: the pretrained run's, or refitted on the target data.
enum class NormPolicy { kKeep, kRefit };
inline constexpr EnumName<NormPolicy> kNormPolicyNames[] = {{NormPolicy::kKeep, "keep"},
                                                            {NormPolicy::kRefit, "refit"}};
inline std::span<const EnumName<NormPolicy>> EnumNames(NormPolicy) {
  return kNormPolicyNames;
}

/// How a fine-tune picks its recipe: the one given (--freeze, --lr), or auto: candidates
/// cross-validated on the data's strikes, the pretrained weights kept unless a tuned one is
/// better beyond the folds' spread (learning::CrossValidateFineTune).
enum class TuneMode { kFixed, kAuto };
inline constexpr EnumName<TuneMode> kTuneModeNames[] = {{TuneMode::kAuto, "auto"},
                                                        {TuneMode::kFixed, "fixed"}};
inline std::span<const EnumName<TuneMode>> EnumNames(TuneMode) { return kTuneModeNames; }

/// `train`: a fresh run, or a fine-tune of a pretrained run (--init-from).
struct TrainOptions {
  std::string data;  // dataset (.h5)
  std::string out;   // run directory
  bool resume{false};
  bool force{false};      // replace an existing run directory
  std::string init_from;  // pretrained run directory; empty: from scratch
  learning::FineTune::Freeze freeze{learning::FineTune::Freeze::kNone};
  NormPolicy norm{NormPolicy::kKeep};
  // self-training (with init_from): the fraction in (0, 1] of the data's strikes that the
  // pretrained run is surest of, labelled by its answers (the data's labels unread); 0: off
  double pseudo_labels{0.0};
  // with init_from; the CLI's default is auto unless a recipe, pseudo-labels or --resume is given
  TuneMode tune{TuneMode::kFixed};
};
CommandResult RunTrain(const GlobalOptions& g, const TrainOptions& o);
/// `eval`: metrics of a run on a dataset.
struct EvalOptions {
  std::string predictions_csv;  // also one row per strike (empty: none)
  bool force{false};            // replace an existing predictions file
  bool turn_average{false};     // learning::LocalizerOptions::turn_average
  bool mirror_average{false};   // learning::LocalizerOptions::mirror_average (turns too)
};
CommandResult RunEval(const GlobalOptions& g, const std::string& model_dir, const std::string& data,
                      const EvalOptions& options = {});
/// `calibrate`: refits the run's interval scales (learning::Recalibrate) on the labelled strikes
/// of `data` (pooled), with the run's features; the run keeps its weights.
CommandResult RunCalibrate(const GlobalOptions& g, const std::string& model_dir,
                           const std::vector<std::string>& data,
                           learning::IntervalFit fit = learning::IntervalFit::kLikelihood);
/// `adapt`: a new run at `out_dir`, the run's input and BatchNorm statistics re-estimated on
/// the strikes of `data` (learning::AdaptToUnlabelled; labels unread), its config.yaml beside.
CommandResult RunAdapt(const GlobalOptions& g, const std::string& model_dir,
                       const std::string& data, const std::string& out_dir,
                       const learning::AdaptOptions& options);
/// `localize --method arrival`: the training-free arrival locator on one WAV, configured by the
/// global config (tube, microphones, arrival settings); no model. The per-strike path (read,
/// picks, search) is timed over `repeat` runs, the set-up (the grid's paths) apart.
CommandResult RunLocalizeByArrival(const GlobalOptions& g, const std::string& wav, int64_t repeat);
CommandResult RunLocalize(const GlobalOptions& g, const std::string& model_dir,
                          const std::string& wav, const std::string& proprio_csv, int64_t repeat);
/// The baselines (docs/baselines.md): kNN on pooled log-mel, steered TDOA, the training-free
/// arrival locator, a constant.
enum class BaselineMethod { kKnn, kTdoa, kArrival, kConstant };
inline constexpr EnumName<BaselineMethod> kBaselineMethodNames[] = {
    {BaselineMethod::kKnn, "knn"},
    {BaselineMethod::kTdoa, "tdoa"},
    {BaselineMethod::kArrival, "arrival"},
    {BaselineMethod::kConstant, "constant"}};
inline std::span<const EnumName<BaselineMethod>> EnumNames(BaselineMethod) {
  return kBaselineMethodNames;
}

/// Options of `sonicboom map` (docs/mapping.md).
struct MapOptions {
  std::string model, data, out;
  std::string plot_script{"scripts/plot.py"};  // "" draws no figure
  bool force{false};
};
/// Localized taps placed in the base frame with the arm's logged pose and scored against the
/// true contact points (MED, RMS Chamfer both ways); writes out/map.json and out/map.png.
CommandResult RunMap(const GlobalOptions& g, const MapOptions& o);

/// Options of `sonicboom reproduce`.
struct ReproduceOptions {
  std::string size{"quick"};  // quick, paper or smoke
  std::string out;            // DIR: data/, model/, eval/, baselines/, ablations/, map/, report.md
  std::string configs_dir{"configs"};
  std::string plot_script{"scripts/plot.py"};
};
/// The paper's evaluation as DIR/report.md with figures and DIR/results.json; resumable stage by
/// stage (a stage reruns when what it was computed from changed).
CommandResult RunReproduce(const GlobalOptions& g, const ReproduceOptions& o);

/// Options of `sonicboom baseline` (docs/baselines.md).
struct BaselineOptions {
  BaselineMethod method{BaselineMethod::kKnn};
  std::string train;             // training dataset: knn and constant need it; tdoa
                                 // fits its speed scale on it when given
  std::string data;              // held-out dataset
  int64_t k{5};                  // knn: neighbours
  int64_t knn_gcc_lags{0};       // knn: GCC-PHAT lags each side in the vector (0: none)
  std::vector<double> bands_hz;  // tdoa: band edges (empty: the default octaves)
  bool non_dispersive{false};    // tdoa: one speed for every band
  bool no_fit{false};            // tdoa: keep the analytic speeds (scale 1)
  int64_t fit_strikes{300};      // tdoa: training strikes used by the speed fit
  // knn: fits kept across calls (reproduce's four scenarios share one); null: fit this call
  std::shared_ptr<KnnFits> knn_fits;
};
/// A baseline's metrics on `data`, with the keys of `eval --json` plus "method" and the
/// method's own fields. The config's base layer is the test dataset's own config.
CommandResult RunBaseline(const GlobalOptions& g, const BaselineOptions& options);
CommandResult RunFk(const GlobalOptions& g, const std::string& joints);
/// `rerender`: the strikes of `in` with audio from the reference solid (another theory).
struct RerenderOptions {
  std::string in, out;
  int64_t count = 0;  // 0 = every sample
  double max_frequency_hz = 15000.0;
  double element_m = 0.0135;
  bool force = false;
  bool ideal = false;  // a uniform tube: no seams, holes, bolts or mounts (a diagnostic)
};
CommandResult RunRerender(const GlobalOptions& g, const RerenderOptions& o);

/// `import`: recorded strikes (a published trial directory or our capture layout) into a
/// dataset; `export`: a dataset into the published trial layout (docs/captures.md).
struct ImportOptions {
  hardware::Layout layout{hardware::Layout::kTrial};
  std::string in;   // directory
  std::string out;  // dataset (.h5)
  hardware::AngleConvention angle_convention{hardware::AngleConvention::kTube};
  double min_duration_s{1.5};
  std::string object;                 // labels from geometry: mesh or point cloud (trial layout)
  double object_scale{1.0};           // object file units to metres (0.001: millimetres)
  double contact_tolerance_m{0.002};  // contact when the object comes this close
  bool skip_bad{false};
  bool invert_polarity{false};  // every channel negated (discs wired the other way)
  bool force{false};            // replace an existing output
};
CommandResult RunImport(const GlobalOptions& g, const ImportOptions& o);
/// `listen`: live localization. Strikes are cut from a device stream (or a WAV read as one) by
/// an energy-onset trigger, localized by a trained run, printed one JSON line each as they
/// happen (with the latency from the onset's arrival to the answer) and, with `save`, written
/// in the capture layout (docs/captures.md).
struct ListenOptions {
  std::string model;          // run directory
  std::string device;         // input device (part of its name); empty: the default input
  std::string wav;            // read this WAV as the stream instead of a device
  bool realtime{false};       // pace a WAV stream at its sample rate, as a device delivers it
  std::string save;           // session directory; empty: save nothing
  int64_t max_events{0};      // stop after this many strikes; 0: at the end of the stream
  double threshold_db{20.0};  // onset: frame energy this far above the noise floor
};
/// `geometry-check`: the first `count` strikes of the scene (mode strike or guided) exported as
/// files (the object as a PLY mesh, the arm's joint log as q_t.npy; under `scenes_dir`, kept,
/// or a temporary directory) and relabelled from them as `import --object` does, against the
/// simulator's labels: median, p95 and worst surface error, failures (docs/captures.md).
CommandResult RunGeometryCheck(const GlobalOptions& g, int64_t count, const std::string& out_md,
                               const std::string& scenes_dir);
CommandResult RunListen(const GlobalOptions& g, const ListenOptions& o);
CommandResult RunExport(const GlobalOptions& g, const std::string& in, const std::string& out,
                        hardware::AngleConvention angle_convention);
/// `inspect`: a summary of a file or run directory. With `png` (a dataset only) also a figure:
/// the (z, theta) coverage of its valid strikes and the six channels of the strike in row
/// `strike_row` with their spectrograms, drawn by `plot_script` (/usr/bin/python3, matplotlib)
/// from PNG.json, which is written beside it.
struct InspectOptions {
  std::string png;
  int64_t strike_row{0};
  std::string plot_script{"scripts/plot.py"};
  bool force{false};  // replace an existing figure and its data (PNG, PNG.json)
};
CommandResult RunInspect(const GlobalOptions& g, const std::string& path,
                         const InspectOptions& o = {});
/// `config`: the resolved config as YAML; with `markdown_sections` (comma-separated top-level
/// sections) a Markdown table of their keys and values instead.
CommandResult RunConfig(const GlobalOptions& g, const std::string& markdown_sections);

/// The demo's embedded config layer (small model, short training).
const std::string& DemoConfigYaml();

}  // namespace sonicboom::experiments
