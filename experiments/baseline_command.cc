// `baseline`: kNN, TDOA, the arrival locator or a constant on a dataset.
#include "sonicboom/experiments/commands.h"

#include <CLI/CLI.hpp>

#include <algorithm>
#include <filesystem>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "sonicboom/core/dataset.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/dsp/features.h"
#include "sonicboom/experiments/baselines.h"
#include "sonicboom/experiments/pipeline.h"
#include "sonicboom/learning/baselines.h"
#include "sonicboom/learning/learning.h"

#include "internal/report.h"
#include "internal/subcommands.h"

namespace sonicboom::experiments {

namespace fs = std::filesystem;
using nlohmann::json;

CommandResult RunBaseline(const GlobalOptions& g, const BaselineOptions& o) {
  const std::string method(NameOf(o.method));
  if ((o.method == BaselineMethod::kKnn || o.method == BaselineMethod::kConstant) &&
      o.train.empty()) {
    throw ConfigError(fmt::format("--method {} needs --train TRAIN.h5", method));
  }
  for (const std::string& path : {o.data, o.train}) {
    if (!path.empty() && !fs::exists(path)) throw IoError(fmt::format("{}: no such dataset", path));
  }
  // a fitted baseline reads both files as its training file's config does (as a trained model
  // reads with its run's): a test set that logs the arm longer (configs/ts3.yaml) is read alike
  const SonicBoomConfig config = ResolveWithDataset(g, o.train.empty() ? o.data : o.train);
  const double radius = config.tube.outer_radius_m;
  std::vector<learning::Prediction> predictions;
  learning::FeatureSet truth;
  json extra;
  std::string detail;

  if (o.method == BaselineMethod::kConstant) {
    // mean height and circular mean angle of the training labels
    const learning::FeatureSet train = DatasetLabels(o.train, config);
    const learning::Prediction p = learning::ConstantPrediction(train.z_m, train.theta_rad);
    truth = DatasetLabels(o.data, config);
    predictions.assign(static_cast<size_t>(truth.size()), p);
    extra = {{"train_n", train.size()}, {"z_m", p.z_m}, {"theta_rad", p.theta_rad}};
  } else if (o.method == BaselineMethod::kArrival) {
    // first arrivals per channel, fitted by surface paths and one free wave speed; no training
    const double fs = DatasetReader(o.data).info().sample_rate_hz;
    const acoustics::ArrivalLocator locator(TdoaGeometryOf(config), config.arrival, fs);
    std::vector<acoustics::ArrivalEstimate> estimates;
    predictions = LocateByArrival(o.data, config, locator, g.threads, !g.quiet, &truth, &estimates);
    std::vector<double> speeds;
    for (const acoustics::ArrivalEstimate& e : estimates) speeds.push_back(e.speed_m_s);
    std::sort(speeds.begin(), speeds.end());
    const double median_speed = speeds.empty() ? 0.0 : speeds[speeds.size() / 2];
    extra = {{"median_speed_m_s", median_speed}};
    detail = fmt::format(" (no training; median fitted speed {:.0f} m/s)", median_speed);
  } else if (o.method == BaselineMethod::kKnn) {
    // pooled log-mel (+ GCC lags) of the training strikes, k nearest by standardized distance
    learning::KnnConfig knn_config;
    knn_config.k = o.k;
    knn_config.crop_frames = config.model.crop_frames;
    knn_config.mel_is_log = config.features.log_mel;
    knn_config.gcc_lags = o.knn_gcc_lags;
    knn_config.threads = g.threads;
    KnnFits own_fit;
    KnnFits& fits = o.knn_fits ? *o.knn_fits : own_fit;
    const learning::KnnBaseline& knn = fits.Get(o.train, config, knn_config, g.threads, !g.quiet);
    truth = ComputeDatasetFeatures(o.data, config, g.threads, !g.quiet);
    predictions = knn.Predict(truth);
    extra = {{"train_n", knn.size()},
             {"k", o.k},
             {"dimensions", knn.dimensions()},
             {"gcc_lags", o.knn_gcc_lags}};
    detail = fmt::format(" (k = {}, {} training strikes, {} dimensions)", o.k, knn.size(),
                         knn.dimensions());
  } else {
    // steered response of band GCC-PHAT envelopes over the contact region
    acoustics::TdoaConfig tdoa_config;
    tdoa_config.dispersive = !o.non_dispersive;
    if (!o.bands_hz.empty()) tdoa_config.band_edges_hz = o.bands_hz;
    const double fs = DatasetReader(o.data).info().sample_rate_hz;
    const acoustics::TdoaLocator locator(TdoaGeometryOf(config), tdoa_config, fs);
    std::vector<double> speeds;
    for (int b = 0; b < locator.bands(); ++b) speeds.push_back(locator.BandSpeed(b));
    double scale = 1.0;
    extra = {{"dispersive", tdoa_config.dispersive},
             {"band_edges_hz", tdoa_config.band_edges_hz},
             {"band_speeds_m_s", speeds},
             {"seamed", !TdoaGeometryOf(config).seam_theta_rad.empty()}};
    if (!o.train.empty() && !o.no_fit) {
      // one global speed scale, fitted on (at most fit_strikes) training strikes; the range
      // holds the simulated tube's best scale (about 0.5, docs/baselines.md) with room
      constexpr double kFitLo = 0.3, kFitHi = 1.5;
      learning::FeatureSet fit_labels;
      const std::vector<acoustics::TdoaCorrelations> fit = CorrelateDataset(
          o.train, config, locator, g.threads, !g.quiet, o.fit_strikes, &fit_labels);
      double fit_med_m = 0.0;
      scale = acoustics::FitSpeedScale(locator, fit, fit_labels.z_m, fit_labels.theta_rad, radius,
                                       kFitLo, kFitHi, g.threads, &fit_med_m);
      extra["fit_strikes"] = fit_labels.size();
      extra["fit_med_cm"] = 100.0 * fit_med_m;
    }
    const std::vector<acoustics::TdoaCorrelations> test =
        CorrelateDataset(o.data, config, locator, g.threads, !g.quiet, 0, &truth);
    predictions = LocateAll(locator, test, scale, g.threads);
    extra["speed_scale"] = scale;
    detail = fmt::format(" ({}, speed scale {:.3f})",
                         tdoa_config.dispersive ? "per-band group velocity" : "one speed", scale);
    if (scale != 1.0) {
      // the pure analytic figure beside the fitted one
      const learning::Metrics analytic =
          learning::ComputeMetrics(LocateAll(locator, test, 1.0, g.threads), truth, radius);
      extra["analytic"] = MetricsJson(analytic);
      detail += fmt::format("; analytic speeds: MED {:.2f} cm", analytic.med_cm);
    }
  }

  const learning::Metrics m = learning::ComputeMetrics(predictions, truth, radius);
  json j = MetricsJson(m);
  j["method"] = method;
  j.update(extra);
  return {j.dump(), fmt::format("{} baseline, {} strikes: MED {:.2f} cm, height {:.2f} cm, angle "
                                "{:.1f} deg (published-code MED {:.2f}){}\n",
                                method, m.n, m.med_cm, m.height_err_cm, m.angle_err_deg,
                                m.reference_med_cm, detail)};
}

void RegisterBaseline(CLI::App& app, GlobalOptions& g, Runner* run) {
  auto o = std::make_shared<BaselineOptions>();
  auto* baseline = app.add_subcommand("baseline",
                                      "a baseline's errors on a dataset: kNN on "
                                      "pooled log-mel, analytic TDOA, or a constant");
  AddEnumOption(baseline, "--method", &o->method, "knn | tdoa | arrival | constant")->required();
  baseline->add_option("--train", o->train,
                       "training dataset (.h5): knn and constant need it; tdoa fits its speed "
                       "scale on it");
  baseline->add_option("--data", o->data, "held-out dataset (.h5)")->required();
  baseline->add_option("--k", o->k, "knn: neighbours")->check(NumberIn(1, 1e6, false, true));
  baseline
      ->add_option("--gcc-lags", o->knn_gcc_lags,
                   "knn: GCC-PHAT lags each side of zero in the feature vector (0 = none)")
      ->check(NumberIn(0, 1e6, false, true));
  baseline
      ->add_option("--bands", o->bands_hz, "tdoa: band edges in Hz, e.g. 1000,2000,4000,8000,16000")
      ->delimiter(',');
  baseline->add_flag("--non-dispersive", o->non_dispersive, "tdoa: one speed for every band");
  baseline->add_flag("--no-fit", o->no_fit, "tdoa: analytic speeds only");
  baseline
      ->add_option("--fit-strikes", o->fit_strikes, "tdoa: training strikes used by the speed fit")
      ->check(NumberIn(1, 1e9, false, true));
  baseline->callback([&g, run, o] { *run = [&g, o] { return RunBaseline(g, *o); }; });
}

}  // namespace sonicboom::experiments
