#include "sonicboom/hardware/trigger.h"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"

namespace sonicboom::hardware {

void TriggerConfig::Validate() const {
  auto positive = [](double v, const char* key) {
    if (!(v > 0.0) || !std::isfinite(v))
      throw ConfigError(fmt::format("trigger {} = {} must be positive", key, v));
  };
  positive(sample_rate_hz, "sample_rate_hz");
  positive(channels, "channels");
  positive(static_cast<double>(record_frames), "record_frames");
  positive(static_cast<double>(frame), "frame");
  positive(floor_time_s, "floor_time_s");
  if (pre_trigger_frames < 0 || pre_trigger_frames + frame > record_frames) {
    throw ConfigError(
        fmt::format("trigger pre_trigger_frames = {} must lie in [0, record_frames - "
                    "frame] = [0, {}] (audio.onset_time_s against "
                    "audio.record_duration_s)",
                    pre_trigger_frames, record_frames - frame));
  }
  if (!std::isfinite(threshold_db) || !(min_rms >= 0.0)) {
    throw ConfigError(
        fmt::format("trigger threshold_db = {} and min_rms = {} must be finite, "
                    "min_rms >= 0",
                    threshold_db, min_rms));
  }
}

OnsetTrigger::OnsetTrigger(const TriggerConfig& config) : config_(config) {
  config_.Validate();
  buffer_.resize(config_.channels, 0);
}

void OnsetTrigger::Push(const Eigen::MatrixXf& block, std::vector<TriggeredRecord>* out) {
  if (block.rows() != config_.channels) {
    throw IoError(fmt::format("trigger: a block of {} channels, expected {}", block.rows(),
                              config_.channels));
  }
  const auto now = std::chrono::steady_clock::now();
  const int64_t old = buffer_.cols();
  buffer_.conservativeResize(Eigen::NoChange, old + block.cols());
  buffer_.rightCols(block.cols()) = block;
  // find onsets and emit the records that are complete, then forget what no record needs
  for (;;) {
    Scan(now);
    if (onset_ < 0 || frames_seen() < onset_ - config_.pre_trigger_frames + config_.record_frames)
      break;
    Emit(out, /*pad=*/false);
  }
  Trim();
}

void OnsetTrigger::Flush(std::vector<TriggeredRecord>* out) {
  if (onset_ >= 0 && buffer_.cols() > 0) Emit(out, /*pad=*/true);
}

void OnsetTrigger::Scan(std::chrono::steady_clock::time_point now) {
  const double alpha =
      std::min(1.0, config_.frame / (config_.floor_time_s * config_.sample_rate_hz));
  const double factor = std::pow(10.0, config_.threshold_db / 10.0);
  const double min_ms = config_.min_rms * config_.min_rms;
  while (onset_ < 0 && scanned_ + config_.frame <= frames_seen()) {
    // mean square of one energy frame over every channel
    const auto frame = buffer_.middleCols(scanned_ - buffer_start_, config_.frame);
    const double ms = frame.cast<double>().squaredNorm() / double(frame.size());
    if (floor_ms_ < 0.0) floor_ms_ = ms;
    if (scanned_ >= quiet_until_ && ms > factor * floor_ms_ && ms > min_ms) {
      onset_ = scanned_;
      onset_seen_ = now;
    } else {
      floor_ms_ += alpha * (ms - floor_ms_);
    }
    scanned_ += config_.frame;
  }
}

void OnsetTrigger::Emit(std::vector<TriggeredRecord>* out, bool pad) {
  TriggeredRecord record;
  record.onset_frame = onset_;
  record.onset_seen = onset_seen_;
  record.audio.resize(config_.channels, config_.record_frames);
  const int64_t start = onset_ - config_.pre_trigger_frames;
  const int64_t last = buffer_.cols() - 1;
  for (int64_t t = 0; t < config_.record_frames; ++t) {
    const int64_t column = std::clamp<int64_t>(start + t - buffer_start_, 0, last);
    record.audio.col(t) = buffer_.col(column);
  }
  SONICBOOM_DEMAND(pad || start + config_.record_frames <= frames_seen());
  out->push_back(std::move(record));
  // the record's own frames never start another one, nor move the noise floor
  quiet_until_ = start + config_.record_frames;
  scanned_ = std::max(scanned_, quiet_until_);
  onset_ = -1;
}

void OnsetTrigger::Trim() {
  // keep the pre-trigger history before the next frame to scan (or the record being filled)
  const int64_t keep_from =
      (onset_ >= 0 ? onset_ : std::min(scanned_, frames_seen())) - config_.pre_trigger_frames;
  const int64_t drop = keep_from - buffer_start_;
  if (drop <= config_.record_frames) return;  // shift rarely: each shift copies the buffer
  const int64_t keep = buffer_.cols() - drop;
  buffer_.leftCols(keep) = buffer_.rightCols(keep).eval();
  buffer_.conservativeResize(Eigen::NoChange, keep);
  buffer_start_ += drop;
}

}  // namespace sonicboom::hardware
