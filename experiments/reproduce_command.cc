// `reproduce`: the paper's evaluation from one command, as DIR/report.md with its figures and
// DIR/results.json. The scenarios are generated (ts1 training strikes; held-out strikes of ts1
// to ts4), the scenario model trained and evaluated on each with the baselines, the modality
// and preprocessing ablations run, and the ts3 taps mapped (paper §V). Stages are resumable: a
// finished stage leaves a stamp holding the key of what it was computed from (the size, its
// resolved configs and the keys of the stages it reads); a stage whose key changed runs again,
// and with it every stage that reads it.
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <functional>
#include <iterator>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "sonicboom/core/cache_file.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/core/progress.h"
#include "sonicboom/experiments/baselines.h"
#include "sonicboom/experiments/config.h"

#include "internal/report.h"
#include "internal/reproduce.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

constexpr int64_t kShotsFirstIndex = 120000;  // labelled target strikes for a fine-tune
constexpr int64_t kFineTuneEpochs = 40;       // the few-shot fine-tune (docs/captures.md's recipe)
// the transfer study's randomized strikes: anywhere on the tube, not on the stationary grid
constexpr const char* kTransferGrid = "scene.stationary.z_grid_m=0";
// The lightweight model's epoch time as a fraction of configs/study.yaml's (ETA only; 3.6 against
// 7.8 s on 1600 ts1 strikes, 2 threads, docs/reproduce.md)
constexpr double kLightTrainFraction = 0.45;

// The ETA's cost model: seconds on this project's 2-core machine at 2 threads, from the stages of
// the paper-size run (docs/reproduce.md); elsewhere the pace of the stages run rescales them.
constexpr double kGenerateS = 0.024;         // one generated strike
constexpr double kFeaturesS = 0.015;         // one strike's features
constexpr double kScoreS = 0.035;            // one held-out strike scored (eval or a baseline)
constexpr double kStudyEpochS = 0.0041;      // one strike through an epoch of configs/study.yaml
constexpr double kTransferEpochS = 0.00054;  // one strike through an epoch of one transfer member
constexpr double kSolidRenderS = 0.13;       // one strike rendered by the reference solid

// A training's seconds: its strikes' features, then `epochs` epochs at `epoch_s` a strike
double TrainSeconds(int64_t strikes, int64_t epochs, double epoch_s) {
  return static_cast<double>(strikes) * (kFeaturesS + static_cast<double>(epochs) * epoch_s);
}

// What the transfer study (docs/transfer.md) runs at a size.
struct TransferSize {
  int64_t train{0};             // randomized ts4 training strikes
  int64_t epochs{0};            // 0: configs/transfer.yaml's
  int64_t members{0};           // ensemble members; 0: configs/transfer.yaml's
  double solid_band_hz{0.0};    // the reference solid's modes up to here
  double solid_element_m{0.0};  // its mesh's element length
  std::vector<int64_t> shots;   // labelled other-theory strikes for each few-shot point
};

// How much of everything a size runs.
struct ReproduceSize {
  std::string name;
  int64_t train{0};                    // ts1 training strikes
  int64_t test{0};                     // held-out strikes per scenario
  int64_t epochs{0};                   // every training's epochs; 0: the model config's
  std::string model_config;            // file in the configs directory
  std::vector<std::string> ablations;  // configs/ablations names over the scenario model
  // configs/ablations names trained over the lightweight model instead (the paper's
  // preprocessing ablation, §V-D: "a lightweight CNN ... to facilitate rapid experimentation");
  // empty: none
  std::vector<std::string> preprocessing;
  std::vector<BaselineMethod> baselines;
  TransferSize transfer;
};

ReproduceSize SizeNamed(const std::string& name) {
  using B = BaselineMethod;
  const std::vector<std::string> modality = {"all", "audio", "proprio", "audio_proprio",
                                             "audio_gcc"};
  // "all" first: the lightweight model's own reference row
  const std::vector<std::string> preprocessing = {
      "all",      "no_gating", "no_time_shift", "no_masking", "no_normalization",
      "gcc_crop", "gcc_short", "fast",          "fastest"};
  if (name == "quick") {
    return {name,
            1200,
            120,
            30,
            "study_fast.yaml",
            modality,
            {},
            {B::kKnn, B::kConstant},
            {1200, 100, 1, 6000.0, 0.018, {10, 25, 50}}};
  }
  if (name == "paper") {
    return {name,
            18000,
            500,
            0,
            "study.yaml",
            modality,
            preprocessing,
            {B::kKnn, B::kTdoa, B::kArrival, B::kConstant},
            {3000, 0, 0, 15000.0, 0.0135, {10, 25, 50}}};
  }
  if (name == "smoke") {
    return {name,
            48,
            12,
            1,
            "study_fast.yaml",
            {"all", "audio"},
            {"all", "gcc_short"},
            {B::kConstant},
            {48, 1, 1, 1500.0, 0.03, {12}}};
  }
  throw ConfigError(fmt::format("--size {}: choose quick, paper or smoke", name));
}

