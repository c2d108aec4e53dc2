// The mode cache's directory: entries that are not regular files, the budget and its
// least-recently-used pruning (sonicboom/core/cache_dir.h, cache_file.h).
#include "sonicboom/core/cache_dir.h"
#include "sonicboom/core/cache_use.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "common/test_util.h"
#include "sonicboom/core/cache_file.h"
#include "sonicboom/core/errors.h"

namespace sonicboom {
namespace {

namespace fs = std::filesystem;
using ::testing::ElementsAre;
using ::testing::HasSubstr;

constexpr char kMagic[8] = {'S', 'B', 'T', 'E', 'S', 'T', '0', '1'};

// SONICBOOM_CACHE_MAX_BYTES for one scope ("" = unset), restored after
class BudgetVariable {
 public:
  explicit BudgetVariable(const std::string& value) {
    if (const char* old = std::getenv(internal::kCacheBudgetVariable)) old_ = old;
    Set(value);
  }
  ~BudgetVariable() { Set(old_); }
  void Set(const std::string& value) {
    if (value.empty())
      ::unsetenv(internal::kCacheBudgetVariable);
    else
      ::setenv(internal::kCacheBudgetVariable, value.c_str(), 1);
  }

 private:
  std::string old_;
};

// an entry's path in `dir` for hash digit `n`
std::string EntryPath(const testing::TempDir& dir, char n, const char* kind = "ritz") {
  return dir / (std::string(kind) + "-" + std::string(15, '0') + n + ".bin");
}

// writes a cache file of `doubles` values keyed by its path, last used `age_s` seconds ago
void WriteEntry(const testing::TempDir& dir, const std::string& path, size_t doubles, int age_s) {
  const std::vector<double> values(doubles, 1.0);
  internal::WriteCacheFile(dir.path().string(), path, kMagic, path, {int64_t(doubles)},
                           {{values.data(), values.size() * sizeof(double)}});
  fs::last_write_time(path, fs::file_time_type::clock::now() - std::chrono::seconds(age_s));
}

std::vector<std::string> Names(const std::vector<internal::CacheEntry>& entries) {
  std::vector<std::string> names;
  for (const internal::CacheEntry& e : entries) names.push_back(e.name);
  return names;
}

std::string Name(const std::string& path) {
  return fs::path(path).filename().string();
}

// Opens `path` as a cache file on another thread and reports whether the open ever reached a
// FIFO's reading end: a writer opened without blocking (O_NONBLOCK) succeeds only then, and lets
// the blocked open go on (it then reads nothing), so the test fails instead of hanging.
bool OpenReachedTheFifo(const std::string& path, bool* opened) {
  std::atomic<bool> done{false}, reached{false};
  std::thread poke([&] {
    while (!done) {
      // (once replaced by a regular file, which opens for writing anyway, it is not the FIFO)
      const int fd = ::open(path.c_str(), O_WRONLY | O_NONBLOCK);
      struct stat st {};
      if (fd >= 0 && ::fstat(fd, &st) == 0 && S_ISFIFO(st.st_mode)) reached = true;
      if (fd >= 0) ::close(fd);
      std::this_thread::sleep_for(std::chrono::milliseconds(5));
    }
  });
  internal::CacheFileReader reader;
  int64_t header = 0;
  *opened = reader.Open(path, kMagic, path, &header, 1);
  done = true;
  poke.join();
  return reached;
}

// A FIFO at a cache entry's name blocked every reader forever (rerender of the reference solid):
// it is never opened for reading, a warning names it, and the next write replaces it.
TEST(CacheReaderTest, AFifoAtAnEntryIsNamedAndReplacedNeverOpenedForReading) {
  const testing::TempDir dir;
  const std::string path = EntryPath(dir, '1', "reference");
  ASSERT_EQ(::mkfifo(path.c_str(), 0600), 0);
  ::testing::internal::CaptureStderr();
  ::testing::internal::CaptureStdout();
  bool opened = true;
  const bool reached = OpenReachedTheFifo(path, &opened);
  const std::string log =
      ::testing::internal::GetCapturedStdout() + ::testing::internal::GetCapturedStderr();
  EXPECT_FALSE(reached) << "the reader opened the FIFO (it blocks until a writer comes)";
  EXPECT_FALSE(opened);
  EXPECT_THAT(log, HasSubstr(path));
  EXPECT_THAT(log, HasSubstr("a FIFO, not a regular file"));
  WriteEntry(dir, path, 10, 0);
  EXPECT_TRUE(fs::is_regular_file(path));
  internal::CacheFileReader reader;
  int64_t header = 0;
  std::vector<double> back(10);
  ASSERT_TRUE(reader.Open(path, kMagic, path, &header, 1));
  EXPECT_TRUE(reader.Read(back.data(), back.size() * sizeof(double)));
  EXPECT_TRUE(reader.Finish());
}

// A directory under an entry's name: a miss, and a write that cannot replace it leaves no temp
// file behind (it kept one per failed write).
TEST(CacheReaderTest, ADirectoryAtAnEntryIsAMissAndItsWriteLeavesNoTempFile) {
  const testing::TempDir dir;
  const std::string path = EntryPath(dir, '2', "modes");
  fs::create_directories(fs::path(path) / "inside");
  internal::CacheFileReader reader;
  int64_t header = 0;
  EXPECT_FALSE(reader.Open(path, kMagic, path, &header, 1));
  WriteEntry(dir, EntryPath(dir, '3', "modes"), 4, 0);  // a sound one beside it
  const std::vector<double> values(4, 2.0);
  internal::WriteCacheFile(dir.path().string(), path, kMagic, path, {4},
                           {{values.data(), sizeof(double) * 4}});
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(dir.path())) names.push_back(Name(e.path()));
  std::sort(names.begin(), names.end());
  EXPECT_THAT(names, ElementsAre(Name(path), Name(EntryPath(dir, '3', "modes"))));
}

TEST(CacheBudgetTest, SizesArePlainNumbersWithAnOptionalUnit) {
  EXPECT_EQ(internal::ParseByteSize("0"), 0u);
  EXPECT_EQ(internal::ParseByteSize("1000"), 1000u);
  EXPECT_EQ(internal::ParseByteSize("1.5k"), 1500u);
  EXPECT_EQ(internal::ParseByteSize("500M"), 500000000u);
  EXPECT_EQ(internal::ParseByteSize("500MB"), 500000000u);
  EXPECT_EQ(internal::ParseByteSize("2g"), 2000000000u);
  EXPECT_EQ(internal::ParseByteSize("1GiB"), 1073741824u);
  EXPECT_EQ(internal::ParseByteSize("3T"), 3000000000000u);
  for (const char* bad : {"", "-1", "+5", "1e9", "0x10", "lots", "1 G", "1G ", "1.", ".5", "1..2",
                          "1X", "1GG", "nan", "99999999999T"}) {
    EXPECT_FALSE(internal::ParseByteSize(bad).has_value()) << bad;
  }
}

TEST(CacheBudgetTest, TheBudgetIsTheVariableElseOneGigabyte) {
  BudgetVariable budget("");
  EXPECT_EQ(internal::CacheBudgetBytes(), 1000000000u);
  budget.Set("2G");
  EXPECT_EQ(internal::CacheBudgetBytes(), 2000000000u);
  budget.Set("0");
  EXPECT_EQ(internal::CacheBudgetBytes(), 0u);
  budget.Set("lots");
  const std::string message =
      testing::ThrownMessage<ConfigError>([] { internal::CacheBudgetBytes(); });
  EXPECT_THAT(message, HasSubstr("SONICBOOM_CACHE_MAX_BYTES = 'lots'"));
  EXPECT_THAT(message, HasSubstr("0 for no cap"));
}

// Entries go least recently used first: by modification time, which a read touches.
TEST(CacheBudgetTest, PruningRemovesTheLeastRecentlyUsedFirstAndAReadCountsAsAUse) {
  const BudgetVariable budget("0");
  const testing::TempDir dir;
  for (char n : {'1', '2', '3', '4'}) WriteEntry(dir, EntryPath(dir, n), 100, 100 - (n - '0'));
  const uint64_t each = fs::file_size(EntryPath(dir, '1'));
  EXPECT_THAT(Names(internal::ListCacheEntries(dir.path().string())),
              ElementsAre(Name(EntryPath(dir, '1')), Name(EntryPath(dir, '2')),
                          Name(EntryPath(dir, '3')), Name(EntryPath(dir, '4'))));
  // reading the oldest makes it the newest
  internal::CacheFileReader reader;
  int64_t header = 0;
  std::vector<double> back(100);
  ASSERT_TRUE(reader.Open(EntryPath(dir, '1'), kMagic, EntryPath(dir, '1'), &header, 1));
  ASSERT_TRUE(reader.Read(back.data(), back.size() * sizeof(double)));
  ASSERT_TRUE(reader.Finish());
  const internal::CachePruned p = internal::PruneCache(dir.path().string(), 2 * each + each / 2);
  EXPECT_EQ(p.removed, 2);
  EXPECT_EQ(p.removed_bytes, 2 * each);
  EXPECT_EQ(p.kept, 2);
  EXPECT_EQ(p.kept_bytes, 2 * each);
  EXPECT_THAT(Names(internal::ListCacheEntries(dir.path().string())),
              ElementsAre(Name(EntryPath(dir, '4')), Name(EntryPath(dir, '1'))));
}

// Every write keeps the directory within SONICBOOM_CACHE_MAX_BYTES, but never removes the entry
// it wrote, even one larger than the budget.
TEST(CacheBudgetTest, AWriteKeepsTheDirectoryWithinTheBudgetButKeepsWhatItWrote) {
  BudgetVariable budget("");
  const testing::TempDir dir;
  for (char n : {'1', '2', '3'}) WriteEntry(dir, EntryPath(dir, n), 100, 100 - (n - '0'));
  EXPECT_EQ(internal::ListCacheEntries(dir.path().string()).size(), 3u);  // within 1 GB
  const uint64_t each = fs::file_size(EntryPath(dir, '1'));
  budget.Set(std::to_string(2 * each + each / 2));
  WriteEntry(dir, EntryPath(dir, '4'), 100, 0);
  EXPECT_THAT(Names(internal::ListCacheEntries(dir.path().string())),
              ElementsAre(Name(EntryPath(dir, '3')), Name(EntryPath(dir, '4'))));
  budget.Set(std::to_string(each / 2));
  const std::vector<double> values(100, 3.0);
  internal::WriteCacheFile(dir.path().string(), EntryPath(dir, '5'), kMagic, "five", {100},
                           {{values.data(), sizeof(values[0]) * values.size()}});
  EXPECT_THAT(Names(internal::ListCacheEntries(dir.path().string())),
              ElementsAre(Name(EntryPath(dir, '5'))));
  // no cap
  budget.Set("0");
  for (char n : {'6', '7'}) WriteEntry(dir, EntryPath(dir, n), 100, 0);
  EXPECT_EQ(internal::ListCacheEntries(dir.path().string()).size(), 3u);
}

// A command's working set stays while it runs (the demo built its randomized pool twice under a
// 1 GB budget, 402 s against 291 s): with sparing on, a write prunes only entries the process
// neither wrote nor read, and the command's end prunes what it wrote to down to the budget.
TEST(CacheBudgetTest, ACommandsWorkingSetStaysUntilItsEndThenTheBudgetHolds) {
  BudgetVariable budget("");
  const testing::TempDir dir;
  WriteEntry(dir, EntryPath(dir, '1'), 100, 300);  // another command's, oldest
  const uint64_t each = fs::file_size(EntryPath(dir, '1'));
  budget.Set(std::to_string(2 * each + each / 2));
  internal::SpareThisProcessesCacheEntries();
  for (char n : {'2', '3', '4'}) WriteEntry(dir, EntryPath(dir, n), 100, 200 - (n - '0'));
  // the other command's entry went; this one's three stay, over the budget, while it runs
  EXPECT_THAT(Names(internal::ListCacheEntries(dir.path().string())),
              ElementsAre(Name(EntryPath(dir, '2')), Name(EntryPath(dir, '3')),
                          Name(EntryPath(dir, '4'))));
  internal::PruneSparedCachesToBudget();
  EXPECT_THAT(Names(internal::ListCacheEntries(dir.path().string())),
              ElementsAre(Name(EntryPath(dir, '3')), Name(EntryPath(dir, '4'))));
  // sparing is off again: a write prunes as before
  WriteEntry(dir, EntryPath(dir, '5'), 100, 0);
  EXPECT_EQ(internal::ListCacheEntries(dir.path().string()).size(), 2u);
}

// A reader holds its entry's lock from Open to Finish: pruning keeps it meanwhile.
TEST(CacheBudgetTest, AnEntryBeingReadIsKept) {
  const BudgetVariable budget("0");
  const testing::TempDir dir;
  WriteEntry(dir, EntryPath(dir, '1'), 100, 50);
  WriteEntry(dir, EntryPath(dir, '2'), 100, 40);
  internal::CacheFileReader reader;
  int64_t header = 0;
  ASSERT_TRUE(reader.Open(EntryPath(dir, '1'), kMagic, EntryPath(dir, '1'), &header, 1));
  const internal::CachePruned p = internal::PruneCache(dir.path().string(), 0);
  EXPECT_EQ(p.removed, 1);
  EXPECT_EQ(p.in_use, 1);
  EXPECT_EQ(p.kept, 1);
  EXPECT_THAT(Names(internal::ListCacheEntries(dir.path().string())),
              ElementsAre(Name(EntryPath(dir, '1'))));
  std::vector<double> back(100);
  EXPECT_TRUE(reader.Read(back.data(), back.size() * sizeof(double)));
  EXPECT_TRUE(reader.Finish());
  EXPECT_EQ(internal::PruneCache(dir.path().string(), 0).removed, 1);
  EXPECT_TRUE(internal::ListCacheEntries(dir.path().string()).empty());
}

// Only cache files and their writers' temp files are the cache's: a temp file whose writer is
// gone and a FIFO under an entry's name are removed whatever the budget; a temp file being
// written, and every other file, stay.
TEST(CacheBudgetTest, StaleTempFilesAndDamagedNamesGoOtherFilesStay) {
  const BudgetVariable budget("0");
  const testing::TempDir dir;
  WriteEntry(dir, EntryPath(dir, '1'), 10, 0);
  const std::string stale = EntryPath(dir, '2') + ".partial.999999999.1f";
  const std::string live = EntryPath(dir, '3') + ".partial." + std::to_string(::getpid()) + ".2";
  const std::string fifo = EntryPath(dir, '4', "level");
  for (const std::string& path :
       {stale, live, dir / "notes.txt", dir / "ritz-zz.bin", dir / "modes-0000000000000005.bin~"})
    std::ofstream(path) << "x";
  ASSERT_EQ(::mkfifo(fifo.c_str(), 0600), 0);
  EXPECT_THAT(Names(internal::ListCacheEntries(dir.path().string())),
              ::testing::UnorderedElementsAre(Name(EntryPath(dir, '1')), Name(stale), Name(live),
                                              Name(fifo)));
  const internal::CachePruned p = internal::PruneCache(dir.path().string(), 1000000000);
  EXPECT_EQ(p.removed, 2);
  EXPECT_EQ(p.kept, 1);
  EXPECT_FALSE(fs::exists(stale));
  EXPECT_FALSE(fs::exists(fs::symlink_status(fifo)));
  for (const std::string& path :
       {live, dir / "notes.txt", dir / "ritz-zz.bin", EntryPath(dir, '1')})
    EXPECT_TRUE(fs::exists(path)) << path;
  // --all: every cache file, still never one being written nor another file
  EXPECT_EQ(internal::PruneCache(dir.path().string(), 0).removed, 1);
  EXPECT_TRUE(fs::exists(live));
  EXPECT_TRUE(fs::exists(dir / "notes.txt"));
}

}  // namespace
}  // namespace sonicboom
