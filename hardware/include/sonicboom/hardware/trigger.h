#pragma once
/// An energy-onset trigger: cuts records of a fixed length around each strike in a continuous
/// multichannel stream, so live captures look like dataset records (docs/captures.md).

#include <Eigen/Core>
#include <chrono>
#include <cstdint>
#include <vector>

namespace sonicboom::hardware {

struct TriggerConfig {
  double sample_rate_hz{44100.0};
  int channels{6};
  int64_t record_frames{88200};       // emitted record length (audio.record_duration_s)
  int64_t pre_trigger_frames{22050};  // frames before the onset (audio.onset_time_s)
  int64_t frame{64};                  // energy frame (1.45 ms at 44.1 kHz)
  double threshold_db{20.0};          // an onset: frame energy this far above the noise floor
  double min_rms{1e-4};               // ... and above this RMS (full scale 1)
  double floor_time_s{0.5};           // time constant of the noise floor (quiet frames only)
  /// Throws ConfigError naming the field for non-positive sizes or rates, or a pre-trigger that
  /// does not fit in the record.
  void Validate() const;
};

/// One triggered record.
struct TriggeredRecord {
  Eigen::MatrixXf audio;   // (channels x record_frames)
  int64_t onset_frame{0};  // stream frame of the onset (from the first frame pushed)
  std::chrono::steady_clock::time_point onset_seen;  // when the onset's block arrived
};

/// Push blocks in stream order; complete records come out. The noise floor starts from the
/// first frames and follows quiet frames only; after an onset no new one is taken until its
/// record has ended. Frames before the first pushed one (an onset earlier than the pre-trigger
/// allows) are filled with the first frame.
class OnsetTrigger {
 public:
  explicit OnsetTrigger(const TriggerConfig& config);
  /// Appends `block` (channels x n) and adds each record that became complete to `out`.
  void Push(const Eigen::MatrixXf& block, std::vector<TriggeredRecord>* out);
  /// End of stream: a record still being filled is completed with its last frame.
  void Flush(std::vector<TriggeredRecord>* out);
  int64_t frames_seen() const { return buffer_start_ + buffer_.cols(); }

 private:
  void Scan(std::chrono::steady_clock::time_point now);
  void Emit(std::vector<TriggeredRecord>* out, bool pad);
  void Trim();

  TriggerConfig config_;
  Eigen::MatrixXf buffer_;   // (channels x n) the recent stream
  int64_t buffer_start_{0};  // stream frame of buffer_ column 0
  int64_t scanned_{0};       // stream frame up to which energy frames were scanned
  double floor_ms_{-1.0};    // noise floor (mean square); < 0: not yet set
  int64_t onset_{-1};        // onset of the record being filled; -1: none
  int64_t quiet_until_{0};   // no onset before this stream frame
  std::chrono::steady_clock::time_point onset_seen_;
};

}  // namespace sonicboom::hardware