// A short, stable digest of a text (the caches' FNV-1a, 64 bit) as hex.
std::string Digest(const std::string& text) {
  return fmt::format("{:016x}", internal::Fnv1a(text.data(), text.size()));
}

// Stages run in order; each reruns when its key changed, and reports progress with an ETA from
// the weights of the stages left.
class StageRunner {
 public:
  StageRunner(std::string dir, double total_weight, bool progress)
      : dir_(std::move(dir)), total_(total_weight), progress_(progress),
        start_(std::chrono::steady_clock::now()) {
    MakeDirectories((fs::path(dir_) / "stamps").string());
  }
  // Runs `body` unless stage `name` finished with `key`; returns the key.
  std::string Run(const std::string& name, const std::string& key, double weight,
                  const std::function<void()>& body) {
    const auto stamp_file = [&](const char* suffix) {
      return fs::path(dir_) / "stamps" / (name + suffix);
    };
    const fs::path stamp = stamp_file(".key");
    const fs::path wall = stamp_file(".wall_s");
    // holds the key of a run of the stage that began and has not finished (a killed process's)
    const fs::path started = stamp_file(".started");
    // present when the stage finished in a process that resumed it: its wall time is that
    // process's share
    const fs::path resumed_mark = stamp_file(".resumed");
    const bool fresh = fs::exists(stamp) && fs::exists(wall) && ReadText(stamp.string()) == key;
    const bool resuming = !fresh && fs::exists(started) && ReadText(started.string()) == key;
    if (progress_) {
      spdlog::info("reproduce: stage {} ({}){}", ++stage_, name,
                   fresh ? ": reused" : (resuming ? ": resumed" : ""));
    }
    // the stage's wall time when it ran, kept beside its stamp
    double s = 0.0;
    if (!fresh) {
      fs::remove(stamp);
      fs::remove(resumed_mark);
      WriteTextAtomic(started.string(), key);
      const auto t0 = std::chrono::steady_clock::now();
      {
        // the body sees whether it resumes; cleared however the body ends
        struct ResumeFlag {
          bool& flag;
          ~ResumeFlag() { flag = false; }
        } guard{resuming_};
        resuming_ = resuming;
        body();
      }
      s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
      WriteTextAtomic(wall.string(), fmt::format("{}", s));
      if (resuming) WriteTextAtomic(resumed_mark.string(), key);
      WriteTextAtomic(stamp.string(), key);
      fs::remove(started);
    }
    wall_s_.push_back({{"stage", name},
                       {"s", std::stod(ReadText(wall.string()))},
                       {"reused", fresh},
                       {"resumed", fs::exists(resumed_mark)}});
    done_ += weight;
    // a resumed stage ran only its rest here: its weight and seconds would overstate the pace
    if (!fresh && !resuming) {
      ran_ += weight;
      ran_s_ += s;
    }
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
    // the ETA: the cost model's seconds left, rescaled by the pace of the stages this run
    // computed whole once they are long enough to tell (reused ones took no time)
    if (progress_ && done_ < total_) {
      const bool paced = ran_ >= kPacedAfterS;
      spdlog::info("reproduce: {:.0f} % of the work done, {:.0f} s elapsed, ETA {}{}",
                   100.0 * done_ / total_, elapsed,
                   FormatDuration((paced ? ran_s_ / ran_ : 1.0) * (total_ - done_)),
                   paced ? "" : " (this project's 2-core machine's pace)");
    }
    return key;
  }
  const json& wall_s() const { return wall_s_; }
  // inside a stage's body: whether a stopped process had begun this stage with the same key
  bool resuming() const { return resuming_; }

 private:
  std::string dir_;
  static constexpr double kPacedAfterS = 300.0;  // cost-model seconds run before the pace counts
  double total_, done_{0.0}, ran_{0.0};          // weights: all, done, run whole by this process
  double ran_s_{0.0};                            // wall seconds of the stages run whole here
  bool progress_;
  int stage_{0};
  bool resuming_{false};
  std::chrono::steady_clock::time_point start_;
  json wall_s_ = json::array();  // in the order run
};

