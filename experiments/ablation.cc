// Ablations as configs: every YAML file of a directory is one variant (modality set or
// preprocessing switch) layered over the run's config; each is trained on one dataset,
// evaluated on another, and the results become one table.
#include <CLI/CLI.hpp>

#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>
#include <nlohmann/json.hpp>

#include "internal/report.h"
#include "internal/subcommands.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/experiments/commands.h"
#include "sonicboom/experiments/pipeline.h"

namespace sonicboom::experiments {
namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// one ablation: its name (file stem without a leading "NN-"), description and config file
struct Variant {
  std::string name, description, path;
};

// the *.yaml files of `dir` in name order; the description is the file's first comment line
std::vector<Variant> ListVariants(const std::string& dir, const std::vector<std::string>& only) {
  if (!fs::is_directory(dir)) throw IoError(fmt::format("{}: no such ablation directory", dir));
  std::vector<Variant> variants;
  for (const auto& entry : fs::directory_iterator(dir)) {
    if (entry.path().extension() != ".yaml") continue;
    std::string name = entry.path().stem().string();
    const size_t dash = name.find('-');
    if (dash != std::string::npos && dash > 0 &&
        std::all_of(name.begin(), name.begin() + dash, [](char c) { return std::isdigit(c); })) {
      name = name.substr(dash + 1);
    }
    const std::string text = ReadText(entry.path().string());
    std::string description;
    if (text.rfind("# ", 0) == 0) description = text.substr(2, text.find('\n') - 2);
    variants.push_back({name, description, entry.path().string()});
  }
  std::sort(variants.begin(), variants.end(),
            [](const Variant& a, const Variant& b) { return a.path < b.path; });
  if (!only.empty()) {
    std::vector<Variant> chosen;
    for (const std::string& want : only) {
      auto it = std::find_if(variants.begin(), variants.end(),
                             [&](const Variant& v) { return v.name == want; });
      if (it == variants.end()) {
        throw ConfigError(fmt::format("--only: no ablation named '{}' in {}", want, dir));
      }
      chosen.push_back(*it);
    }
    variants = chosen;
  }
  if (variants.empty()) throw ConfigError(fmt::format("{}: holds no ablation (*.yaml)", dir));
  return variants;
}

// features of a dataset, computed once per distinct feature config; one set in memory at a
// time (datasets are large): whole (a test set) or split for training
class FeatureCache {
 public:
  FeatureCache(std::string path, int threads, bool quiet)
      : path_(std::move(path)), threads_(threads), quiet_(quiet) {}
  const learning::FeatureSet& Whole(const SonicBoomConfig& config) {
    const std::string key = FeaturesKey(config);
    if (key != key_) {
      Compute(config);
      key_ = key;
    }
    return set_;
  }
  // the training and validation rows (SplitFeatures: in place, no second copy of the set)
  const FeatureSplit& Split(const SonicBoomConfig& config) {
    const std::string key =
        FeaturesKey(config) + fmt::format("\nsplit: seed {}, val_fraction {:.17g}", config.seed,
                                          config.train.val_fraction);
    if (key != key_) {
      Compute(config);
      split_ = SplitFeatures(config, std::move(set_), indices_, path_);
      key_ = key;
    }
    return split_;
  }

 private:
  // every section but the model and training ones can change the features
  static std::string FeaturesKey(const SonicBoomConfig& config) {
    SonicBoomConfig stripped = config;
    stripped.model = learning::ModelConfig{};
    stripped.train = learning::TrainConfig{};
    return ConfigToYaml(stripped);
  }
  // the dataset's features into set_; nothing held counts (key_ "") until the caller names it
  void Compute(const SonicBoomConfig& config) {
    key_.clear();
    set_ = {};
    split_ = {};
    set_ = ComputeDatasetFeatures(path_, config, threads_, !quiet_, &indices_);
  }

