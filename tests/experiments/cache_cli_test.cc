// `sonicboom cache list|prune` end to end, and the mode cache's rules as the CLI meets them: a
// FIFO at the solid's entry, a bad budget, HOME unset.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <fstream>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "common/test_util.h"

namespace sonicboom {
namespace {

namespace fs = std::filesystem;
using testing::EnvChanges;
using ::testing::HasSubstr;
using ::testing::Not;
using testing::RunCliEnv;
using testing::TempDir;

// A workspace with a cache directory `cache` of entries made by hand (cache files are listed
// and pruned by name and time, not read) and a file that is not the cache's.
class CacheCliTest : public ::testing::Test {
 protected:
  void SetUp() override {
    fs::create_directories(cache_);
    std::ofstream(cache_ + "/notes.txt") << "not an entry";
  }
  // an entry KIND-000...N.bin of `bytes` bytes, last used `age_s` seconds ago; its name
  std::string Add(const std::string& kind, char n, size_t bytes, int age_s) {
    const std::string name = kind + "-" + std::string(15, '0') + n + ".bin";
    std::ofstream(cache_ + "/" + name) << std::string(bytes, 'x');
    fs::last_write_time(cache_ + "/" + name,
                        fs::file_time_type::clock::now() - std::chrono::seconds(age_s));
    return name;
  }
  // the cache's entries by name
  std::vector<std::string> Left() const {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(cache_)) names.push_back(e.path().filename());
    std::sort(names.begin(), names.end());
    return names;
  }
  EnvChanges Env(const std::string& budget = "") const {
    return {{"SONICBOOM_CACHE_DIR", cache_}, {"SONICBOOM_CACHE_MAX_BYTES", budget}};
  }
  testing::CliRun Run(const std::string& args, const std::string& budget = "") {
    return RunCliEnv(args, dir_.path().string(), Env(budget));
  }