// The user's options with `files` layered before their own config files and `sets` after
// their own overrides; results come back as JSON whatever --json says.
GlobalOptions Layered(const GlobalOptions& g, const std::vector<std::string>& files,
                      const std::vector<std::string>& sets = {}) {
  GlobalOptions out = g;
  out.sources.files = files;
  out.sources.files.insert(out.sources.files.end(), g.sources.files.begin(), g.sources.files.end());
  out.sources.overrides.insert(out.sources.overrides.end(), sets.begin(), sets.end());
  out.json = false;  // each stage's own progress shows unless --quiet
  return out;
}

// The resolved config of a stage as its key's text.
std::string ConfigKey(const GlobalOptions& g) { return ConfigToYaml(ResolveConfig(g.sources)); }

// What a generated dataset depends on: the resolved config but for what reads the data (the
// features, the model, its training, the locator) and the demo's sizes.
std::string DataKey(const GlobalOptions& g) {
  SonicBoomConfig c = ResolveConfig(g.sources);
  c.features = {};
  c.model = {};
  c.train = {};
  c.arrival = {};
  c.demo = {};
  return ConfigToYaml(c);
}

}  // namespace

std::string CheckoutCommit(const fs::path& root) {
  const fs::path git = root / ".git";
  try {
    std::string head = ReadText((git / "HEAD").string());
    while (!head.empty() && std::isspace(static_cast<unsigned char>(head.back()))) head.pop_back();
    if (head.rfind("ref: ", 0) != 0) return head;  // a detached HEAD holds the hash itself
    const std::string ref = head.substr(5);
    // a loose ref file, else its line in packed-refs ("<hash> <ref>"), as `git gc` leaves it
    if (fs::exists(git / ref)) {
      const std::string hash = ReadText((git / ref).string());
      return hash.substr(0, hash.find_first_of(" \n"));
    }
    if (fs::exists(git / "packed-refs")) {
      std::istringstream packed(ReadText((git / "packed-refs").string()));
      for (std::string line; std::getline(packed, line);) {
        const size_t space = line.find(' ');
        if (space != std::string::npos && line.substr(space + 1) == ref) {
          return line.substr(0, space);
        }
      }
    }
  } catch (const Error&) {
  }
  return "unknown";
}

namespace {

// One reproduction: its options, sizes, paths and stages; each method is one part of the report.
class Reproduction {
 public:
  Reproduction(const GlobalOptions& g, const ReproduceOptions& o)
      : g_(g), o_(o), size_(SizeNamed(o.size)), cfg_(o.configs_dir), out_(o.out) {
    for (const char* ts : kScenarios) {
      if (!fs::is_regular_file(cfg_ / (std::string(ts) + ".yaml"))) {
        throw IoError(fmt::format("--configs {}: no {}.yaml (run from the repository root or "
                                  "pass the configs directory)",
                                  o.configs_dir, ts));
      }
    }
    if (!fs::is_regular_file(o.plot_script)) {
      throw IoError(fmt::format("--plot {}: no such script", o.plot_script));
    }
    if (size_.epochs > 0) epochs_.push_back(fmt::format("train.epochs={}", size_.epochs));
    g_model_ = Layered(g, {Config("ts1.yaml"), Config(size_.model_config)}, epochs_);
    if (!size_.preprocessing.empty()) {
      MakeDirectories(out_.string());
      g_light_ = LightModel();
    }
    // the ETA's weights (the cost model's seconds): every stage's, summed
    const double model_epoch_s =
        kStudyEpochS * (size_.model_config == kLightModelConfig ? kLightTrainFraction : 1.0);
    train_weight_ = TrainSeconds(size_.train, EpochsOf(g_model_), model_epoch_s);
    light_weight_ = size_.preprocessing.empty() ? 0.0
                                                : TrainSeconds(size_.train, EpochsOf(g_light_),
                                                               kStudyEpochS * kLightTrainFraction);
    const TransferSize& t = size_.transfer;
    const SonicBoomConfig transfer = ResolveConfig(TransferModel().sources);
    transfer_epochs_ = transfer.train.epochs;
    transfer_epoch_s_ = kTransferEpochS * transfer.train.ensemble_members;
    // the stages in the order they run, each weighed as its call below weighs it
    const double n_scenarios = std::size(kScenarios);
    const bool knn =
        std::count(size_.baselines.begin(), size_.baselines.end(), BaselineMethod::kKnn) > 0;
    double total = size_.train * kGenerateS + n_scenarios * TestGenerateWeight() + train_weight_ +
                   n_scenarios * (1.0 + size_.baselines.size()) * ScoreWeight() +
                   (knn ? KnnFitWeight() : 0.0);
    if (fs::is_regular_file(cfg_ / "materials.yaml")) total += TestGenerateWeight() + ScoreWeight();
    total += AblationWeight() + n_scenarios * ScoreWeight();
    if (!size_.preprocessing.empty()) {
      total += size_.preprocessing.size() * light_weight_ + ScoreWeight();
    }
    total += ScoreWeight();  // the map
    total += t.train * kGenerateS + TrainSeconds(t.train, transfer_epochs_, transfer_epoch_s_) +
             RerenderWeight(size_.test) + 4.0 * ScoreWeight();
    for (const int64_t n : t.shots) {
      total += n * kGenerateS + RerenderWeight(n) + FewShotWeight(n, /*fine_tune=*/true) +
               FewShotWeight(n, /*fine_tune=*/false) + 2.0 * ScoreWeight();
    }
    total += 1.0;  // the figures
    MakeDirectories(Path("data"));
    MakeDirectories(Path("transfer"));
    stages_ = std::make_unique<StageRunner>(o.out, total, !g.quiet);
  }

