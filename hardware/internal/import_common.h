#pragma once
/// Pieces shared by the trial and capture layouts: checked audio records, labels, poses.

#include <Eigen/Core>
#include <functional>
#include <filesystem>
#include <string>
#include <vector>

#include "sonicboom/core/sample.h"
#include "sonicboom/hardware/import.h"

namespace sonicboom::hardware::internal {

/// What loading one capture noticed besides its sample: the recording's length, and whether it
/// was longer than the record (and trimmed to it).
struct LoadNotes {
  double captured_s{0.0};
  bool trimmed{false};
};

/// One capture to import: `file` names it in reports; `load` reads it into a sample (its
/// index set by the caller) or throws IoError with the reason it is bad.
struct ImportEntry {
  std::string file;
  uint64_t index{0};
  std::function<StrikeSample(const ImportSettings&, LoadNotes*)> load;
};

/// The entries of a published trial directory (trial{N}, by N) and of a capture directory
/// (labels.csv rows, in order). Throw IoError for a missing directory or malformed labels.csv.
std::vector<ImportEntry> ListTrials(const std::string& dir);
std::vector<ImportEntry> ListCaptures(const std::string& dir);

/// `dir / name` when it is a file inside `dir`: IoError naming `where` and `column` for an empty,
/// absolute or '..' name, or one whose links lead out of `dir` (a capture may come from anyone).
std::filesystem::path InsideCapture(const std::filesystem::path& dir, const std::string& name,
                                    const std::string& where, const char* column);

/// A multichannel WAV checked against the rig (rate, channels, length, finite, not clipped) and
/// padded (last frame repeated) or trimmed to the record length: (channels x record_frames).
/// `notes` (optional) gets the recording's length. Throws IoError with the reason.
Eigen::MatrixXf CheckedRecord(const std::string& wav, const ImportSettings& settings,
                              LoadNotes* notes = nullptr);

/// Fills the label and one impact contact episode from (z, θ_tube); IoError when z is off the
/// tube or either value is not finite. What a capture does not record (contact time, impulse,
/// approach speed, duration, striker mass, peak force) is NaN: not known (docs/dataset.md).
void SetLabel(double z_m, double theta_rad, const ImportSettings& settings,
              const std::string& where, StrikeSample* sample);

/// `rows` copies of the identity pose at rest: position 0, quaternion (1, 0, 0, 0), velocity 0.
Eigen::MatrixXf HeldProprio(int64_t rows);

}  // namespace sonicboom::hardware::internal
