// A finished run's calibration refitted on records other than its validation split: e.g. strikes
// of structures beyond the training pool, or labelled captures of the user's own robot.

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <string>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>
#include <spdlog/spdlog.h>

#include "internal/data.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/learning/conformal.h"
#include "sonicboom/learning/learning.h"

namespace sonicboom::learning {

namespace fs = std::filesystem;

int64_t CalibrationRecords(const std::vector<Prediction>& predictions, const FeatureSet& truth) {
  int64_t n = 0;
  for (size_t i = 0; i < predictions.size() && i < truth.z_m.size(); ++i) {
    n += predictions[i].has_uncertainty() && std::isfinite(truth.z_m[i]) &&
         std::isfinite(truth.theta_rad[i]);
  }
  return n;
}

CalibrationFit FitOrKeepCalibration(const std::vector<Prediction>& predictions,
                                    const FeatureSet& truth, const UncertaintyCalibration& kept,
                                    const std::string& kept_what) {
  CalibrationFit fit;
  fit.records = CalibrationRecords(predictions, truth);
  fit.fitted = fit.records >= kMinFitRecords;
  if (fit.fitted) {
    fit.scales = FitUncertaintyCalibration(predictions, truth);
    fit.method = "scales minimizing the mean NLL of the validation split";
    return fit;
  }
  fit.scales = kept;
  fit.method = fmt::format(
      "not fitted: {} validation strikes with a predictive distribution, fewer than the {} a fit "
      "needs; {} kept",
      fit.records, kMinFitRecords, kept_what);
  spdlog::warn("interval scales {} (sigma_z x {:.3g}, kappa x {:.3g}); sonicboom calibrate "
               "refits them on labelled strikes",
               fit.method, kept.z_std_scale, kept.kappa_scale);
  return fit;
}

CalibrationFit KeptCalibrationFit(const UncertaintyCalibration& kept, const std::string& kept_what) {
  CalibrationFit fit;
  fit.scales = kept;
  fit.method = fmt::format("not fitted (the fine-tune keeps its calibration): {}", kept_what);
  return fit;
}

namespace {

// The "uncertainty" object of model.json or ensemble.json with `after` and its provenance.
void StoreScales(nlohmann::json* u, const UncertaintyCalibration& after, const std::string& source,
                 int64_t records, IntervalFit fit) {
  (*u)["z_std_scale"] = after.z_std_scale;
  (*u)["kappa_scale"] = after.kappa_scale;
  (*u)["method"] = fmt::format(
      "scales {} of {} ({} records; sonicboom calibrate)",
      fit == IntervalFit::kCoverage ? "covering 90 % with the 90 % intervals"
                                       : "minimizing the mean NLL",
      source, records);
  (*u)["records"] = records;
  (*u)["calibrated_on"] = source;
}

}  // namespace

Recalibration Recalibrate(const std::string& run_dir, const std::vector<Prediction>& predictions,
                          const FeatureSet& truth, const std::string& source, IntervalFit fit) {
  const bool ensemble = !EnsembleMembers(run_dir).empty();
  const std::string path =
      (fs::path(run_dir) / (ensemble ? "ensemble.json" : "model.json")).string();
  if (static_cast<int64_t>(predictions.size()) != truth.size() ||
      truth.theta_rad.size() != truth.z_m.size()) {
    throw SchemaError(fmt::format("{}: {} predictions for {} labelled records", path,
                                  predictions.size(), truth.size()));
  }
  const int64_t records = CalibrationRecords(predictions, truth);
  if (records < kMinFitRecords) {
    throw SchemaError(fmt::format(
        "{}: {} labelled records with a predictive distribution in {}; a refit of the two "
        "scales needs at least {}",
        path, records, source, kMinFitRecords));
  }
  nlohmann::json j = internal::ReadJsonFile(path);
  if (!j.is_object()) throw SchemaError(fmt::format("{}: not a JSON object", path));
  // the stored scales (1 and 1 in a file written before calibration existed)
  Recalibration r;
  if (j.contains("uncertainty")) {
    r.before = internal::CalibrationFromJson(j["uncertainty"], path);
  } else {
    j["uncertainty"] = nlohmann::json::object();
  }
  r.relative = fit == IntervalFit::kCoverage ? FitCoverageCalibration(predictions, truth)
                                                : FitUncertaintyCalibration(predictions, truth);
  // the product kept within the scales' bounds
  const auto bounded = [](double scale) {
    return std::clamp(scale, UncertaintyCalibration::kMinScale, UncertaintyCalibration::kMaxScale);
  };
  r.after = {bounded(r.before.z_std_scale * r.relative.z_std_scale),
             bounded(r.before.kappa_scale * r.relative.kappa_scale)};
  // what the refit applied on top of the stored scales, once bounded
  r.relative = {r.after.z_std_scale / r.before.z_std_scale,
                r.after.kappa_scale / r.before.kappa_scale};
  StoreScales(&j["uncertainty"], r.after, source, records, fit);
  WriteTextAtomic(path, j.dump(2) + "\n");
  return r;
}

}  // namespace sonicboom::learning