  // ts1 training strikes and held-out strikes of every scenario: their keys by name
  void GenerateData() {
    const GlobalOptions gt = Layered(g_, {Config("ts1.yaml")});
    data_key_["train"] = stages_->Run(
        "generate_train", Digest(size_.name + DataKey(gt) + std::to_string(size_.train)),
        size_.train * kGenerateS,
        [&] { RunGenerate(gt, Path("data/train.h5"), size_.train, 0, "0", 1, true); });
    for (const char* ts : kScenarios) data_key_[ts] = GenerateTest(ts, std::string(ts) + ".yaml");
  }

  // the scenario model on ts1
  void TrainModel() {
    model_key_ =
        stages_->Run("train", Digest(ConfigKey(g_model_) + data_key_["train"]), train_weight_,
                     [&] { RunTrain(g_model_, StageTrain("data/train.h5", "model")); });
  }

  // the model and the baselines on every scenario: (scenarios, baselines)
  std::pair<json, json> ScoreScenarios() {
    json scenarios = json::object(), baselines = json::object();
    knn_fits_ = std::make_shared<KnnFits>();
    for (int k = 0; k < 4; ++k) {
      const std::string ts = kScenarios[k];
      json s = Evaluate(ts, /*with_predictions=*/true);
      s["paper_med_cm"] = kPaperMedCm[k];
      s["predictions_csv"] = fmt::format("eval/{}.csv", ts);
      scenarios[ts] = s;
      for (BaselineMethod m : size_.baselines) {
        baselines[std::string(NameOf(m))][ts] = Baseline(m, ts);
      }
    }
    knn_fits_.reset();
    return {scenarios, baselines};
  }

  // the novel striker materials (paper §V-C2): wood, aluminium and PVC strikers by hand, as ts4
  json Materials() {
    if (!fs::is_regular_file(cfg_ / "materials.yaml")) return json();
    data_key_["materials"] = GenerateTest("materials", "materials.yaml");
    return Evaluate("materials", /*with_predictions=*/false);
  }

  // the modality ablations over the scenario model, trained on ts1 and tested on every scenario
  // (paper Fig. 6): their rows
  json Ablations() {
    // the row of every modality is the scenario model itself: copied, not trained again
    return Ablate("ablations", g_model_, size_.ablations, AblationWeight(),
                  {std::begin(kScenarios), std::end(kScenarios)}, {Path("model")});
  }

  // the preprocessing ablations on ts1 over the lightweight model (none: null)
  json Preprocessing() {
    if (size_.preprocessing.empty()) return json();
    return Ablate("preprocessing", g_light_, size_.preprocessing,
                  size_.preprocessing.size() * light_weight_, {"ts1"}, {});
  }

