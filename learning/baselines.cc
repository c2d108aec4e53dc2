#include "sonicboom/learning/baselines.h"

#include <fmt/format.h>
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/task_arena.h>
#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <numbers>
#include <numeric>
#include <utility>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/tube.h"

namespace sonicboom::learning {

void KnnConfig::Validate() const {
  auto fail = [](const char* key, const std::string& why) {
    throw ConfigError(fmt::format("knn.{} {}", key, why));
  };
  if (k < 1) fail("k", fmt::format("must be >= 1, got {}", k));
  if (crop_frames < 1) fail("crop_frames", fmt::format("must be >= 1, got {}", crop_frames));
  if (pooled_frames < 1 || pooled_frames > crop_frames) {
    fail("pooled_frames",
         fmt::format("must be in [1, crop_frames = {}], got {}", crop_frames, pooled_frames));
  }
  if (!(log_floor > 0.0)) fail("log_floor", fmt::format("must be > 0, got {}", log_floor));
  if (gcc_lags < 0) fail("gcc_lags", fmt::format("must be >= 0, got {}", gcc_lags));
  if (!(gcc_weight >= 0.0) || !std::isfinite(gcc_weight)) {
    fail("gcc_weight", fmt::format("must be finite and >= 0, got {}", gcc_weight));
  }
  if (threads < 0) fail("threads", fmt::format("must be >= 0, got {}", threads));
}

double CircularMean(const std::vector<double>& theta_rad, const std::vector<double>& weights,
                    double fallback) {
  if (theta_rad.size() != weights.size()) {
    throw SchemaError(
        fmt::format("CircularMean: {} angles with {} weights", theta_rad.size(), weights.size()));
  }
  double c = 0.0, s = 0.0, total = 0.0;
  for (size_t i = 0; i < theta_rad.size(); ++i) {
    c += weights[i] * std::cos(theta_rad[i]);
    s += weights[i] * std::sin(theta_rad[i]);
    total += std::abs(weights[i]);
  }
  // a resultant below 1e-9 of the total weight has no direction
  if (!(std::hypot(c, s) > 1e-9 * total)) return fallback;
  return WrapAngle(std::atan2(s, c));
}

Prediction ConstantPrediction(const std::vector<double>& z_m,
                              const std::vector<double>& theta_rad) {
  if (z_m.size() != theta_rad.size()) {
    throw SchemaError(
        fmt::format("constant baseline: {} heights for {} angles", z_m.size(), theta_rad.size()));
  }
  double z_sum = 0.0;
  std::vector<double> angles;
  for (size_t i = 0; i < z_m.size(); ++i) {
    if (std::isnan(z_m[i]) || std::isnan(theta_rad[i])) continue;
    z_sum += z_m[i];
    angles.push_back(theta_rad[i]);
  }
  if (angles.empty()) throw SchemaError("constant baseline: no labelled training rows");
  const std::vector<double> ones(angles.size(), 1.0);
  Prediction p;
  p.z_m = z_sum / static_cast<double>(angles.size());
  p.theta_rad = CircularMean(angles, ones, 0.0);
  return p;
}

// ---------------------------------------------------------------------------------------------
// KnnBaseline

namespace {

using RowMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// A test block's rows are matched against the whole training matrix at once.
constexpr int64_t kBlockRows = 64;
// A neighbour closer than this (standardized units, rows of norm ~1) is an exact match; the
// product form of the distance leaves ~1e-8 of round-off on an identical row.
constexpr double kExactDistance = 1e-6;

}  // namespace

struct KnnBaseline::Impl {
  KnnConfig config;
  FeatureSet shapes;  // shapes of the training set (no rows)
  int64_t crop_start{0};
  int64_t mel_dims{0};
  int64_t gcc_dims{0};
  Eigen::RowVectorXd mean;      // (D) training mean
  Eigen::RowVectorXd scale;     // (D) 1 / (std) times the block weight
  RowMatrix train;              // (N x D) standardized training rows
  Eigen::VectorXd train_norm2;  // (N) squared norms
  std::vector<double> z_m, theta_rad;

  // Checks that `f` can be embedded with this config.
  void CheckShapes(const FeatureSet& f, const char* what) const {
    const int64_t n = f.size();
    if (static_cast<int64_t>(f.theta_rad.size()) != n) {
      throw SchemaError(
          fmt::format("kNN {}: {} heights for {} angles", what, n, f.theta_rad.size()));
    }
    if (static_cast<int64_t>(f.mel.size()) != n * f.channels * f.mels * f.frames) {
      throw SchemaError(fmt::format("kNN {}: mel holds {} values, expected {} x {} x {} x {}", what,
                                    f.mel.size(), n, f.channels, f.mels, f.frames));
    }
    if (config.gcc_lags > 0 && static_cast<int64_t>(f.gcc.size()) != n * f.gcc_pairs * f.gcc_lags) {
      throw SchemaError(fmt::format("kNN {}: gcc holds {} values, expected {} x {} x {}", what,
                                    f.gcc.size(), n, f.gcc_pairs, f.gcc_lags));
    }
  }

