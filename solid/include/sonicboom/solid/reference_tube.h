#pragma once
/// The reference solid ready to render strikes: its modes up to a band, each mode's disc outputs
/// and its shape on the outer surface, solved once and kept in an on-disk cache (checksummed; a
/// damaged or foreign file is recomputed with a warning naming it).

#include <Eigen/Core>
#include <memory>
#include <string>

#include "sonicboom/core/tube.h"
#include "sonicboom/solid/solid_tube.h"

namespace sonicboom::solid {

struct ReferenceTubeConfig {
  TubeConfig tube;
  MaterialConfig material;
  SolidStructure structure;
  SolidMeshConfig mesh;
  MicArrayConfig mics;
  double max_frequency_hz{20000.0};  // modes solved up to here
  std::string cache_dir;             // "" = no cache
};

class ReferenceTube {
 public:
  explicit ReferenceTube(const ReferenceTubeConfig& config);
  ~ReferenceTube();

  /// (modes) elastic modes, ascending, rad/s.
  const Eigen::VectorXd& omega_rad_s() const { return omega_rad_s_; }
  /// (mics x modes) each disc's strain per unit modal amplitude (mass-normalized shapes).
  const Eigen::MatrixXd& disc_strain() const { return disc_strain_; }
  /// (modes) the outward surface displacement of each mode at (z, theta), m per unit modal
  /// amplitude: the drive of an outward point force. Throws ConfigError off the tube.
  Eigen::VectorXd ModalDrive(double z_m, double theta_rad) const;
  /// Whether the modes came from the cache.
  bool from_cache() const { return from_cache_; }
  const ReferenceTubeConfig& config() const { return config_; }
  const SolidTubeModel& model() const { return *model_; }

 private:
  void Solve();
  ReferenceTubeConfig config_;
  std::unique_ptr<SolidTubeModel> model_;
  Eigen::VectorXd omega_rad_s_;
  Eigen::MatrixXd disc_strain_;
  std::vector<int64_t> surface_dofs_;  // ascending
  Eigen::MatrixXd surface_shapes_;     // (surface_dofs x modes)
  bool from_cache_{false};
};

/// The text every cached file is keyed by: every input of the solve, at full precision, and the
/// model's version.
std::string ReferenceCacheKey(const ReferenceTubeConfig& config);

}  // namespace sonicboom::solid