  // `ablate` of the configs/ablations layers `names` over `g`'s model into DIR/<stage>, tested on
  // the held-out sets of `scenarios` (a variant identical to one of `trained_runs` copied from
  // it): their rows
  json Ablate(const std::string& stage, const GlobalOptions& g,
              const std::vector<std::string>& names, double weight,
              const std::vector<std::string>& scenarios,
              const std::vector<std::string>& trained_runs) {
    const std::string dir = Path(stage);
    std::string tests_key;
    for (const std::string& ts : scenarios) tests_key += data_key_[ts];
    stages_->Run(stage,
                 Digest(ConfigKey(g) + data_key_["train"] + tests_key +
                        fmt::format("{}", fmt::join(names, ","))),
                 weight + scenarios.size() * ScoreWeight(), [&] {
                   // kept: ablate reuses a variant trained with the same config and resumes a
                   // killed one (a paper-size run spans several sittings)
                   AblateOptions a;
                   a.data = Path("data/train.h5");
                   for (const std::string& ts : scenarios) {
                     a.tests.push_back(Path(fmt::format("data/test_{}.h5", ts)));
                   }
                   a.out = dir;
                   a.configs_dir = (cfg_ / "ablations").string();
                   a.only = names;
                   a.trained_runs = trained_runs;
                   RunAblate(g, a);
                 });
    return json::parse(ReadText(dir + "/results.json"))["ablations"];
  }

  // the haptic map of the ts3 taps: its scores
  json Map() {
    stages_->Run("map", Digest(model_key_ + data_key_["ts3"]), ScoreWeight(), [&] {
      MapOptions m;
      m.model = Path("model");
      m.data = Path("data/test_ts3.h5");
      m.out = Path("map");
      m.plot_script = o_.plot_script;
      m.force = true;
      RunMap(Layered(g_, {}), m);
    });
    json map = json::parse(ReadText(Path("map/map.json")));
    map.erase("points");
    map.erase("skeleton");
    return map;
  }

  // The transfer study (docs/transfer.md) at this size: configs/transfer.yaml trained on
  // randomized ts4 strikes, scored zero-shot on ts4's held-out strikes (our shell) and on the
  // same strikes rendered by the reference solid (another theory, docs/reference_model.md)
  // beside the training-free arrival locator; then fine-tuned on `shots` other strikes of the
  // solid, against the same network trained from scratch on them. Its rows by name.
  json Transfer() {
    const TransferSize& t = size_.transfer;
    const GlobalOptions g_rand =
        Layered(g_, {Config("ts4.yaml"), Config("randomized.yaml")}, {kTransferGrid});
    data_key_["transfer_train"] = stages_->Run(
        "generate_transfer_train", Digest(size_.name + DataKey(g_rand) + std::to_string(t.train)),
        t.train * kGenerateS,
        [&] { RunGenerate(g_rand, Path("data/transfer_train.h5"), t.train, 0, "0", 1, true); });
    const GlobalOptions g_transfer = TransferModel();
    const std::string transfer_key = stages_->Run(
        "train_transfer", Digest(ConfigKey(g_transfer) + data_key_["transfer_train"]),
        TrainSeconds(t.train, transfer_epochs_, transfer_epoch_s_),
        [&] { RunTrain(g_transfer, StageTrain("data/transfer_train.h5", "transfer/model")); });
    // the held-out ts4 strikes, rendered by the solid: zero-shot, beside the arrival locator
    data_key_["ts4_solid"] = Rerender("ts4", data_key_["ts4"], size_.test);
    json rows = json::object();
    rows["zero_shot_shell"] = EvaluateRun("transfer_ts4", "transfer/model", transfer_key, "ts4");
    rows["zero_shot_solid"] =
        EvaluateRun("transfer_ts4_solid", "transfer/model", transfer_key, "ts4_solid");
    rows["arrival_shell"] = Baseline(BaselineMethod::kArrival, "ts4");
    rows["arrival_solid"] = Baseline(BaselineMethod::kArrival, "ts4_solid");
    // n labelled strikes of the solid beyond the held-out ones: fine-tuned, and from scratch
    rows["fewshot"] = json::array();
    for (const int64_t n : t.shots) {
      const std::string shots = fmt::format("shots{}", n);
      const GlobalOptions g_ts4 = Layered(g_, {Config("ts4.yaml")});
      data_key_[shots] =
          stages_->Run("generate_" + shots, Digest(size_.name + DataKey(g_ts4) + std::to_string(n)),
                       n * kGenerateS, [&] {
                         RunGenerate(g_ts4, Path(fmt::format("data/test_{}.h5", shots)), n,
                                     kShotsFirstIndex, "0", 1, true);
                       });
      data_key_[shots + "_solid"] = Rerender(shots, data_key_[shots], n);
      json point = {{"n", n}};
      point["tuned"] = FewShot(shots, n, transfer_key, g_transfer, /*fine_tune=*/true);
      point["scratch"] = FewShot(shots, n, transfer_key, g_transfer, /*fine_tune=*/false);
      rows["fewshot"].push_back(point);
    }
    return {{"train_strikes", t.train},
            {"epochs", t.epochs},
            {"members", t.members},
            {"solid_band_hz", t.solid_band_hz},
            {"solid_element_m", t.solid_element_m},
            {"rows", rows}};
  }

