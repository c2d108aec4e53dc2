// A full disk (a 3 MB tmpfs): every writer ends with exit 1 naming the file and the full disk,
// nothing under the final name, and an old output replaced with --force stays intact. The five
// commands ended in SIGSEGV (libhdf5's shutdown closing a file whose close had failed) or
// SIGABRT (torch's file writer throwing from its destructor).
#include <gmock/gmock.h>
#include <gtest/gtest.h>
#include <sys/mount.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "common/test_util.h"

namespace sonicboom {
namespace {

namespace fs = std::filesystem;
using sonicboom::testing::CliRun;
using sonicboom::testing::kShortRecordArgs;
using sonicboom::testing::kTinyModelArgs;
using sonicboom::testing::RunCli;
using sonicboom::testing::TempDir;
using ::testing::HasSubstr;

std::string Bytes(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), {}};
}

// A small tmpfs at `dir`, unmounted with the object; `mounted` false where mounting is not
// allowed (no root, a container without the capability).
class SmallDisk {
 public:
  explicit SmallDisk(const fs::path& dir) : dir_(dir) {
    fs::create_directories(dir_);
    mounted_ = ::mount("tmpfs", dir_.c_str(), "tmpfs", 0, "size=3m") == 0;
  }
  ~SmallDisk() {
    if (mounted_) ::umount2(dir_.c_str(), MNT_DETACH);
  }
  bool mounted() const { return mounted_; }
  // fills the disk but for `left_kib`
  void Fill(int left_kib) const {
    const fs::space_info space = fs::space(dir_);
    const auto bytes = static_cast<std::streamsize>(space.available) - 1024 * left_kib;
    std::ofstream(dir_ / "fill", std::ios::binary)
        << std::string(static_cast<size_t>(std::max<std::streamsize>(bytes, 0)), 'x');
  }
  void Empty() const {
    for (const auto& entry : fs::directory_iterator(dir_)) fs::remove_all(entry.path());
  }

 private:
  fs::path dir_;
  bool mounted_{false};
};

TEST(FullDiskTest, EveryWriterEndsInAnErrorAndLeavesNothingUnderItsFinalName) {
  TempDir work;
  const std::string cwd = work.path().string();
  const SmallDisk disk(work.path() / "disk");
  if (!disk.mounted()) {
    GTEST_SKIP() << "cannot mount a tmpfs here (needs root and CAP_SYS_ADMIN); the full-disk "
                    "cases run where it can";
  }
  const std::string args = kShortRecordArgs + "-q --threads 1 ";
  ASSERT_EQ(RunCli(args + "generate --count 16 --out D.h5", cwd).exit_code, 0);
  for (int s = 0; s < 2; ++s) {
    ASSERT_EQ(RunCli(args + "generate --count 16 --shard " + std::to_string(s) +
                         " --num-shards 2 --out S" + std::to_string(s) + ".h5",
                     cwd)
                  .exit_code,
              0);
  }
  ASSERT_EQ(RunCli("-q export --layout trial --in D.h5 --out TR", cwd).exit_code, 0);

  // (command, its final output under disk/)
  const std::pair<std::string, std::string> cases[] = {
      {"generate --count 64 --out disk/G.h5", "G.h5"},
      {"features --in D.h5 --out disk/F.h5", "F.h5"},
      {"merge --out disk/M.h5 S0.h5 S1.h5", "M.h5"},
      {"import --layout trial --min-duration-s 0.5 --in TR --out disk/I.h5", "I.h5"},
      {kTinyModelArgs + "--set train.epochs=1 train --data D.h5 --out disk/R", "R"},
  };
  for (const auto& [command, output] : cases) {
    disk.Empty();
    disk.Fill(/*left_kib=*/64);
    const CliRun run = RunCli(args + command, cwd);
    EXPECT_EQ(run.exit_code, 1) << command << "\n" << run.err;
    EXPECT_THAT(run.err, HasSubstr("no space left on device")) << command;
    EXPECT_THAT(run.err, HasSubstr("disk/" + output)) << command;
    EXPECT_FALSE(fs::exists(work.path() / "disk" / output)) << command;
  }

  // --force over a finished output: the old one stays whole when the new one cannot be written
  disk.Empty();
  ASSERT_EQ(RunCli(args + "generate --count 2 --out disk/G.h5", cwd).exit_code, 0);
  const std::string old = Bytes(work.path() / "disk/G.h5");
  disk.Fill(/*left_kib=*/64);
  const CliRun run = RunCli(args + "--seed 5 generate --count 64 --out disk/G.h5 --force", cwd);
  EXPECT_EQ(run.exit_code, 1) << run.err;
  EXPECT_EQ(Bytes(work.path() / "disk/G.h5"), old);
}

}  // namespace
}  // namespace sonicboom