  TempDir dir_;
  std::string cache_ = dir_ / "cache";
};

TEST_F(CacheCliTest, ListShowsEveryEntryItsSizeLastUseAndTheTotalAgainstTheBudget) {
  const std::string ritz = Add("ritz", '1', 78000, 3600), modes = Add("modes", '2', 1000, 60),
                    ref = Add("reference", '3', 5000, 10);
  auto run = Run("cache list");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_THAT(run.out, HasSubstr("mode cache " + cache_ +
                                 ": 3 entries, 84.0 kB of a budget of "
                                 "1.00 GB (SONICBOOM_CACHE_MAX_BYTES)"));
  EXPECT_THAT(run.out, HasSubstr("78.0 kB  " + ritz));
  EXPECT_THAT(run.out, Not(HasSubstr("notes.txt")));
  // least recently used (pruned) first
  EXPECT_LT(run.out.find(ritz), run.out.find(modes));
  EXPECT_LT(run.out.find(modes), run.out.find(ref));
  run = Run("--json cache list", "0");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const auto j = nlohmann::json::parse(run.out);
  EXPECT_EQ(j["dir"], cache_);
  EXPECT_EQ(j["budget_bytes"], 0);
  EXPECT_EQ(j["total_bytes"], 84000);
  EXPECT_EQ(j["entries_count"], 3);
  ASSERT_EQ(j["entries"].size(), 3u);
  EXPECT_EQ(j["entries"][0]["name"], ritz);
  EXPECT_EQ(j["entries"][0]["kind"], "ritz");
  EXPECT_EQ(j["entries"][0]["bytes"], 78000);
  EXPECT_THAT(Run("cache list", "0").out, HasSubstr("of no cap"));
  // another directory, by option; a file is not one
  run = RunCliEnv("cache list --cache-dir " + dir_.path().string(), dir_.path().string(), Env());
  EXPECT_THAT(run.out, HasSubstr(": 0 entries, 0 B of a budget of 1.00 GB"));
  run = Run("cache list --cache-dir cache/notes.txt");
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_THAT(run.err, HasSubstr("cache/notes.txt: not a directory"));
}

TEST_F(CacheCliTest, PruneRemovesTheLeastRecentlyUsedFirstDownToMaxBytes) {
  const std::string a = Add("ritz", '1', 1000, 40), b = Add("ritz", '2', 1000, 30),
                    c = Add("modes", '3', 1000, 20), d = Add("level", '4', 1000, 10);
  auto run = Run("cache prune --max-bytes 2.5k");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_THAT(run.out, HasSubstr("removed 2 file(s) (2.0 kB); 2 entries (2.0 kB) remain"));
  EXPECT_EQ(Left(), (std::vector<std::string>{d, c, "notes.txt"}));
}

TEST_F(CacheCliTest, PruneKeepsTheBudgetAndAllRemovesEveryEntryAndNothingElse) {
  Add("ritz", '1', 1000, 40);
  Add("ritz", '2', 1000, 30);
  const std::string newest = Add("reference", '3', 1000, 20);
  auto run = Run("cache prune", "1500");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_THAT(run.out, HasSubstr("against a budget of 1.5 kB"));
  EXPECT_EQ(Left(), (std::vector<std::string>{"notes.txt", newest}));
  run = Run("cache prune", "0");  // no cap: nothing to remove
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(Left(), (std::vector<std::string>{"notes.txt", newest}));
  run = Run("--json cache prune --all");
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_EQ(nlohmann::json::parse(run.out)["removed"], 1);
  EXPECT_EQ(Left(), (std::vector<std::string>{"notes.txt"}));
}

TEST_F(CacheCliTest, BadSizesAreRefusedNamingTheOptionOrTheVariable) {
  const std::string a = Add("ritz", '1', 1000, 40);
  for (const char* bad : {"lots", "-1", "1e9", "0x10"}) {
    const auto run = Run(std::string("cache prune --max-bytes ") + bad);
    EXPECT_EQ(run.exit_code, 2) << bad;
    EXPECT_THAT(run.err, HasSubstr("--max-bytes")) << bad;
    EXPECT_THAT(run.err, HasSubstr(std::string("'") + bad + "' is not a size")) << bad;
  }
  EXPECT_EQ(Run("cache prune --all --max-bytes 1k").exit_code, 2);
  EXPECT_EQ(Run("cache").exit_code, 2);
  // the variable is refused before any work, by every command
  for (const char* command : {"cache list", "cache prune", "config"}) {
    const auto run = Run(command, "lots");
    EXPECT_EQ(run.exit_code, 1) << command;
    EXPECT_THAT(run.err, HasSubstr("SONICBOOM_CACHE_MAX_BYTES = 'lots': expected a size"));
  }
  EXPECT_EQ(Left(), (std::vector<std::string>{"notes.txt", a}));
}

// With HOME unset the mode cache was off without a word: the passwd home takes its place (or
// the command says there is none), and XDG_CACHE_HOME is honoured.
TEST_F(CacheCliTest, WithHomeUnsetTheCommandSaysWhereTheCacheIs) {
  const std::string cwd = dir_.path().string();
  auto run = RunCliEnv("cache list", cwd,
                       {{"HOME", ""}, {"SONICBOOM_CACHE_DIR", ""}, {"XDG_CACHE_HOME", ""}});
  EXPECT_THAT(run.err, HasSubstr("HOME is unset"));
  EXPECT_THAT(run.err, HasSubstr("SONICBOOM_CACHE_DIR"));
  if (run.exit_code == 0) {
    EXPECT_THAT(run.out, HasSubstr("/.cache/sonicboom/modes: "));
  } else {
    EXPECT_EQ(run.exit_code, 1);
    EXPECT_THAT(run.err, HasSubstr("there is no mode cache"));
  }
  run = RunCliEnv("cache list", cwd,
                  {{"HOME", ""}, {"SONICBOOM_CACHE_DIR", ""}, {"XDG_CACHE_HOME", cwd}});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  EXPECT_THAT(run.out, HasSubstr("mode cache " + cwd + "/sonicboom/modes: 0 entries"));
  EXPECT_THAT(run.err, Not(HasSubstr("HOME")));
}

// Runs `run` while polling `fifo`: true when something opened the FIFO to read (a writer opened
// without blocking succeeds only then, and it lets that reader go on: a hang becomes a failure).
template <typename F>
bool FifoOpenedWhile(const std::string& fifo, F run) {
  std::atomic<bool> done{false}, reached{false};
  std::thread poke([&] {
    while (!done) {
      // (once replaced by a regular file, which opens for writing anyway, it is not the FIFO)
      const int fd = ::open(fifo.c_str(), O_WRONLY | O_NONBLOCK);
      struct stat st {};
      if (fd >= 0 && ::fstat(fd, &st) == 0 && S_ISFIFO(st.st_mode)) reached = true;
      if (fd >= 0) ::close(fd);
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
  });
  run();
  done = true;
  poke.join();
  return reached;
}

// The hang: a FIFO at the reference solid's cache entry blocked `rerender` forever. Its
// reader never opens it: a warning names it, the modes are solved again and the entry replaced.
TEST_F(CacheCliTest, AFifoAtTheSolidsCacheEntryIsSolvedAgainNotWaitedOn) {
  // the solid at its coarsest (two solves of 2 s): what is checked is its cache entry
  const std::string coarse = " --max-frequency 1000 --element-m 0.12 -q";
  // the strikes with the suite's own cache (the shell's modes solved once), the solid with `cache`
  ASSERT_EQ(testing::RunCli(testing::kShortRecordArgs + "generate --count 2 --out D.h5 -q",
                            dir_.path().string())
                .exit_code,
            0);
  auto run = Run("rerender --in D.h5 --out R.h5" + coarse);
  ASSERT_EQ(run.exit_code, 0) << run.err;
  std::string entry;
  for (const auto& e : fs::directory_iterator(cache_)) {
    if (e.path().filename().string().rfind("reference-", 0) == 0) entry = e.path().string();
  }
  ASSERT_FALSE(entry.empty()) << "rerender wrote no reference-*.bin into " << cache_;
  fs::remove(entry);
  ASSERT_EQ(::mkfifo(entry.c_str(), 0600), 0);
  const bool opened =
      FifoOpenedWhile(entry, [&] { run = Run("rerender --in D.h5 --out R2.h5" + coarse); });
  EXPECT_FALSE(opened) << "rerender opened the FIFO at " << entry << " (it blocks there)";
  EXPECT_EQ(run.exit_code, 0) << run.err;
  EXPECT_THAT(run.err, HasSubstr(entry + " is a FIFO, not a regular file; solving again"));
  EXPECT_TRUE(fs::is_regular_file(entry));
}

}  // namespace
}  // namespace sonicboom