  // results.json and every figure drawn from it
  void Figures(const json& results) {
    stages_->Run("figures", Digest(results.dump()), 1.0, [&] {
      WriteTextAtomic(Path("results.json"), results.dump(1) + "\n");
      const std::string advice = "results.json is written";
      DrawFigure(o_.plot_script, "errors", Path("results.json"), Path("errors.png"), advice);
      DrawFigure(o_.plot_script, "ablation", Path("results.json"), Path("ablation.png"), advice);
      DrawFigure(o_.plot_script, "transfer", Path("results.json"), Path("transfer.png"), advice);
      InspectOptions inspect;
      inspect.png = Path("coverage_ts3.png");
      inspect.plot_script = o_.plot_script;
      inspect.force = true;  // the stage owns its run directory's figures
      RunInspect(Layered(g_, {}), Path("data/test_ts3.h5"), inspect);
      // the figure of a study this command does not run, as docs/ holds it
      const fs::path pareto = cfg_.parent_path() / "docs" / "fidelity_pareto.png";
      if (fs::is_regular_file(pareto)) {
        fs::copy_file(pareto, Path("fidelity_pareto.png"), fs::copy_options::overwrite_existing);
      }
    });
  }

  std::string Path(const std::string& rel) const { return (out_ / rel).string(); }

  // A training stage's options: a run begun by a stopped process (the stage's key, which holds
  // the config and data, is the same) resumes from the last epoch's checkpoint in OUT.partial;
  // otherwise the run is trained afresh over any earlier one.
  TrainOptions StageTrain(const std::string& data, const std::string& out) const {
    TrainOptions o;
    o.data = Path(data);
    o.out = Path(out);
    o.resume = stages_->resuming() && fs::exists(o.out + ".partial");
    o.force = !o.resume;
    return o;
  }
  const ReproduceSize& size() const { return size_; }
  uint64_t seed() const { return ResolveConfig(g_model_.sources).seed; }
  const json& wall_s() const { return stages_->wall_s(); }

 private:
  std::string Config(const std::string& file) const { return (cfg_ / file).string(); }

  // the epochs a training with `g`'s config runs
  static int64_t EpochsOf(const GlobalOptions& g) { return ResolveConfig(g.sources).train.epochs; }

  // configs/transfer.yaml over randomized ts4 strikes, at this size's epochs and members
  GlobalOptions TransferModel() const {
    const TransferSize& t = size_.transfer;
    std::vector<std::string> sets = {kTransferGrid};
    if (t.epochs > 0) sets.push_back(fmt::format("train.epochs={}", t.epochs));
    if (t.members > 0) sets.push_back(fmt::format("train.ensemble_members={}", t.members));
    return Layered(g_, {Config("ts4.yaml"), Config("randomized.yaml"), Config("transfer.yaml")},
                   sets);
  }

  // the cost model's seconds of a stage: the size's held-out strikes scored; the kNN's fit on
  // the training strikes; `strikes` rendered by the solid; a few-shot training on n strikes
  double ScoreWeight() const { return size_.test * kScoreS; }
  double TestGenerateWeight() const { return size_.test * kGenerateS; }
  double KnnFitWeight() const { return size_.train * kFeaturesS; }
  static double RerenderWeight(int64_t strikes) { return strikes * kSolidRenderS; }
  double FewShotWeight(int64_t n, bool fine_tune) const {
    return TrainSeconds(n, fine_tune ? kFineTuneEpochs : transfer_epochs_, transfer_epoch_s_);
  }

  // the modality ablations' seconds: every variant trained but `all`, which is the model copied
  double AblationWeight() const {
    const auto copied = std::count(size_.ablations.begin(), size_.ablations.end(), "all");
    return static_cast<double>(size_.ablations.size() - copied) * train_weight_;
  }

  // The preprocessing ablation's base: the scenario model's config (features and data) with the
  // lightweight model's network and training (its own features, ungated and GCC-PHAT over the
  // whole window, would make the "all" row one of the switches), resolved into one layer file
  GlobalOptions LightModel() const {
    SonicBoomConfig config = ResolveConfig(g_model_.sources);
    const SonicBoomConfig light = ResolveConfig(
        Layered(g_, {Config("ts1.yaml"), Config(kLightModelConfig)}, epochs_).sources);
    config.model = light.model;
    config.train = light.train;
    const std::string file = Path("preprocessing_base.yaml");
    WriteTextAtomic(file, ConfigToYaml(config));
    GlobalOptions out = g_model_;
    out.sources.files = {file};
    out.sources.overrides.clear();  // resolved into the file
    return out;
  }

