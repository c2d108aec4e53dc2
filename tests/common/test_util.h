#pragma once
// Shared helpers for the test suites: temporary directories and running the CLI.

#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <filesystem>
#include <random>
#include <string>

namespace sonicboom::testing {

// CLI arguments of the end-to-end tests: short records (0.6 s, the onset at 0.25 s) and a tiny
// network (width 16, one block, two heads, batches of 8) keep each run to seconds.
inline const std::string kShortRecordArgs =
    "--set audio.record_duration_s=0.6 --set audio.onset_time_s=0.25 ";
inline const std::string kTinyModelArgs =
    "--set model.width=16 --set model.blocks=1 --set model.heads=2 --set train.batch_size=8 ";

// A fresh directory under the system temp dir, removed with the object.
class TempDir {
 public:
  TempDir() {
    std::random_device rd;
    path_ = std::filesystem::temp_directory_path() /
            ("sonicboom_test_" + std::to_string(rd()) + std::to_string(rd()));
    std::filesystem::create_directories(path_);
  }
  ~TempDir() {
    std::error_code ec;
    std::filesystem::remove_all(path_, ec);
  }
  std::string operator/(const std::string& name) const { return (path_ / name).string(); }
  const std::filesystem::path& path() const { return path_; }

 private:
  std::filesystem::path path_;
};

// Result of one CLI run: exit code, stdout, stderr.
struct CliRun {
  int exit_code{-1};
  std::string out;
  std::string err;
};

// Runs the built `sonicboom` with `args` (shell-quoted by the caller) in `cwd`.
inline CliRun RunCli(const std::string& args, const std::string& cwd) {
  const std::string err_file = cwd + "/.stderr.txt";
  const std::string cmd =
      "cd '" + cwd + "' && '" + std::string(SONICBOOM_CLI) + "' " + args + " 2>'" + err_file + "'";
  CliRun run;
  FILE* pipe = popen(cmd.c_str(), "r");
  if (!pipe) return run;
  std::array<char, 4096> buf;
  size_t n;
  while ((n = fread(buf.data(), 1, buf.size(), pipe)) > 0) run.out.append(buf.data(), n);
  const int status = pclose(pipe);
  run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  if (FILE* f = fopen(err_file.c_str(), "r")) {
    while ((n = fread(buf.data(), 1, buf.size(), f)) > 0) run.err.append(buf.data(), n);
    fclose(f);
  }
  std::filesystem::remove(err_file);
  return run;
}

// Message of the E thrown by f, or a test failure.
template <typename E, typename F>
std::string ThrownMessage(F f) {
  try {
    f();
  } catch (const E& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected an exception";
  return "";
}

}  // namespace sonicboom::testing