  // Raw (unstandardized) feature vector of row r of `f` into out (D).
  void EmbedRow(const FeatureSet& f, int64_t r, double* out) const {
    const int64_t crop = config.crop_frames, pooled = config.pooled_frames;
    const float* mel = f.mel.data() + r * f.channels * f.mels * f.frames;
    int64_t d = 0;
    for (int64_t c = 0; c < f.channels; ++c) {
      for (int64_t b = 0; b < f.mels; ++b) {
        const float* row = mel + (c * f.mels + b) * f.frames + crop_start;
        for (int64_t t = 0; t < pooled; ++t) {
          // time bin t covers crop frames [t crop / pooled, (t + 1) crop / pooled)
          const int64_t lo = t * crop / pooled, hi = (t + 1) * crop / pooled;
          double sum = 0.0;
          for (int64_t i = lo; i < hi; ++i) {
            const double v = row[i];
            sum += config.mel_is_log ? v : std::log10(std::max(v, 0.0) + config.log_floor);
          }
          out[d++] = sum / static_cast<double>(hi - lo);
        }
      }
    }
    if (config.gcc_lags > 0) {
      const float* gcc = f.gcc.data() + r * f.gcc_pairs * f.gcc_lags;
      const int64_t centre = f.gcc_lags / 2;
      for (int64_t p = 0; p < f.gcc_pairs; ++p) {
        for (int64_t l = -config.gcc_lags; l <= config.gcc_lags; ++l) {
          out[d++] = gcc[p * f.gcc_lags + centre + l];
        }
      }
    }
  }

  // Raw feature vectors of the given rows (rows x D), in parallel.
  RowMatrix Embed(const FeatureSet& f, const std::vector<int64_t>& rows) const {
    RowMatrix x(static_cast<int64_t>(rows.size()), mel_dims + gcc_dims);
    tbb::parallel_for(int64_t{0}, static_cast<int64_t>(rows.size()),
                      [&](int64_t i) { EmbedRow(f, rows[i], x.row(i).data()); });
    return x;
  }