  // size.test held-out strikes of `config` into data/test_<name>.h5; returns the stage's key
  std::string GenerateTest(const std::string& name, const std::string& config) {
    const GlobalOptions gt = Layered(g_, {Config(config)});
    return stages_->Run(
        "generate_" + name, Digest(size_.name + DataKey(gt) + std::to_string(size_.test)),
        TestGenerateWeight(), [&] {
          RunGenerate(gt, Path(fmt::format("data/test_{}.h5", name)), size_.test,
                      kTestFirstIndex, "0", 1, true);
        });
  }

  // the model's eval of data/test_<name>.h5 (eval/<name>.json; with its per-strike CSV)
  json Evaluate(const std::string& name, bool with_predictions) {
    return EvaluateRun(name, "model", model_key_, name, with_predictions);
  }

  // run `run` (its stage's key `run_key`) scored on data/test_<data>.h5: eval/<name>.json
  json EvaluateRun(const std::string& name, const std::string& run, const std::string& run_key,
                   const std::string& data, bool with_predictions = false) {
    const std::string result = Path(fmt::format("eval/{}.json", name));
    stages_->Run("eval_" + name, Digest(run_key + data_key_[data]), ScoreWeight(), [&] {
      MakeDirectories(Path("eval"));
      EvalOptions e;
      if (with_predictions) e.predictions_csv = Path(fmt::format("eval/{}.csv", name));
      e.force = true;
      const std::string h5 = Path(fmt::format("data/test_{}.h5", data));
      WriteTextAtomic(result, RunEval(Layered(g_, {}), Path(run), h5, e).json + "\n");
    });
    return json::parse(ReadText(result));
  }

  // The transfer model fine-tuned on data/test_<shots>_solid.h5 (every layer at lr 3e-4 for 40
  // epochs: the recipe docs/captures.md chose where the pretrained model is wrong), or the same
  // network trained from scratch on it; scored on the solid's held-out strikes.
  json FewShot(const std::string& shots, int64_t n, const std::string& transfer_key,
               const GlobalOptions& g_transfer, bool fine_tune) {
    const std::string run = fmt::format("transfer/{}_{}", fine_tune ? "tuned" : "scratch", shots);
    const std::string data = shots + "_solid";
    const std::string key = stages_->Run(
        fmt::format("{}_{}", fine_tune ? "tune" : "scratch", shots),
        Digest((fine_tune ? transfer_key : ConfigKey(g_transfer)) + data_key_[data]),
        FewShotWeight(n, fine_tune), [&] {
          TrainOptions o;
          o.data = Path(fmt::format("data/test_{}.h5", data));
          o.out = Path(run);
          o.force = true;
          if (fine_tune) {
            o.init_from = Path("transfer/model");
            o.freeze = learning::FineTune::Freeze::kNone;
            RunTrain(Layered(g_, {},
                             {"train.learning_rate=0.0003",
                              fmt::format("train.epochs={}", kFineTuneEpochs)}),
                     o);
          } else {
            RunTrain(g_transfer, o);
          }
        });
    return EvaluateRun(fmt::format("{}_ts4_solid", fs::path(run).filename().string()), run, key,
                       "ts4_solid");
  }

  // data/test_<name>.h5 (`strikes` of them) rendered by the reference solid into
  // data/test_<name>_solid.h5
  std::string Rerender(const std::string& name, const std::string& data_key, int64_t strikes) {
    const TransferSize& t = size_.transfer;
    return stages_->Run("rerender_" + name,
                        Digest(data_key + fmt::format("{} {}", t.solid_band_hz, t.solid_element_m)),
                        RerenderWeight(strikes), [&] {
                          RerenderOptions o;
                          o.in = Path(fmt::format("data/test_{}.h5", name));
                          o.out = Path(fmt::format("data/test_{}_solid.h5", name));
                          o.max_frequency_hz = t.solid_band_hz;
                          o.element_m = t.solid_element_m;
                          o.force = true;
                          RunRerender(Layered(g_, {}), o);
                        });
  }

