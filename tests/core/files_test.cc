// One writer per output: OutputLock against a second process and within one process.
#include "sonicboom/core/files.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include "sonicboom/core/cache_file.h"
#include "sonicboom/core/errors.h"

namespace sonicboom {
namespace {

namespace fs = std::filesystem;
using ::testing::HasSubstr;

// Exit status of a forked child that tries to take the lock on `path`: 0 taken, 1 refused
// naming the path and this (the holder's) pid, 2 refused otherwise.
int ChildTakes(const std::string& path) {
  const pid_t holder = ::getpid();
  const pid_t child = ::fork();
  if (child == 0) {
    int code = 0;
    try {
      const OutputLock lock(path);
    } catch (const IoError& e) {
      const std::string what = e.what();
      code = what.find(path) != std::string::npos &&
                     what.find("pid " + std::to_string(holder)) != std::string::npos
                 ? 1
                 : 2;
    }
    ::_exit(code);
  }
  int status = 0;
  ::waitpid(child, &status, 0);
  return WIFEXITED(status) ? WEXITSTATUS(status) : -1;
}

TEST(OutputLockTest, OneProcessWritesAnOutput) {
  const fs::path dir = fs::temp_directory_path() / ("sb_lock_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir);
  const std::string out = (dir / "D.h5").string();
  {
    const OutputLock lock(out);
    EXPECT_TRUE(fs::exists(out + ".lock"));
    // held here: another process is refused, naming the output and the holder
    EXPECT_EQ(ChildTakes(out), 1);
    // within this process the lock is shared (the dataset writer takes it after resume did)
    { const OutputLock again(out); }
    EXPECT_EQ(ChildTakes(out), 1);
    // another output is free
    EXPECT_EQ(ChildTakes((dir / "E.h5").string()), 0);
  }
  // released: the lock file is gone and another process takes it
  EXPECT_FALSE(fs::exists(out + ".lock"));
  EXPECT_EQ(ChildTakes(out), 0);
  // a lock file a killed process left behind holds nothing
  std::ofstream(out + ".lock") << "12345";
  EXPECT_EQ(ChildTakes(out), 0);
  // a directory that cannot hold the lock file: refused naming it
  try {
    const OutputLock lock((dir / "missing" / "F.h5").string());
    ADD_FAILURE() << "no error";
  } catch (const IoError& e) {
    EXPECT_THAT(e.what(), HasSubstr("F.h5.lock"));
  }
  fs::remove_all(dir);
}

// One spelling per file: a link, "..", "." and a trailing separator resolve to the same path,
// and containment is by whole components ("/a/bc" is not inside "/a/b").
TEST(ResolvedPathTest, SpellingsOfOneFileCompareEqualAndContainmentIsByComponent) {
  const fs::path root =
      fs::temp_directory_path() / ("resolved_path_test_" + std::to_string(::getpid()));
  fs::remove_all(root);
  fs::create_directories(root / "b" / "c");
  fs::create_directories(root / "bc");
  fs::create_directory_symlink(root / "b", root / "link");
  EXPECT_EQ(ResolvedPath(root / "link" / "c"), ResolvedPath(root / "b" / "c"));
  EXPECT_EQ(ResolvedPath(root / "bc" / ".." / "b" / "." / "c"), ResolvedPath(root / "b" / "c"));
  // a path that does not exist yet keeps its missing tail
  EXPECT_EQ(ResolvedPath(root / "link" / "new.h5"), ResolvedPath(root / "b") / "new.h5");
  EXPECT_TRUE(IsWithin(ResolvedPath(root / "link" / "c"), ResolvedPath(root / "b")));
  EXPECT_TRUE(IsWithin(ResolvedPath(root / "b"), ResolvedPath(root / "b")));
  EXPECT_TRUE(IsWithin(ResolvedPath(root / "b" / "c"), fs::path(root.string() + "/b/")));
  EXPECT_FALSE(IsWithin(ResolvedPath(root / "bc"), ResolvedPath(root / "b")));
  EXPECT_FALSE(IsWithin(ResolvedPath(root / "b"), ResolvedPath(root / "b" / "c")));
  fs::remove_all(root);
}

// Writers of one cache key at once (two tests, or two threads, solving the same modes): each
// writes its own temp file and the last rename wins, so the file left is whole and no temp file
// stays; with one shared temp name a writer could rename another's half-written file.
TEST(CacheFileTest, ConcurrentWritersOfOneKeyLeaveOneWholeFile) {
  const fs::path dir = fs::temp_directory_path() / ("cache_race_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::string path = (dir / "modes-test.bin").string();
  const char magic[8] = {'S', 'B', 'T', 'E', 'S', 'T', '0', '1'};
  constexpr size_t kValues = size_t{1} << 19;  // 4 MiB a writer
  for (int round = 0; round < 3; ++round) {
    // writer w writes header w and every value w: a file mixing two writers fails its checksum
    std::vector<std::vector<double>> blocks(4, std::vector<double>(kValues));
    std::vector<std::thread> writers;
    for (int w = 0; w < 4; ++w) {
      std::fill(blocks[w].begin(), blocks[w].end(), static_cast<double>(w));
      writers.emplace_back([&, w] {
        internal::WriteCacheFile(dir.string(), path, magic, "key", {int64_t{w}},
                                 {{blocks[w].data(), kValues * sizeof(double)}});
      });
    }
    for (std::thread& t : writers) t.join();
    internal::CacheFileReader reader;
    int64_t header = -1;
    ASSERT_TRUE(reader.Open(path, magic, "key", &header, 1)) << round;
    std::vector<double> back(kValues);
    ASSERT_TRUE(reader.Read(back.data(), kValues * sizeof(double)));
    EXPECT_TRUE(reader.Finish()) << round;
    EXPECT_EQ(back, std::vector<double>(kValues, static_cast<double>(header))) << round;
    int files = 0;
    for (const auto& entry : fs::directory_iterator(dir)) {
      ++files;
      EXPECT_EQ(entry.path().string(), path);
    }
    EXPECT_EQ(files, 1);
  }
  fs::remove_all(dir);
}

}  // namespace
}  // namespace sonicboom
