#include "sonicboom/solid/reference_tube.h"

#include <algorithm>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <numbers>
#include <vector>

#include <fmt/format.h>
#include <fmt/ranges.h>
#include <spdlog/spdlog.h>

#include "sonicboom/core/errors.h"
#include "sonicboom/core/files.h"
#include "sonicboom/solid/solid_modes.h"

namespace sonicboom::solid {
namespace {

// bump when anything the solve computes changes
constexpr int kReferenceModelVersion = 1;
constexpr char kMagic[8] = {'S', 'B', 'R', 'E', 'F', 'M', '0', '1'};

uint64_t Fnv1a(const void* data, size_t bytes, uint64_t h = 1469598103934665603ull) {
  const auto* p = static_cast<const unsigned char*>(data);
  for (size_t i = 0; i < bytes; ++i) h = (h ^ p[i]) * 1099511628211ull;
  return h;
}

template <typename T>
void Put(std::string* out, const T& v) {
  out->append(reinterpret_cast<const char*>(&v), sizeof(T));
}
void PutDoubles(std::string* out, const double* v, size_t n) {
  out->append(reinterpret_cast<const char*>(v), n * sizeof(double));
}

// reads T from data at *pos; false past the end
template <typename T>
bool Get(const std::string& data, size_t* pos, T* v) {
  if (*pos + sizeof(T) > data.size()) return false;
  std::memcpy(v, data.data() + *pos, sizeof(T));
  *pos += sizeof(T);
  return true;
}
bool GetDoubles(const std::string& data, size_t* pos, double* v, size_t n) {
  if (n > (data.size() - *pos) / sizeof(double)) return false;
  std::memcpy(v, data.data() + *pos, n * sizeof(double));
  *pos += n * sizeof(double);
  return true;
}

}  // namespace

// Every field of these structs is in the key below, or deliberately left out (the tube's contact
// region, the material's loss factor: they change no mode). A struct that grows fails here, so
// that its new field is put into the key, or these sizes updated, on purpose (x86-64 sizes).
static_assert(sizeof(TubeConfig) == 48 && sizeof(MaterialConfig) == 32 &&
                  sizeof(MicArrayConfig) == 56 && sizeof(SolidStructure) == 160 &&
                  sizeof(SolidMeshConfig) == 40,
              "a config struct changed: update ReferenceCacheKey and these sizes");

std::string ReferenceCacheKey(const ReferenceTubeConfig& c) {
  const SolidStructure& s = c.structure;
  return fmt::format(
      "reference v{} tube {:.17g} {:.17g} {:.17g} material {:.17g} {:.17g} {:.17g} mesh {:.17g} "
      "{:.17g} {} {} {} ends {} seams {:.17g} bolts {:.17g} k {:.17g} patch {:.17g} holes {:.17g} "
      "/ {:.17g} d "
      "{:.17g} mounts {:.17g} {:.17g} mics {:.17g} / {:.17g} d {:.17g} band {:.17g}",
      kReferenceModelVersion, c.tube.outer_radius_m, c.tube.wall_thickness_m, c.tube.length_m,
      c.material.youngs_modulus_pa, c.material.poisson_ratio, c.material.density_kg_m3,
      c.mesh.element_arc_m, c.mesh.element_axial_m, c.mesh.degree_wall, c.mesh.degree_thickness,
      c.mesh.elements_through, static_cast<int>(s.ends), fmt::join(s.seam_theta_deg, ","),
      fmt::join(s.bolt_z_m, ","), fmt::join(s.bolt_stiffness_n_m, ","), s.bolt_patch_half_length_m,
      fmt::join(s.hole_z_m, ","), fmt::join(s.hole_theta_deg, ","), s.hole_diameter_m,
      s.flange_mount_stiffness_n_m2, s.tool_mount_stiffness_n_m2, fmt::join(c.mics.z_m, ","),
      fmt::join(c.mics.theta_deg, ","), c.mics.disc_diameter_m, c.max_frequency_hz);
}

ReferenceTube::ReferenceTube(const ReferenceTubeConfig& config) : config_(config) {
  model_ = std::make_unique<SolidTubeModel>(config_.tube, config_.material, config_.structure,
                                            config_.mesh);
  config_.mics.Validate(config_.tube);
  surface_dofs_ = model_->OuterSurfaceDofs();
  Solve();
}

ReferenceTube::~ReferenceTube() = default;

void ReferenceTube::Solve() {
  const std::string key = ReferenceCacheKey(config_);
  std::string path;
  if (!config_.cache_dir.empty()) {
    path = (std::filesystem::path(config_.cache_dir) /
            fmt::format("reference-{:016x}.bin", Fnv1a(key.data(), key.size())))
               .string();
  }
  // a cached file: magic, key, sizes, payload, and the payload's checksum last
  if (!path.empty() && std::filesystem::is_regular_file(path)) {
    std::string data;
    try {
      data = ReadText(path);
    } catch (const Error&) {
      data.clear();
    }
    size_t pos = 0;
    uint64_t key_size = 0, modes = 0, mics = 0, dofs = 0, sum = 0;
    const bool header =
        data.size() > sizeof(kMagic) + 8 && std::memcmp(data.data(), kMagic, sizeof(kMagic)) == 0;
    pos = sizeof(kMagic);
    bool ok = header && Get(data, &pos, &key_size) && key_size < data.size() &&
              data.compare(pos, key_size, key) == 0;
    if (ok) {
      pos += key_size;
      const size_t payload = pos;
      ok = Get(data, &pos, &modes) && Get(data, &pos, &mics) && Get(data, &pos, &dofs) &&
           mics == static_cast<uint64_t>(config_.mics.count()) && dofs == surface_dofs_.size() &&
           modes < (1u << 20);
      if (ok) {
        omega_rad_s_.resize(modes);
        disc_strain_.resize(mics, modes);
        surface_shapes_.resize(dofs, modes);
        ok = GetDoubles(data, &pos, omega_rad_s_.data(), modes) &&
             GetDoubles(data, &pos, disc_strain_.data(), mics * modes) &&
             GetDoubles(data, &pos, surface_shapes_.data(), dofs * modes);
        const size_t end = pos;
        ok = ok && Get(data, &pos, &sum) && pos == data.size() &&
             sum == Fnv1a(data.data() + payload, end - payload);
      }
    }
    if (ok) {
      from_cache_ = true;
      return;
    }
    spdlog::warn("reference modes: {} is damaged or from another build; solving again", path);
  }

  SolidModeRequest request;
  request.max_frequency_hz = config_.max_frequency_hz;
  request.shape_dofs = surface_dofs_;
  request.projection_rows = model_->SensorRows(config_.mics);
  const SolidModes modes = SolveSolidModes(*model_, request);
  omega_rad_s_ = modes.omega_rad_s;
  disc_strain_ = modes.projections;
  surface_shapes_ = modes.shapes;
  if (path.empty()) return;

  std::string out(kMagic, sizeof(kMagic));
  Put(&out, static_cast<uint64_t>(key.size()));
  out += key;
  const size_t payload = out.size();
  Put(&out, static_cast<uint64_t>(omega_rad_s_.size()));
  Put(&out, static_cast<uint64_t>(disc_strain_.rows()));
  Put(&out, static_cast<uint64_t>(surface_shapes_.rows()));
  PutDoubles(&out, omega_rad_s_.data(), omega_rad_s_.size());
  PutDoubles(&out, disc_strain_.data(), disc_strain_.size());
  PutDoubles(&out, surface_shapes_.data(), surface_shapes_.size());
  Put(&out, Fnv1a(out.data() + payload, out.size() - payload));
  try {
    MakeDirectories(config_.cache_dir);
    WriteTextAtomic(path, out);
  } catch (const Error& e) {
    spdlog::warn("reference modes: not cached ({})", e.what());
  }
}

Eigen::VectorXd ReferenceTube::ModalDrive(double z_m, double theta_rad) const {
  const Eigen::VectorXd weights = model_->RadialForceWeights(z_m, theta_rad);
  Eigen::VectorXd drive = Eigen::VectorXd::Zero(omega_rad_s_.size());
  for (size_t r = 0; r < surface_dofs_.size(); ++r) {
    const double w = weights(surface_dofs_[r]);
    if (w != 0.0) drive += w * surface_shapes_.row(r).transpose();
  }
  return drive;
}

}  // namespace sonicboom::solid
