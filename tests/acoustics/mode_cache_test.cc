// Where the mode cache lives when no directory is configured (acoustics/mode_cache.cc).
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "common/test_util.h"
#include "sonicboom/acoustics/shell_modes.h"
#include "sonicboom/acoustics/shell_ritz.h"

namespace sonicboom::acoustics {
namespace {

using ::testing::HasSubstr;

TEST(ModeCacheDirTest, TheVariableThenXdgThenHome) {
  EXPECT_EQ(ChooseModeCacheDir({"/c", "/x", "/h", "/p"}).dir, "/c");
  EXPECT_EQ(ChooseModeCacheDir({"", "/x", "/h", ""}).dir, "/x/sonicboom/modes");
  // XDG_CACHE_HOME counts only as an absolute path (the XDG base directory rule)
  EXPECT_EQ(ChooseModeCacheDir({"", "rel", "/h", ""}).dir, "/h/.cache/sonicboom/modes");
  for (const ModeCacheEnvironment& e : std::vector<ModeCacheEnvironment>{
           {"/c", "", "", ""}, {"", "/x", "", ""}, {"", "", "/h", ""}}) {
    EXPECT_EQ(ChooseModeCacheDir(e).warning, "") << e.cache_dir << e.xdg_cache_home << e.home;
  }
}

// With HOME unset the cache was off without a word (a 223 s solve on every run): the passwd
// home takes its place, or the run says the cache is off; both name HOME and how to set one.
TEST(ModeCacheDirTest, WithHomeUnsetThePasswdHomeOrAWarningThatTheCacheIsOff) {
  const ModeCacheChoice fallback = ChooseModeCacheDir({"", "", "", "/home/u"});
  EXPECT_EQ(fallback.dir, "/home/u/.cache/sonicboom/modes");
  const ModeCacheChoice off = ChooseModeCacheDir({"", "rel", "", ""});
  EXPECT_EQ(off.dir, "");
  for (const ModeCacheChoice& c : {fallback, off}) {
    EXPECT_THAT(c.warning, HasSubstr("HOME is unset"));
    EXPECT_THAT(c.warning, HasSubstr("SONICBOOM_CACHE_DIR"));
    EXPECT_THAT(c.warning, HasSubstr("acoustics.mode_cache_dir"));
  }
  EXPECT_THAT(fallback.warning, HasSubstr(fallback.dir));
  EXPECT_THAT(off.warning, HasSubstr("the mode cache is off"));
  EXPECT_THAT(off.warning, HasSubstr("solves its modes again"));
}

// Every pool reads the base's modes first and then writes its variants: by modification time
// alone the base (about 400 MB, 86 s to solve on the default grid) was the first entry a 1 GB
// budget removed in `reproduce --size smoke`, and solved again by the next stage.
TEST(ModeCacheBudgetTest, AVariantsUseIsItsBasesUseSoTheBudgetPrunesVariantsFirst) {
  namespace fs = std::filesystem;
  const testing::TempDir dir;
  const std::string cache = dir.path().string();
  ShellConfig coarse;
  coarse.grid_spacing_m = 0.01;
  coarse.axial_spacing_m = 0.01;
  const TubeConfig tube;
  const MaterialConfig material;
  const ShellModel base(tube, material, coarse);
  const ShellModes base_modes = CachedShellModes(base, 3000.0, 0, true, cache);
  const std::string base_path = ShellModesCachePath(base, 3000.0, 0, true, cache);
  ASSERT_TRUE(fs::is_regular_file(base_path));
  const ShellRitzProjector projector(base, base_modes);
  const auto get = [&projector]() -> const ShellRitzProjector& { return projector; };
  const std::vector<int64_t> rows = {0, 7, 100, 2001};
  // a variant read or written marks its base used
  const auto old = fs::file_time_type::clock::now() - std::chrono::hours(1);
  std::vector<std::unique_ptr<ShellModel>> variants;
  for (double k : {2.0, 3.0, 4.0}) {
    ShellConfig s = coarse;
    s.bolt_stiffness_n_m *= k;
    variants.push_back(std::make_unique<ShellModel>(tube, material, s));
  }
  fs::last_write_time(base_path, old);
  CachedRitzModes(get, base, *variants[0], 3000.0, rows, cache);
  EXPECT_GT(fs::last_write_time(base_path), old + std::chrono::minutes(59));
  fs::last_write_time(base_path, old);
  bool hit = false;
  CachedRitzModes(get, base, *variants[0], 3000.0, rows, cache, &hit);
  EXPECT_TRUE(hit);
  EXPECT_GT(fs::last_write_time(base_path), old + std::chrono::minutes(59));
  // a budget of the base and one and a half variants keeps the base and the newest variant
  uint64_t variant_bytes = 0;
  for (const auto& e : fs::directory_iterator(dir.path())) {
    if (e.path().filename().string().rfind("ritz-", 0) == 0) variant_bytes = e.file_size();
  }
  const std::string budget = std::to_string(fs::file_size(base_path) + variant_bytes * 3 / 2);
  ::setenv("SONICBOOM_CACHE_MAX_BYTES", budget.c_str(), 1);
  for (size_t v = 1; v < variants.size(); ++v)
    CachedRitzModes(get, base, *variants[v], 3000.0, rows, cache);
  ::unsetenv("SONICBOOM_CACHE_MAX_BYTES");
  int entries = 0;
  for (const auto& e : fs::directory_iterator(dir.path())) ++entries, (void)e;
  EXPECT_EQ(entries, 2);
  EXPECT_TRUE(fs::is_regular_file(base_path));
  CachedRitzModes(get, base, *variants.back(), 3000.0, rows, cache, &hit);
  EXPECT_TRUE(hit);
}

}  // namespace
}  // namespace sonicboom::acoustics
