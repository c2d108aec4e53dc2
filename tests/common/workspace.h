#pragma once
// A suite's shared workspace: the inputs its tests read (datasets, a trained run), built once for
// a ctest run and copied into each test process's own directory.
//
// ctest runs one test per process, so a suite whose SetUpTestSuite generated and trained rebuilt
// the same files for every test. Now the suite's builder test (a TEST that calls
// PublishWorkspace) builds them into the build tree's test-work/<name>, stamped with the binaries
// that made them; tests/CMakeLists.txt makes it the suite's ctest fixture (FIXTURES_SETUP), so it
// runs first in every ctest run. Each test process then copies it (UseWorkspace, or the suite's
// fixture WorkspaceTest). A process that finds no workspace stamped with its binaries (a test
// binary run by hand after a rebuild) builds its own, as the builder does.
#include <fcntl.h>
#include <sys/file.h>
#include <unistd.h>

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include "common/test_util.h"

namespace sonicboom::testing {

// A suite's workspace: its name under the build tree's test-work and what fills an empty
// directory with it.
struct Workspace {
  const char* name;
  void (*build)(const std::filesystem::path& dir);
};

namespace workspace_detail {

namespace fs = std::filesystem;

inline fs::path Root() {
  return fs::path(SONICBOOM_TEST_WORK_DIR);
}

// What the files of a workspace follow from: the CLI that made them and the test binary holding
// the recipe (size and modification time of each)
inline std::string Stamp() {
  std::ostringstream s;
  for (const fs::path& binary : {fs::path(SONICBOOM_CLI), fs::read_symlink("/proc/self/exe")}) {
    std::error_code ec;
    const auto size = fs::file_size(binary, ec);
    const auto time = fs::last_write_time(binary, ec).time_since_epoch().count();
    s << binary.string() << " " << size << " " << time << "\n";
  }
  return s.str();
}

// An advisory lock on the workspace `name` (shared while copying, exclusive while replacing),
// released when the object goes
class Lock {
 public:
  Lock(const std::string& name, int operation) {
    fs::create_directories(Root());
    fd_ = ::open((Root() / (name + ".lock")).c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd_ < 0 || ::flock(fd_, operation) != 0) ADD_FAILURE() << "cannot lock workspace " << name;
  }
  ~Lock() {
    if (fd_ >= 0) ::close(fd_);
  }
  Lock(const Lock&) = delete;
  Lock& operator=(const Lock&) = delete;

 private:
  int fd_{-1};
};

// The file under `dir` that names `dir` by its absolute path, or "" (a copy of such a workspace
// would still point at the original)
inline std::string NamesItsOwnPath(const fs::path& dir) {
  for (const auto& [path, bytes] : Snapshot(dir)) {
    if (bytes.find(dir.string()) != std::string::npos) return path;
  }
  return "";
}

}  // namespace workspace_detail

// Runs each CLI command of `commands` in `dir` in order; the first that fails ends the build as a
// test failure naming it and its stderr.
inline void RunEach(const std::vector<std::string>& commands, const std::filesystem::path& dir) {
  for (const std::string& args : commands) {
    const CliRun run = RunCli(args, dir.string());
    ASSERT_EQ(run.exit_code, 0) << args << "\n" << run.err;
  }
}

// The builder test's body: builds `workspace` and puts it in place of an older one; a build that
// fails leaves none, so the suite's tests build their own.
inline void PublishWorkspace(const Workspace& workspace) {
  namespace fs = std::filesystem;
  using workspace_detail::Lock;
  const std::string name = workspace.name;
  const fs::path root = workspace_detail::Root(), published = root / name;
  const std::string pid = std::to_string(::getpid());
  const fs::path fresh = root / (name + ".new." + pid), old = root / (name + ".old." + pid);
  {
    const Lock lock(name, LOCK_EX);
    fs::remove_all(published);
  }
  fs::remove_all(fresh);
  fs::create_directories(fresh);
  workspace.build(fresh);
  const std::string self_named = workspace_detail::NamesItsOwnPath(fresh);
  EXPECT_EQ(self_named, "") << "a workspace file names the workspace's own path";
  if (::testing::Test::HasFailure()) {
    fs::remove_all(fresh);
    return;
  }
  std::ofstream(fresh / ".stamp") << workspace_detail::Stamp();
  const Lock lock(name, LOCK_EX);
  if (fs::exists(published)) fs::rename(published, old);
  fs::rename(fresh, published);
  fs::remove_all(old);
}

// Fills the empty directory `dir` with `workspace`: a copy of the published one if the binaries
// that made it are this process's, else built here.
inline void UseWorkspace(const Workspace& workspace, const std::filesystem::path& dir) {
  namespace fs = std::filesystem;
  const fs::path published = workspace_detail::Root() / workspace.name;
  {
    const workspace_detail::Lock lock(workspace.name, LOCK_SH);
    if (ReadBytes(published / ".stamp") == workspace_detail::Stamp()) {
      fs::copy(published, dir, fs::copy_options::recursive | fs::copy_options::copy_symlinks);
      fs::remove(dir / ".stamp");
      return;
    }
  }
  workspace.build(dir);
}

// The fixture of a suite whose tests work in one copy of workspace `kWorkspace` a test process,
// at dir_: `class FooTest : public WorkspaceTest<kFooWorkspace>`.
template <const Workspace& kWorkspace>
class WorkspaceTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new TempDir();
    UseWorkspace(kWorkspace, dir_->path());
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static inline TempDir* dir_ = nullptr;
};

}  // namespace sonicboom::testing