  std::string path_;
  int threads_;
  bool quiet_;
  std::string key_;  // what set_ or split_ holds; "" = nothing
  learning::FeatureSet set_;
  FeatureSplit split_;
  std::vector<uint64_t> indices_;
};

// the sum of a run's epoch_seconds (metrics.jsonl: one JSON object per epoch)
double EpochSeconds(const std::string& metrics_jsonl) {
  std::istringstream in(ReadText(metrics_jsonl));
  double sum = 0.0;
  for (std::string line; std::getline(in, line);) {
    if (!line.empty()) sum += nlohmann::json::parse(line).at("epoch_seconds").get<double>();
  }
  return sum;
}

// The first of `runs` trained with exactly `config_yaml` (a finished run: model.json written
// last), copied file by file into run_dir (model.json last); "" when none matches.
std::string CopyIdenticalRun(const std::vector<std::string>& runs, const std::string& config_yaml,
                             const std::string& run_dir) {
  for (const std::string& run : runs) {
    const fs::path from(run);
    if (ReadText((from / "config.yaml").string()) != config_yaml) continue;
    MakeDirectories(run_dir);
    for (const fs::directory_entry& e : fs::directory_iterator(from)) {
      if (e.is_regular_file() && e.path().filename() != "model.json") {
        fs::copy_file(e.path(), fs::path(run_dir) / e.path().filename(),
                      fs::copy_options::overwrite_existing);
      }
    }
    fs::copy_file(from / "model.json", fs::path(run_dir) / "model.json",
                  fs::copy_options::overwrite_existing);
    return run;
  }
  return "";
}

std::string Join(const std::vector<std::string>& v) {
  std::string s;
  for (const std::string& x : v) s += (s.empty() ? "" : "+") + x;
  return s;
}

}  // namespace

std::string AblationTableMarkdown(const json& rows, bool descriptions) {
  auto on = [](const json& a, const char* key) { return a[key].get<bool>() ? "on" : "off"; };
  const json& tests = rows.empty() ? json::array() : rows[0]["tests"];
  std::string head = descriptions ? " description |" : "", rule = descriptions ? "---|" : "";
  for (size_t k = tests.size(); tests.size() > 1 && k-- > 0;) {
    std::string set = fs::path(tests[k]["data"].get<std::string>()).stem().string();
    if (set.rfind("test_", 0) == 0) set = set.substr(5);  // reproduce's data/test_<scenario>.h5
    head = fmt::format(" MED {} (cm) |", set) + head;
    rule = "---|" + rule;
  }
  std::string md = fmt::format(
      "| ablation | modalities | gating | GCC span (s) | shift | masks | norm | 3-D MED (cm) | "
      "height (cm) | angle (deg) | train (s) "
      "|{}\n|---|---|---|---|---|---|---|---|---|---|---|{}\n",
      head, rule);
  std::string notes;  // a footnote per row copied from a given run or diverged
  for (const json& a : rows) {
    const json& m = a["test"];
    const json copied = a.value("copied_from", json());
    const json diverged = a.value("diverged", json());
    const std::string name = a["name"].get<std::string>();
    if (copied.is_string()) {
      notes += fmt::format("\n\\* {}: copied from {}, trained with the very same config.\n", name,
                           copied.get<std::string>());
    }
    if (diverged.is_string()) {
      notes += fmt::format("\n† {}: not scored; {}\n", name, diverged.get<std::string>());
    }
    // a diverged row has no errors: its cells say so
    auto cell = [&](const json& e, const char* key, const char* spec) {
      return e.is_null() ? std::string("diverged†")
                         : fmt::format(fmt::runtime(spec), e[key].get<double>());
    };
    md += fmt::format("| {} | {} | {} | {:g} | {} | {} | {} | {} | {} | {} | {:.0f}{} |", name,
                      Join(a["modalities"].get<std::vector<std::string>>()), on(a, "gating"),
                      a["gcc_span_s"].get<double>(), on(a, "time_shift"), on(a, "masking"),
                      on(a, "normalize"), cell(m, "med_cm", "{:.2f}"),
                      cell(m, "height_err_cm", "{:.2f}"), cell(m, "angle_err_deg", "{:.1f}"),
                      a["train_s"].get<double>(), copied.is_string() ? "\\*" : "");
    for (size_t k = 0; tests.size() > 1 && k < a["tests"].size(); ++k) {
      md += fmt::format(" {} |", cell(a["tests"][k]["test"], "med_cm", "{:.2f}"));
    }
    md += descriptions ? fmt::format(" {} |\n", a["description"].get<std::string>()) : "\n";
  }
  return md + notes;
}