  int Threads() const { return config.threads > 0 ? config.threads : tbb::task_arena::automatic; }
};

KnnBaseline::KnnBaseline(const FeatureSet& train, const KnnConfig& config)
    : impl_(std::make_unique<Impl>()) {
  config.Validate();
  Impl& m = *impl_;
  m.config = config;
  m.shapes = train.ShapesOnly();
  m.CheckShapes(train, "training set");
  if (train.frames < config.crop_frames) {
    throw SchemaError(fmt::format("kNN: knn.crop_frames = {} exceeds the {} mel frames",
                                  config.crop_frames, train.frames));
  }
  if (config.gcc_lags > 0 && 2 * config.gcc_lags + 1 > train.gcc_lags) {
    throw SchemaError(fmt::format("kNN: knn.gcc_lags = {} exceeds the {} GCC lags each side",
                                  config.gcc_lags, train.gcc_lags / 2));
  }
  m.crop_start = CentreCropStart(train.frames, config.crop_frames);
  m.mel_dims = train.channels * train.mels * config.pooled_frames;
  m.gcc_dims = config.gcc_lags > 0 ? train.gcc_pairs * (2 * config.gcc_lags + 1) : 0;
  if (m.mel_dims + m.gcc_dims == 0) throw SchemaError("kNN: the feature vector is empty");

  // labelled rows only
  std::vector<int64_t> rows;
  for (int64_t r = 0; r < train.size(); ++r) {
    if (std::isnan(train.z_m[r]) || std::isnan(train.theta_rad[r])) continue;
    rows.push_back(r);
    m.z_m.push_back(train.z_m[r]);
    m.theta_rad.push_back(train.theta_rad[r]);
  }
  if (rows.empty()) throw SchemaError("kNN: the training set has no labelled rows");

  tbb::task_arena arena(m.Threads());
  arena.execute([&] { m.train = m.Embed(train, rows); });

  // per-dimension standardization; each block weighted so that it contributes its share
  // (mel 1, GCC gcc_weight) of the squared distance whatever its length
  const double n = static_cast<double>(rows.size());
  m.mean = m.train.colwise().mean();
  m.train.rowwise() -= m.mean;
  const Eigen::RowVectorXd stdev = (m.train.colwise().squaredNorm() / n).cwiseSqrt();
  m.scale.resize(m.mel_dims + m.gcc_dims);
  for (int64_t d = 0; d < m.scale.size(); ++d) {
    const double block = d < m.mel_dims
                             ? 1.0 / std::sqrt(static_cast<double>(m.mel_dims))
                             : std::sqrt(config.gcc_weight / static_cast<double>(m.gcc_dims));
    m.scale[d] = (stdev[d] > 1e-12 ? 1.0 / stdev[d] : 1.0) * block;
  }
  m.train.array().rowwise() *= m.scale.array();
  m.train_norm2 = m.train.rowwise().squaredNorm();
}

KnnBaseline::~KnnBaseline() = default;
KnnBaseline::KnnBaseline(KnnBaseline&&) noexcept = default;
KnnBaseline& KnnBaseline::operator=(KnnBaseline&&) noexcept = default;

int64_t KnnBaseline::dimensions() const {
  return impl_->mel_dims + impl_->gcc_dims;
}
int64_t KnnBaseline::size() const {
  return static_cast<int64_t>(impl_->z_m.size());
}

std::vector<Prediction> KnnBaseline::Predict(const FeatureSet& test) const {
  const Impl& m = *impl_;
  const FeatureSet& s = m.shapes;
  if (test.channels != s.channels || test.mels != s.mels || test.frames != s.frames ||
      (m.config.gcc_lags > 0 && (test.gcc_pairs != s.gcc_pairs || test.gcc_lags != s.gcc_lags))) {
    throw SchemaError(fmt::format(
        "kNN: test features ({} x {} x {} mel, {} x {} GCC) differ from the training set's "
        "({} x {} x {}, {} x {})",
        test.channels, test.mels, test.frames, test.gcc_pairs, test.gcc_lags, s.channels, s.mels,
        s.frames, s.gcc_pairs, s.gcc_lags));
  }
  m.CheckShapes(test, "test set");
  const int64_t n_test = test.size();
  const int64_t n_train = static_cast<int64_t>(m.z_m.size());
  const int64_t k = std::min<int64_t>(m.config.k, n_train);
  std::vector<Prediction> predictions(static_cast<size_t>(n_test));

  tbb::task_arena arena(m.Threads());
  arena.execute([&] {
    tbb::parallel_for(int64_t{0}, (n_test + kBlockRows - 1) / kBlockRows, [&](int64_t block) {
      // standardized test rows of this block
      const int64_t first = block * kBlockRows;
      const int64_t rows = std::min(kBlockRows, n_test - first);
      std::vector<int64_t> index(static_cast<size_t>(rows));
      std::iota(index.begin(), index.end(), first);
      RowMatrix x = m.Embed(test, index);
      x.rowwise() -= m.mean;
      x.array().rowwise() *= m.scale.array();

      // squared distances |x|^2 + |t|^2 - 2 x t^T, (rows x n_train)
      RowMatrix d2 = -2.0 * x * m.train.transpose();
      d2.colwise() += x.rowwise().squaredNorm();
      d2.rowwise() += m.train_norm2.transpose();

      std::vector<int64_t> order(static_cast<size_t>(n_train));
      for (int64_t i = 0; i < rows; ++i) {
        const double* row = d2.row(i).data();
        // k nearest, ties to the lower training row
        std::iota(order.begin(), order.end(), 0);
        std::partial_sort(
            order.begin(), order.begin() + k, order.end(),
            [row](int64_t a, int64_t b) { return row[a] < row[b] || (row[a] == row[b] && a < b); });
        std::vector<double> dist(static_cast<size_t>(k));
        for (int64_t j = 0; j < k; ++j) dist[j] = std::sqrt(std::max(row[order[j]], 0.0));
        // weights 1/d; exact matches (d ~ 0) take all the weight, equally
        std::vector<double> w(static_cast<size_t>(k), 1.0);
        if (m.config.distance_weighted) {
          if (dist[0] < kExactDistance) {
            for (int64_t j = 0; j < k; ++j) w[j] = dist[j] < kExactDistance ? 1.0 : 0.0;
          } else {
            for (int64_t j = 0; j < k; ++j) w[j] = 1.0 / dist[j];
          }
        }
        double z = 0.0, w_sum = 0.0;
        std::vector<double> theta(static_cast<size_t>(k));
        for (int64_t j = 0; j < k; ++j) {
          z += w[j] * m.z_m[order[j]];
          w_sum += w[j];
          theta[j] = m.theta_rad[order[j]];
        }
        predictions[first + i].z_m = z / w_sum;
        predictions[first + i].theta_rad = CircularMean(theta, w, theta[0]);
      }
    });
  });
  return predictions;
}

}  // namespace sonicboom::learning
