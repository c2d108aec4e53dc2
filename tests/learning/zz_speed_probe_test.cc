#include <chrono>
#include <cstdio>
#include <filesystem>
#include <gtest/gtest.h>
#include "sonicboom/core/rng.h"
#include "sonicboom/learning/learning.h"
namespace sonicboom::learning {
TEST(SpeedProbe, Compact) {
  FeatureSet f;
  const int64_t n = 256;
  Rng rng(1);
  f.mel.resize(n * 6 * 50 * 517);
  for (auto& v : f.mel) v = rng.Uniform();
  f.gcc.resize(n * 15 * 883);
  for (auto& v : f.gcc) v = rng.Uniform();
  f.proprio.resize(n * 50 * 10);
  for (auto& v : f.proprio) v = rng.Uniform();
  for (int64_t i = 0; i < n; ++i) { f.z_m.push_back(rng.Uniform(-0.1, 0.1)); f.theta_rad.push_back(rng.Uniform(-3, 3)); }
  FeatureSet val = f;
  val.mel.resize(8 * 6 * 50 * 517); val.gcc.resize(8 * 15 * 883); val.proprio.resize(8 * 500);
  val.z_m.resize(8); val.theta_rad.resize(8);
  ModelConfig m;
  for (const char* enc : {"compact", "resnet18"}) {
  m.audio_encoder = enc;
  TrainConfig t;
  t.epochs = 2;
  t.batch_size = 32;
  const std::string dir = "/tmp/sonicboom_speed_probe";
  std::filesystem::remove_all(dir);
  auto start = std::chrono::steady_clock::now();
  Train(f, val, m, t, 0.05, 1, dir, false, true);
  double s = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  std::printf("%s: %.1f samples/s (%.1f s for %lld samples)\n", enc, 2.0 * n / s, s, (long long)(2 * n));
  auto st = std::chrono::steady_clock::now();
  Localizer loc(dir);
  auto p = loc.Predict(f);
  double ps = std::chrono::duration<double>(std::chrono::steady_clock::now() - st).count();
  std::printf("%s predict: %.1f samples/s\n", enc, n / ps);
  std::filesystem::remove_all(dir);
  }
}
}
