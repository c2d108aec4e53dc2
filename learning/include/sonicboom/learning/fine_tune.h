#pragma once
/// Automatic fine-tuning (`train --init-from RUN`, `--tune auto`): candidate recipes judged by
/// k-fold cross-validation over the user's labelled strikes, by their held-out localization error;
/// a tuned recipe is chosen only when it beats the pretrained weights by more than the folds'
/// spread allows by chance.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "sonicboom/learning/learning.h"

namespace sonicboom::learning {

/// How a tuned candidate trains (its epochs are the training config's).
struct FineTuneRecipe {
  FineTune::Freeze freeze{FineTune::Freeze::kNone};
  double learning_rate{3e-4};
};

/// One candidate: a recipe, or (no recipe) the pretrained weights unchanged.
struct FineTuneCandidate {
  std::string name;
  std::optional<FineTuneRecipe> recipe;
};

/// The candidates of `--tune auto`, the pretrained weights first: those, `all-but-head` at lr
/// 1e-4 (keeps what a model that is right has), `none` at lr 3e-4 (moves a model that is wrong).
std::vector<FineTuneCandidate> DefaultFineTuneCandidates();

/// The selection rule: a tuned candidate replaces the pretrained weights (candidate 0) only when
/// a one-sided paired t-test over the folds says its held-out MED is lower, at `alpha`.
struct FineTuneSelection {
  double alpha{0.05};  // one of 0.05, 0.10 (the t quantiles tabulated)
};

/// The decision over per-fold held-out MEDs.
struct FineTuneChoice {
  int64_t chosen{0};            // index into the candidates; 0: the pretrained weights
  std::vector<double> mean_med_cm;  // per candidate, the mean over folds
  std::vector<double> t_statistic;  // per candidate, paired against candidate 0 (NaN for it)
  std::vector<int64_t> folds_better;  // per candidate, folds where it beat candidate 0
  double t_critical{0.0};       // the one-sided quantile the statistic must fall below
  std::string why;              // the decision in words
};

/// Chooses among candidates from fold_med_cm[candidate][fold] (candidate 0 the pretrained
/// weights; every candidate the same k >= 2 folds, k <= 11): the tuned candidate with the lowest
/// mean among those whose paired differences d_f = MED_c,f - MED_0,f have mean(d) / SE(d) below
/// -t_{k-1, 1-alpha} (SE = sd / sqrt(k); every d below 0 with no spread passes). None: candidate
/// 0. ConfigError for fold counts out of range or unequal, or an alpha not tabulated.
/// `names` name the candidates in `why` ("candidate i" for those missing).
FineTuneChoice SelectFineTune(const std::vector<std::vector<double>>& fold_med_cm,
                              const FineTuneSelection& rule = {},
                              std::vector<std::string> names = {});

/// The fold (0..folds-1) of each row: rows ordered by SampleSeed(seed, sample index), then dealt
/// out in turn, so folds differ in size by at most one and do not depend on row order.
std::vector<int64_t> AssignFolds(const std::vector<uint64_t>& sample_indices, int64_t folds,
                                 uint64_t seed);

/// What the cross-validation trains and how.
struct AutoFineTuneOptions {
  std::string init_from;  // the pretrained run (a run or an ensemble directory)
  ModelConfig model;
  TrainConfig train;  // epochs and the rest of each tuned candidate (keep_best is turned off)
  bool refit_normalization{false};  // FineTune::refit_normalization of every tuned candidate
  double surface_radius_m{0.0};
  uint64_t seed{0};
  std::string work_dir;  // the fold runs (removed when done)
  int64_t max_folds{5};  // k = min(max_folds, labelled strikes)
  int64_t min_strikes{5};  // fewer labelled strikes: ConfigError
  FineTuneSelection selection;
  std::vector<FineTuneCandidate> candidates = DefaultFineTuneCandidates();
  bool show_progress{false};
};

/// The cross-validation and its decision.
struct AutoFineTuneResult {
  std::vector<FineTuneCandidate> candidates;
  std::vector<int64_t> fold_of_row;              // per labelled row of the input
  std::vector<std::vector<double>> fold_med_cm;  // [candidate][fold]
  FineTuneChoice choice;
  // the chosen candidate's held-out predictions, one per row (each by the fold model that did not
  // train on it; the pretrained run's own for candidate 0): what its intervals are judged on
  std::vector<Prediction> held_out;
};

/// Cross-validates options.candidates on `labelled` (every row labelled; sample_indices its
/// global indices): per fold, each tuned candidate fine-tunes options.init_from on the other
/// folds (FineTune::Calibration::kKeepPretrained, so the held-out fold informs nothing) and
/// answers the held-out fold with the run's own averaging (Localizer); candidate 0 is the
/// pretrained run's answers. Then SelectFineTune. ConfigError with fewer than min_strikes rows.
AutoFineTuneResult CrossValidateFineTune(const FeatureSet& labelled,
                                         const std::vector<uint64_t>& sample_indices,
                                         const AutoFineTuneOptions& options);

}  // namespace sonicboom::learning
