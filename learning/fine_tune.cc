// `--tune auto`: fine-tune candidates cross-validated on the user's strikes, judged by their
// held-out MED, the pretrained weights kept unless a tuned candidate is better beyond the noise.

#include "sonicboom/learning/fine_tune.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <numeric>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/rng.h"

namespace sonicboom::learning {

namespace fs = std::filesystem;

namespace {

// One-sided Student-t quantiles t_{df, 1 - alpha} for df = 1..10.
double TQuantile(int64_t df, double alpha) {
  static constexpr double kAlpha05[] = {6.314, 2.920, 2.353, 2.132, 2.015,
                                        1.943, 1.895, 1.860, 1.833, 1.812};
  static constexpr double kAlpha10[] = {3.078, 1.886, 1.638, 1.533, 1.476,
                                        1.440, 1.415, 1.397, 1.383, 1.372};
  if (alpha != 0.05 && alpha != 0.10) {
    throw ConfigError(fmt::format("fine-tune selection alpha = {}: one of 0.05, 0.10", alpha));
  }
  const auto i = static_cast<size_t>(df - 1);
  return alpha == 0.05 ? kAlpha05[i] : kAlpha10[i];
}

double Mean(const std::vector<double>& v) {
  return std::accumulate(v.begin(), v.end(), 0.0) / static_cast<double>(v.size());
}

// mean(d) / (sd(d) / sqrt(k)) of the paired differences d; +-inf (or 0) when they do not spread.
double PairedT(const std::vector<double>& d) {
  const double mean = Mean(d);
  double ss = 0.0;
  for (const double x : d) ss += (x - mean) * (x - mean);
  const double se = std::sqrt(ss / static_cast<double>(d.size() - 1) / static_cast<double>(d.size()));
  if (se > 0.0) return mean / se;
  return mean < 0.0 ? -std::numeric_limits<double>::infinity()
                    : (mean > 0.0 ? std::numeric_limits<double>::infinity() : 0.0);
}

void CheckFolds(const std::vector<std::vector<double>>& fold_med_cm) {
  if (fold_med_cm.empty()) throw ConfigError("fine-tune selection: no candidates");
  const size_t k = fold_med_cm.front().size();
  if (k < 2 || k > 11) {
    throw ConfigError(fmt::format("fine-tune selection: {} folds; 2 to 11 are tabulated", k));
  }
  for (const auto& c : fold_med_cm) {
    if (c.size() != k) throw ConfigError("fine-tune selection: candidates with unequal folds");
  }
}

// The decision in words.
std::string Why(const FineTuneChoice& c, const std::vector<std::string>& names, size_t k,
                double alpha) {
  const double pre = c.mean_med_cm[0];
  if (c.chosen > 0) {
    const auto i = static_cast<size_t>(c.chosen);
    return fmt::format(
        "{}: held-out MED {:.3f} cm against {:.3f} cm for the pretrained weights, lower on {} of "
        "{} folds (paired t = {:.2f} < -{:.3f}, one-sided at {})",
        names[i], c.mean_med_cm[i], pre, c.folds_better[i], k, c.t_statistic[i], c.t_critical,
        alpha);
  }
  size_t best = 0;
  for (size_t i = 1; i < names.size(); ++i) {
    if (best == 0 || c.mean_med_cm[i] < c.mean_med_cm[best]) best = i;
  }
  if (best == 0) return fmt::format("pretrained weights: the only candidate ({:.3f} cm)", pre);
  return fmt::format(
      "pretrained weights kept: held-out MED {:.3f} cm; no tuned candidate beats it beyond the "
      "folds' spread (best {} {:.3f} cm, lower on {} of {} folds, paired t = {:.2f}; needs < "
      "-{:.3f}, one-sided at {})",
      pre, names[best], c.mean_med_cm[best], c.folds_better[best], k, c.t_statistic[best],
      c.t_critical, alpha);
}

// The rows of `fold` and the others, ascending.
std::pair<std::vector<int64_t>, std::vector<int64_t>> FoldRows(const std::vector<int64_t>& fold_of,
                                                               int64_t fold) {
  std::vector<int64_t> in, out;
  for (size_t r = 0; r < fold_of.size(); ++r) {
    (fold_of[r] == fold ? in : out).push_back(static_cast<int64_t>(r));
  }
  return {in, out};
}

// A tuned candidate trained on every fold but `fold`; its answers to that fold's rows.
std::vector<Prediction> HeldOutAnswers(const FeatureSet& labelled, const std::vector<int64_t>& rows_in,
                                       const std::vector<int64_t>& rows_out,
                                       const FineTuneRecipe& recipe,
                                       const AutoFineTuneOptions& o, const std::string& dir) {
  const FeatureSet train = labelled.SelectRows(rows_out), held = labelled.SelectRows(rows_in);
  TrainConfig config = o.train;
  config.learning_rate = recipe.learning_rate;
  config.keep_best = false;  // the held-out fold chooses nothing
  FineTune tune;
  tune.init_from = o.init_from;
  tune.freeze = recipe.freeze;
  tune.refit_normalization = o.refit_normalization;
  tune.calibration = FineTune::Calibration::kKeepPretrained;
  TrainEnsemble(train, held, o.model, config, o.surface_radius_m, o.seed, dir, /*resume=*/false,
                /*show_progress=*/false, tune);
  return Localizer(dir).Predict(held);
}

// Mean surface error of `rows` (cm).
double RowsMedCm(const std::vector<Prediction>& p, const FeatureSet& truth,
                 const std::vector<int64_t>& rows, double radius_m) {
  double sum = 0.0;
  for (const int64_t r : rows) {
    const auto i = static_cast<size_t>(r);
    sum += SurfaceErrorCm(p[i], truth.z_m[i], truth.theta_rad[i], radius_m);
  }
  return sum / static_cast<double>(rows.size());
}

}  // namespace

std::vector<FineTuneCandidate> DefaultFineTuneCandidates() {
  return {{"pretrained", std::nullopt},
          {"all-but-head lr 1e-4", FineTuneRecipe{FineTune::Freeze::kAllButHead, 1e-4}},
          {"none lr 3e-4", FineTuneRecipe{FineTune::Freeze::kNone, 3e-4}}};
}

FineTuneChoice SelectFineTune(const std::vector<std::vector<double>>& fold_med_cm,
                              const FineTuneSelection& rule, std::vector<std::string> names) {
  CheckFolds(fold_med_cm);
  const size_t k = fold_med_cm.front().size();
  FineTuneChoice c;
  c.t_critical = TQuantile(static_cast<int64_t>(k) - 1, rule.alpha);
  for (size_t i = names.size(); i < fold_med_cm.size(); ++i) {
    names.push_back(fmt::format("candidate {}", i));
  }
  for (size_t i = 0; i < fold_med_cm.size(); ++i) {
    c.mean_med_cm.push_back(Mean(fold_med_cm[i]));
    std::vector<double> d;
    int64_t better = 0;
    for (size_t f = 0; f < k; ++f) {
      d.push_back(fold_med_cm[i][f] - fold_med_cm[0][f]);
      better += d.back() < 0.0;
    }
    c.folds_better.push_back(i == 0 ? 0 : better);
    c.t_statistic.push_back(i == 0 ? std::numeric_limits<double>::quiet_NaN() : PairedT(d));
    const bool passes = i > 0 && c.t_statistic[i] < -c.t_critical;
    const auto chosen = static_cast<size_t>(c.chosen);
    if (passes && (c.chosen == 0 || c.mean_med_cm[i] < c.mean_med_cm[chosen])) {
      c.chosen = static_cast<int64_t>(i);
    }
  }
  c.why = Why(c, names, k, rule.alpha);
  return c;
}

std::vector<int64_t> AssignFolds(const std::vector<uint64_t>& sample_indices, int64_t folds,
                                 uint64_t seed) {
  if (folds < 1) throw ConfigError(fmt::format("{} folds: need at least one", folds));
  const uint64_t stream = SampleSeed(seed, static_cast<uint64_t>(Stream::kSplit));
  std::vector<std::pair<uint64_t, size_t>> keyed;
  for (size_t r = 0; r < sample_indices.size(); ++r) {
    keyed.emplace_back(SampleSeed(stream, sample_indices[r]), r);
  }
  std::sort(keyed.begin(), keyed.end());
  std::vector<int64_t> fold_of(sample_indices.size());
  for (size_t rank = 0; rank < keyed.size(); ++rank) {
    fold_of[keyed[rank].second] = static_cast<int64_t>(rank) % folds;
  }
  return fold_of;
}

AutoFineTuneResult CrossValidateFineTune(const FeatureSet& labelled,
                                         const std::vector<uint64_t>& sample_indices,
                                         const AutoFineTuneOptions& o) {
  const int64_t n = labelled.size();
  if (n < o.min_strikes) {
    throw ConfigError(fmt::format(
        "{} labelled strikes: --tune auto cross-validates over at least {}; give more, a fixed "
        "recipe (--freeze F --lr LR), or use the pretrained run as it is",
        n, o.min_strikes));
  }
  if (o.max_folds < 2 || o.max_folds > 11) {
    throw ConfigError(fmt::format("{} folds: 2 to 11 are tabulated", o.max_folds));
  }
  TQuantile(1, o.selection.alpha);  // an alpha not tabulated is refused before any training
  const int64_t k = std::min(o.max_folds, n);
  AutoFineTuneResult result;
  result.candidates = o.candidates;
  result.fold_of_row = AssignFolds(sample_indices, k, o.seed);
  const std::vector<Prediction> pretrained = Localizer(o.init_from).Predict(labelled);
  std::vector<std::vector<Prediction>> answers;
  for (size_t c = 0; c < o.candidates.size(); ++c) {
    const FineTuneCandidate& candidate = o.candidates[c];
    answers.push_back(pretrained);
    result.fold_med_cm.emplace_back();
    for (int64_t f = 0; f < k; ++f) {
      const auto [rows_in, rows_out] = FoldRows(result.fold_of_row, f);
      if (candidate.recipe) {
        const std::string dir = (fs::path(o.work_dir) / fmt::format("c{}_fold{}", c, f)).string();
        const std::vector<Prediction> p =
            HeldOutAnswers(labelled, rows_in, rows_out, *candidate.recipe, o, dir);
        for (size_t i = 0; i < rows_in.size(); ++i) answers[c][static_cast<size_t>(rows_in[i])] = p[i];
        fs::remove_all(dir);
      }
      result.fold_med_cm[c].push_back(RowsMedCm(answers[c], labelled, rows_in, o.surface_radius_m));
      if (o.show_progress) {
        spdlog::info("cross-validation: {}, fold {}/{} ({} held out): MED {:.3f} cm",
                     candidate.name, f + 1, k, rows_in.size(), result.fold_med_cm[c].back());
      }
    }
  }
  std::vector<std::string> names;
  for (const FineTuneCandidate& c : o.candidates) names.push_back(c.name);
  result.choice = SelectFineTune(result.fold_med_cm, o.selection, names);
  result.held_out = answers[static_cast<size_t>(result.choice.chosen)];
  return result;
}

}  // namespace sonicboom::learning