  // a baseline on scenario ts (baselines/<method>_<ts>.json)
  json Baseline(BaselineMethod m, const std::string& ts) {
    const std::string name(NameOf(m));
    const std::string file = Path(fmt::format("baselines/{}_{}.json", name, ts));
    // asked twice in one run (the scenarios' and the transfer study's arrival locator): once
    if (!scored_.insert(file).second) return json::parse(ReadText(file));
    // the kNN's fit (the training strikes' features) falls to its first scenario
    const double fit_s = m == BaselineMethod::kKnn && ts == kScenarios[0] ? KnnFitWeight() : 0.0;
    stages_->Run(fmt::format("baseline_{}_{}", name, ts),
                 Digest(name + data_key_["train"] + data_key_[ts] + ConfigKey(g_)),
                 ScoreWeight() + fit_s, [&] {
                   MakeDirectories(Path("baselines"));
                   BaselineOptions b;
                   b.method = m;
                   b.data = Path(fmt::format("data/test_{}.h5", ts));
                   b.train = m == BaselineMethod::kArrival ? "" : Path("data/train.h5");
                   b.k = 1;  // kNN as docs/baselines.md chose it on a validation set
                   b.knn_gcc_lags = 441;
                   b.knn_fits = knn_fits_;  // one fit on the training strikes for every scenario
                   WriteTextAtomic(file, RunBaseline(Layered(g_, {}), b).json + "\n");
                 });
    return json::parse(ReadText(file));
  }

  const GlobalOptions& g_;
  const ReproduceOptions& o_;
  ReproduceSize size_;
  fs::path cfg_, out_;
  std::vector<std::string> epochs_;
  GlobalOptions g_model_, g_light_;  // the scenario model's and the lightweight model's
  double train_weight_{0.0};         // the scenario model's training, cost-model seconds
  double light_weight_{0.0};         // one preprocessing row's training
  int64_t transfer_epochs_{0};       // the transfer network's epochs at this size
  double transfer_epoch_s_{0.0};     // one strike through an epoch of the transfer ensemble
  std::unique_ptr<StageRunner> stages_;
  std::map<std::string, std::string> data_key_;
  std::set<std::string> scored_;  // baseline files written or reused by this run
  // the kNN fitted on the training strikes, while the scenarios are scored (then dropped: its
  // rows are gigabytes at paper size)
  std::shared_ptr<KnnFits> knn_fits_;
  std::string model_key_;
};

}  // namespace

CommandResult RunReproduce(const GlobalOptions& g, const ReproduceOptions& o) {
  Reproduction r(g, o);
  r.GenerateData();
  r.TrainModel();
  const auto [scenarios, baselines] = r.ScoreScenarios();
  const json materials = r.Materials();
  const json ablations = r.Ablations();
  const json preprocessing = r.Preprocessing();
  const json map = r.Map();
  const json transfer = r.Transfer();
  json results = {
      {"size", r.size().name},
      {"train_strikes", r.size().train},
      {"test_strikes_per_scenario", r.size().test},
      {"seed", r.seed()},
      {"commit", CheckoutCommit(fs::current_path())},
      {"machine",
       {{"hardware_threads", std::thread::hardware_concurrency()}, {"threads", g.threads}}},
      {"scenarios", scenarios},
      {"baselines", baselines},
      {"ablations", ablations},
      {"preprocessing", preprocessing},
      {"map", map},
      {"materials", materials},
      {"transfer", transfer}};
  r.Figures(results);
  results["wall_s"] = r.wall_s();
  WriteTextAtomic(r.Path("results.json"), results.dump(1) + "\n");
  const std::string report = ReproduceReport(results, o.size);
  WriteTextAtomic(r.Path("report.md"), report);
  return {results.dump(), fmt::format("{}\nreport: {}\n", report, r.Path("report.md"))};
}

void RegisterReproduce(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto o = std::make_shared<ReproduceOptions>();
  auto* cmd = app.add_subcommand(
      "reproduce",
      "the paper's evaluation in one command: scenarios, training, baselines, ablations and the "
      "haptic map, as DIR/report.md with figures and DIR/results.json (resumable)");
  cmd->add_option("--size", o->size,
                  "quick (about 15 min on 2 cores), paper (18 000 training strikes) or smoke (a "
                  "check that every stage runs; its figures mean nothing)");
  cmd->add_option("--out", o->out, "output directory")->required();
  cmd->add_option("--configs", o->configs_dir, "the configs directory (ts1-ts4, ablations/)");
  cmd->add_option("--plot", o->plot_script, "plotting script");
  cmd->callback([&g, run, o] { *run = [&g, o] { return RunReproduce(g, *o); }; });
}

}  // namespace sonicboom::experiments