CommandResult RunAblate(const GlobalOptions& g, const AblateOptions& o) {
  if (o.tests.empty()) throw ConfigError("ablate: --test names no held-out dataset");
  std::vector<ReadPath> inputs = {{o.data, "--data"}, {o.configs_dir, "--configs"}};
  if (!fs::exists(o.data)) throw IoError(fmt::format("{}: no such dataset", o.data));
  for (const std::string& test : o.tests) {
    if (!fs::exists(test)) throw IoError(fmt::format("{}: no such dataset", test));
    inputs.push_back({test, "--test"});
  }
  for (const std::string& run : o.trained_runs) {
    for (const char* file : {"config.yaml", "model.json"}) {
      if (!fs::is_regular_file(fs::path(run) / file)) {
        throw IoError(fmt::format("--reuse {}: not a finished run (no {})", run, file));
      }
    }
    inputs.push_back({run, "--reuse"});
  }
  RefuseWritingOverInputs(g, {o.out}, inputs);
  const std::vector<Variant> variants = ListVariants(o.configs_dir, o.only);
  // resolve every variant first: a bad file fails before any training
  std::vector<SonicBoomConfig> configs;
  for (const Variant& v : variants) {
    // the variant goes after the user's --config files, before the --set overrides
    ConfigSources sources = g.sources;
    sources.files.push_back(v.path);
    configs.push_back(ResolveConfig(sources));
  }
  MakeDirectories(o.out);

  FeatureCache train_features(o.data, g.threads, g.quiet);
  std::vector<std::unique_ptr<FeatureCache>> test_features;
  for (const std::string& test : o.tests) {
    test_features.push_back(std::make_unique<FeatureCache>(test, g.threads, g.quiet));
  }
  json rows = json::array();
  for (size_t i = 0; i < variants.size(); ++i) {
    const Variant& v = variants[i];
    const SonicBoomConfig& config = configs[i];
    const std::string run_dir = (fs::path(o.out) / v.name).string();
    spdlog::info("ablation {}/{}: {} ({})", i + 1, variants.size(), v.name, v.description);

    // a finished run of this variant trained with this very config is kept (model.json is
    // written last); one of o.trained_runs with this very config is copied; a killed one resumes
    // from its last epoch; a run of another config (a changed file or layer) is removed and
    // trained again
    double train_s = 0.0;
    std::string copied_from;
    const fs::path timing = fs::path(run_dir) / "ablation_train_s.txt";
    const fs::path config_file = fs::path(run_dir) / "config.yaml";
    const std::string config_yaml = ConfigToYaml(config);
    if (fs::exists(run_dir) &&
        !(fs::exists(config_file) && ReadText(config_file.string()) == config_yaml)) {
      spdlog::info("ablation {}: {} was trained with another config; training it again", v.name,
                   run_dir);
      fs::remove_all(run_dir);
    }
    const fs::path copied = fs::path(run_dir) / "ablation_copied_from.txt";
    // holds the error of a variant whose training diverged (no model.json)
    const fs::path diverged_file = fs::path(run_dir) / "ablation_diverged.txt";
    const bool finished =
        (fs::exists(fs::path(run_dir) / "model.json") || fs::exists(diverged_file)) &&
        fs::exists(timing);
    if (!finished) copied_from = CopyIdenticalRun(o.trained_runs, config_yaml, run_dir);
    if (finished) {
      train_s = std::stod(ReadText(timing.string()));
      if (fs::exists(copied)) copied_from = ReadText(copied.string());
    } else if (!copied_from.empty()) {
      // the same network on the same strikes: the given run's model and its training time
      spdlog::info("ablation {}: trained with the same config as {}; copied", v.name, copied_from);
      train_s = EpochSeconds((fs::path(run_dir) / "metrics.jsonl").string());
      WriteTextAtomic(copied.string(), copied_from);
      WriteTextAtomic(timing.string(), fmt::format("{}\n", train_s));
    } else {
      MakeDirectories(run_dir);
      WriteTextAtomic(config_file.string(), config_yaml);
      const FeatureSplit& split = train_features.Split(config);
      const bool resumed = fs::exists(fs::path(run_dir) / "checkpoint.pt");
      const auto start = std::chrono::steady_clock::now();
      try {
        TrainOnSplit(config, split, run_dir, /*resume=*/true, g.quiet);
      } catch (const NumericalError& e) {
        // a variant whose training diverges is a finding of the ablation, not the end of the
        // others: its row says so, and a rerun does not train it again
        spdlog::warn("ablation {}: {}", v.name, e.what());
        WriteTextAtomic(diverged_file.string(), e.what());
      }
      train_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
      // resumed: the epochs' own seconds over every process that trained it
      if (resumed) train_s = EpochSeconds((fs::path(run_dir) / "metrics.jsonl").string());
      WriteTextAtomic(timing.string(), fmt::format("{}\n", train_s));
    }

    // held-out errors on every test set (null when the training diverged); the first is the
    // table's
    const json diverged =
        fs::exists(diverged_file) ? json(ReadText(diverged_file.string())) : json();
    json by_test = json::array();
    std::unique_ptr<learning::Localizer> localizer;
    if (diverged.is_null()) localizer = std::make_unique<learning::Localizer>(run_dir);
    for (size_t k = 0; k < o.tests.size(); ++k) {
      json errors;
      if (localizer) {
        const learning::FeatureSet& test = test_features[k]->Whole(config);
        errors = MetricsJson(learning::ComputeMetrics(localizer->Predict(test), test,
                                                      localizer->surface_radius_m()));
      }
      by_test.push_back({{"data", o.tests[k]}, {"test", errors}});
    }
    const learning::TrainConfig& t = config.train;
    const bool masks = t.augment && (t.time_mask_frames > 0 || t.freq_mask_bands > 0);
    const bool shift = t.augment && t.time_shift_frames > 0;
    const double gcc_span_s = config.features.gcc_span_s();
    json row = {{"name", v.name},
                {"description", v.description},
                {"config", v.path},
                {"modalities", config.model.modalities},
                {"gating", config.features.gating},
                {"gcc_span_s", gcc_span_s},
                {"time_shift", shift},
                {"masking", masks},
                {"normalize", t.normalize},
                {"train_s", train_s},
                {"copied_from", copied_from.empty() ? json() : json(copied_from)},
                {"diverged", diverged},
                {"test", by_test[0]["test"]},
                {"tests", by_test}};
    rows.push_back(row);
  }
  const std::string table = AblationTableMarkdown(rows, /*descriptions=*/true);

  // the first test set's size, from a row that was scored
  int64_t n_test = 0;
  for (auto row = rows.begin(); row != rows.end() && n_test == 0; ++row) {
    if (!(*row)["test"].is_null()) n_test = (*row)["test"]["n"].get<int64_t>();
  }
  const std::string header = fmt::format(
      "Ablations: trained on {}, evaluated on {} ({} strikes){}; configs from {}.\n\n", o.data,
      o.tests[0], n_test,
      o.tests.size() > 1
          ? fmt::format(" and on {}", fmt::join(o.tests.begin() + 1, o.tests.end(), ", "))
          : "",
      o.configs_dir);
  WriteTextAtomic((fs::path(o.out) / "table.md").string(), header + table);
  const json result = {{"out", o.out},
                       {"data", o.data},
                       {"test", o.tests[0]},
                       {"tests", o.tests},
                       {"ablations", rows}};
  WriteTextAtomic((fs::path(o.out) / "results.json").string(), result.dump(2) + "\n");
  return {result.dump(), header + table};
}

void RegisterAblate(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto o = std::make_shared<AblateOptions>();
  auto* ablate = app.add_subcommand("ablate",
                                    "train and evaluate every ablation config (modality "
                                    "sets, preprocessing switches) and write a table");
  ablate->add_option("--data", o->data, "training dataset (.h5)")->required();
  ablate
      ->add_option("--test", o->tests,
                   "held-out dataset (.h5); repeat for more (a MED column each; the first is "
                   "the table's)")
      ->required();
  ablate->add_option("--out", o->out, "output directory")->required();
  ablate->add_option("--configs", o->configs_dir, "directory of ablation YAML layers");
  ablate->add_option("--only", o->only, "ablation names to run (default all)")->delimiter(',');
  ablate->add_option("--reuse", o->trained_runs,
                     "a finished run trained on --data; a variant with its very config is copied "
                     "from it, not trained again (repeat for more)");
  ablate->callback([&g, run, o] { *run = [&g, o] { return RunAblate(g, *o); }; });
}

}  // namespace sonicboom::experiments
