#include "sonicboom/core/constants.h"
#include "sonicboom/hardware/import.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>

#include <fmt/format.h>
#include <tbb/parallel_pipeline.h>
#include <tbb/task_arena.h>

#include "internal/import_common.h"
#include "sonicboom/core/audio_io.h"
#include "sonicboom/core/errors.h"
#include "sonicboom/core/tube.h"

namespace fs = std::filesystem;

namespace sonicboom::hardware {
namespace {

// A capture longer than the record is imported as its first record_frames: noted for a warning.
void NoteIfTrimmed(const std::string& file, const internal::LoadNotes& notes,
                   ImportReport* report) {
  if (notes.trimmed) report->trimmed.push_back({file, notes.captured_s});
}

constexpr double kJ7OffsetRad = 50.0 * kPi / 180.0;  // θ_tube = −θ_j7 − 50°
// An int16 converter's positive full scale as libsndfile reads it (32767 / 32768).
constexpr float kFullScale = 32767.0f / 32768.0f;

// Loads, checks and encodes one entry: the encoded sample, or the reason it is bad.
struct Loaded {
  std::optional<DatasetWriter::EncodedSample> sample;
  std::string reason;
  internal::LoadNotes notes;
};

Loaded LoadOne(const internal::ImportEntry& entry, const ImportSettings& settings,
               const DatasetWriter& writer) {
  Loaded out;
  try {
    StrikeSample s = entry.load(settings, &out.notes);
    s.index = entry.index;
    s.provenance = entry.file;
    out.sample = writer.Encode(s);
  } catch (const Error& e) {
    out.reason = e.what();
  }
  return out;
}

// A capture directory's no-contact clip (noise.wav), checked like a capture; empty when absent.
Eigen::MatrixXf ReadNoiseClip(const std::string& in_dir, const ImportSettings& settings,
                              ImportReport* report) {
  const fs::path noise = fs::path(in_dir) / "noise.wav";
  if (settings.layout != Layout::kCapture || !fs::exists(noise)) return {};
  internal::LoadNotes notes;
  Eigen::MatrixXf clip = internal::CheckedRecord(noise.string(), settings, &notes);
  NoteIfTrimmed(noise.string(), notes, report);
  return clip;
}

}  // namespace

double TubeAngleFrom(double stored_rad, AngleConvention convention) {
  return WrapAngle(convention == AngleConvention::kTube ? stored_rad : -stored_rad - kJ7OffsetRad);
}

double StoredAngleFrom(double tube_rad, AngleConvention convention) {
  return WrapAngle(convention == AngleConvention::kTube ? tube_rad : -tube_rad - kJ7OffsetRad);
}

namespace internal {

Eigen::MatrixXf CheckedRecord(const std::string& wav, const ImportSettings& settings,
                              LoadNotes* notes) {
  const AudioClip clip = ReadWav(wav);
  if (notes != nullptr) {
    notes->captured_s = static_cast<double>(clip.frames()) / clip.sample_rate_hz;
    notes->trimmed = clip.frames() > settings.record_frames;
  }
  if (std::abs(clip.sample_rate_hz - settings.sample_rate_hz) > 1e-6) {
    throw IoError(fmt::format("{}: sample rate {} Hz, the rig's is {} Hz (audio.sample_rate_hz)",
                              wav, clip.sample_rate_hz, settings.sample_rate_hz));
  }
  if (clip.channels() != settings.channels) {
    throw IoError(fmt::format("{}: {} channels, the rig has {} mics", wav, clip.channels(),
                              settings.channels));
  }
  const auto min_frames =
      static_cast<int64_t>(std::ceil(settings.min_duration_s * settings.sample_rate_hz));
  if (clip.frames() < min_frames) {
    throw IoError(fmt::format("{}: {:.3f} s long, shorter than {} s (--min-duration-s)", wav,
                              clip.frames() / clip.sample_rate_hz, settings.min_duration_s));
  }
  // finite, not clipped, not silent
  const Eigen::MatrixXf& x = clip.samples;
  for (int64_t t = 0; t < x.cols(); ++t) {
    for (int c = 0; c < x.rows(); ++c) {
      if (!std::isfinite(x(c, t))) {
        throw IoError(fmt::format("{}: sample {} of channel {} is not finite", wav, t, c));
      }
    }
  }
  const Eigen::Index clipped = (x.array().abs() >= kFullScale).count();
  if (clipped > 0) {
    Eigen::Index c = 0, t = 0;
    x.array().abs().maxCoeff(&c, &t);
    throw IoError(
        fmt::format("{}: clipped: {} samples at or beyond full scale (peak {:.4g} on "
                    "channel {} at {:.4f} s)",
                    wav, clipped, std::abs(x(c, t)), c, t / clip.sample_rate_hz));
  }
  for (int c = 0; c < x.rows(); ++c) {
    if (x.row(c).cwiseAbs().maxCoeff() == 0.0f) {
      throw IoError(fmt::format("{}: channel {} is silent (every sample is zero)", wav, c));
    }
  }
  // pad by repeating the last frame, or trim
  Eigen::MatrixXf record(settings.channels, settings.record_frames);
  const int64_t keep = std::min<int64_t>(x.cols(), settings.record_frames);
  record.leftCols(keep) = x.leftCols(keep);
  for (int64_t t = keep; t < settings.record_frames; ++t) record.col(t) = x.col(x.cols() - 1);
  // (full scale is symmetric: a record that passed the clipping check negates exactly)
  if (settings.invert_polarity) record = -record;
  return record;
}

void SetLabel(double z_m, double theta_rad, const ImportSettings& settings,
              const std::string& where, StrikeSample* sample) {
  if (!std::isfinite(z_m) || !std::isfinite(theta_rad)) {
    throw IoError(fmt::format("{}: label ({}, {}) is not finite", where, z_m, theta_rad));
  }
  if (std::abs(z_m) > settings.z_limit_m) {
    throw IoError(fmt::format("{}: label z = {} m is off the tube (|z| <= {} m)", where, z_m,
                              settings.z_limit_m));
  }
  if (std::abs(theta_rad) > kPi + 1e-6) {
    throw IoError(fmt::format("{}: label angle {} rad is outside [-pi, pi]", where, theta_rad));
  }
  // what a capture does not record is NaN, not known (docs/dataset.md); 0 read as a measurement
  constexpr double kUnknown = std::numeric_limits<double>::quiet_NaN();
  ContactLabel& l = sample->label;
  l.impulse_Ns = l.time_s = l.normal_speed_m_s = l.duration_s = kUnknown;
  l.z_m = z_m;
  l.theta_rad = WrapAngle(theta_rad);
  l.normal = SurfaceNormal(l.theta_rad);
  l.point_m = settings.outer_radius_m * l.normal + Eigen::Vector3d(0.0, 0.0, z_m);
  ContactEpisode episode;
  episode.z_m = l.z_m;
  episode.theta_rad = l.theta_rad;
  episode.point_m = l.point_m;
  episode.normal = l.normal;
  episode.kind = ContactEpisode::Kind::kImpact;
  episode.time_s = episode.duration_s = episode.normal_speed_m_s = kUnknown;
  episode.effective_mass_kg = episode.impulse_Ns = episode.peak_force_N = kUnknown;
  sample->contacts.assign(1, episode);
}

Eigen::MatrixXf HeldProprio(int64_t rows) {
  Eigen::MatrixXf p = Eigen::MatrixXf::Zero(rows, kProprioFeatures);
  p.col(3).setOnes();  // quaternion w
  return p;
}

}  // namespace internal

ImportReport ImportCaptures(const std::string& in_dir, const std::string& out_path,
                            const ImportSettings& settings, DatasetInfo info) {
  if (!fs::is_directory(in_dir)) throw IoError(fmt::format("{}: no such directory", in_dir));
  const std::vector<internal::ImportEntry> entries = settings.layout == Layout::kTrial
                                                         ? internal::ListTrials(in_dir)
                                                         : internal::ListCaptures(in_dir);
  if (entries.empty()) throw IoError(fmt::format("{}: no captures to import", in_dir));
  info.source = "hardware";
  info.sample_rate_hz = settings.sample_rate_hz;
  info.channels = settings.channels;
  info.audio_frames = settings.record_frames;
  info.proprio_rows = settings.proprio_rows;
  info.audio_int16 = true;

  // Load and encode in parallel, append in input order; bad captures are collected.
  ImportReport report;
  const Eigen::MatrixXf noise = ReadNoiseClip(in_dir, settings, &report);
  auto writer = std::make_unique<DatasetWriter>(out_path, info);
  size_t next = 0;
  tbb::task_arena arena(settings.threads > 0 ? settings.threads : tbb::task_arena::automatic);
  arena.execute([&] {
    tbb::parallel_pipeline(static_cast<size_t>(2 * arena.max_concurrency()),
                           tbb::make_filter<void, size_t>(tbb::filter_mode::serial_in_order,
                                                          [&](tbb::flow_control& fc) -> size_t {
                                                            if (next == entries.size()) fc.stop();
                                                            return next++;
                                                          }) &
                               tbb::make_filter<size_t, std::shared_ptr<std::pair<size_t, Loaded>>>(
                                   tbb::filter_mode::parallel,
                                   [&](size_t i) {
                                     return std::make_shared<std::pair<size_t, Loaded>>(
                                         i, LoadOne(entries[i], settings, *writer));
                                   }) &
                               tbb::make_filter<std::shared_ptr<std::pair<size_t, Loaded>>, void>(
                                   tbb::filter_mode::serial_in_order, [&](const auto& item) {
                                     const auto& [i, loaded] = *item;
                                     if (!loaded.sample) {
                                       report.bad.push_back({entries[i].file, loaded.reason});
                                     } else if (report.bad.empty() || settings.skip_bad) {
                                       writer->AppendEncoded(*loaded.sample);
                                       ++report.imported;
                                       NoteIfTrimmed(entries[i].file, loaded.notes, &report);
                                     }
                                   }));
  });

  // All or nothing without --skip-bad; nothing at all is an error either way.
  const std::string partial = out_path + ".partial";
  auto discard = [&] {
    writer.reset();
    std::error_code ignored;
    fs::remove(partial, ignored);
  };
  if (!report.bad.empty() && !settings.skip_bad) {
    discard();
    std::string list;
    for (const BadCapture& b : report.bad) list += "\n  " + b.reason;
    throw IoError(
        fmt::format("{}: {} of {} captures are bad, nothing written (--skip-bad "
                    "imports the rest):{}",
                    in_dir, report.bad.size(), entries.size(), list));
  }
  if (report.imported == 0) {
    discard();
    throw IoError(fmt::format("{}: every capture is bad, nothing written", in_dir));
  }
  if (noise.size() > 0) {
    AudioClip clip;
    clip.samples = noise;
    clip.sample_rate_hz = settings.sample_rate_hz;
    report.noise_wav = out_path + ".noise.wav";
    WriteWav(report.noise_wav, clip, /*pcm16=*/true);
  }
  writer->Finish();
  return report;
}

}  // namespace sonicboom::hardware
