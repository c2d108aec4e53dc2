#pragma once
/// Recorded strikes into datasets and datasets out to the published trial layout
/// (docs/captures.md). An import writes the same HDF5 schema as `generate`, with source
/// "hardware" and each sample's origin in /index/provenance, so every command that reads a
/// dataset reads an import unchanged.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <array>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "sonicboom/core/archive.h"
#include "sonicboom/core/dataset.h"
#include "sonicboom/hardware/geometry.h"

namespace sonicboom::hardware {

/// Directory layouts: `trial` is the published code's (trial{N}/mic2.wav, gt_label.npy, x_t.npy,
/// xdot_t.npy, optional q_t.npy); `capture` is ours (WAVs, labels.csv, optional robot logs and
/// noise.wav, capture.yaml).
enum class Layout { kTrial, kCapture };
inline constexpr EnumName<Layout> kLayoutNames[] = {{Layout::kTrial, "trial"},
                                                    {Layout::kCapture, "capture"}};
inline std::span<const EnumName<Layout>> EnumNames(Layout) {
  return kLayoutNames;
}
/// Angle of a trial's gt_label: `tube` is docs/conventions.md's θ; `j7` is the published joint-7
/// angle θ_j7 with θ_tube = −θ_j7 − 50°.
enum class AngleConvention { kTube, kJ7 };
inline constexpr EnumName<AngleConvention> kAngleConventionNames[] = {
    {AngleConvention::kTube, "tube"}, {AngleConvention::kJ7, "j7"}};
inline std::span<const EnumName<AngleConvention>> EnumNames(AngleConvention) {
  return kAngleConventionNames;
}

/// θ_tube from a stored angle and back (wrapped to (−π, π]).
double TubeAngleFrom(double stored_rad, AngleConvention convention);
double StoredAngleFrom(double tube_rad, AngleConvention convention);

/// What an import needs to know about the rig (from the resolved config).
/// Tube pose (base frame) for the seven joint angles (rad) of the arm.
using TubePoseFromJoints = std::function<Eigen::Isometry3d(const std::array<double, 7>&)>;

/// The tube poses of every row of a joint log (.npy, rows x 7, rad), as `import --object` places
/// the tube to label a trial from geometry. IoError naming the file for a bad file or shape.
std::vector<Eigen::Isometry3d> TubePosesFromJointLog(const std::string& path,
                                                     const TubePoseFromJoints& tube_pose);

struct ImportSettings {
  Layout layout{Layout::kTrial};
  AngleConvention angle{AngleConvention::kTube};
  double sample_rate_hz{44100.0};
  int channels{6};
  int64_t record_frames{88200};    // every record padded (last value repeated) or trimmed to this
  double min_duration_s{1.5};      // shorter captures are bad
  int64_t proprio_rows{50};        // rows kept from a pose log (at least this many needed)
  double outer_radius_m{0.05355};  // label point on the surface
  double z_limit_m{0.1524};        // |z| beyond this (half the tube length) is not on the tube
  bool skip_bad{false};            // import the good captures when some are bad
  // every channel negated: discs poled or wired the other way from docs/conventions.md ("Signs")
  bool invert_polarity{false};
  int threads{1};  // reading and compression workers (0: all cores)
  /// Tube pose (base frame) for a joint vector, used when x_t.npy has no orientation
  /// (3 columns) and q_t.npy is present; unset: such trials are bad.
  TubePoseFromJoints tube_pose_from_joints;
  /// Labels from geometry (trial layout): when set, each trial's label is where the tube, placed
  /// by forward kinematics of every row of its q_t.npy, first meets this object; gt_label.npy is
  /// not read, and a trial without q_t.npy or without a contact is bad.
  std::shared_ptr<const ContactLabeler> labeler;
};

/// One capture that could not be imported, and why.
struct BadCapture {
  std::string file;
  std::string reason;
};

/// A capture longer than the record, imported as its first record_frames: its file and length.
struct TrimmedCapture {
  std::string file;
  double captured_s{0.0};
};

struct ImportReport {
  int64_t imported{0};
  std::vector<BadCapture> bad;          // listed in input order
  std::vector<TrimmedCapture> trimmed;  // imported captures longer than the record, in order
  std::string noise_wav;                // the copied no-contact clip, "" when the layout had none
};

/// Imports `in_dir` into `out_path` with `info` as the file's metadata (config_yaml, rates; its
/// source is set to "hardware"). Without skip_bad, any bad capture fails the whole import
/// (IoError listing every bad file and its reason) and nothing is written; with it, the rest are
/// imported and the bad ones reported. A capture layout's noise.wav is checked and copied to
/// "<out_path>.noise.wav". Throws IoError / ConfigError for a missing or malformed directory.
ImportReport ImportCaptures(const std::string& in_dir, const std::string& out_path,
                            const ImportSettings& settings, DatasetInfo info);

/// Writes every valid sample of `dataset_path` in the published trial layout under `out_dir`
/// (trial0 ... trial{M-1} in sample-index order; mic2.wav 16-bit PCM; gt_label.npy [z_m, angle];
/// x_t.npy (K, 7) position + quaternion x y z w; xdot_t.npy (K, 3)). The directory is built as
/// "<out_dir>.partial" and renamed when whole. Returns the number of trials written. A valid
/// sample whose label is not known (NaN z or angle) is refused before anything is written
/// (SchemaError naming the file, the row and the column): gt_label.npy holds two finite numbers.
int64_t ExportTrials(const std::string& dataset_path, const std::string& out_dir,
                     AngleConvention angle);

}  // namespace sonicboom::hardware
