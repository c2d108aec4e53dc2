#pragma once
// Shared helpers for the test suites: temporary directories and running the CLI.

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <map>
#include <optional>
#include <random>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "sonicboom/core/process.h"

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

// The bytes of a file ("" when it cannot be read), read at once into a string of its size (a
// snapshot of a workspace reads tens of megabytes around every refused command).
inline std::string ReadBytes(const std::filesystem::path& path) {
  std::ifstream in(path, std::ios::binary | std::ios::ate);
  const std::streamoff size = in ? static_cast<std::streamoff>(in.tellg()) : -1;
  if (size < 0) return "";
  std::string bytes(static_cast<size_t>(size), '\0');
  in.seekg(0);
  in.read(bytes.data(), static_cast<std::streamsize>(size));
  return in ? bytes : "";
}

// The bytes of every regular file under `root`, by path: a snapshot to compare after a refused
// run.
inline std::map<std::string, std::string> Snapshot(const std::filesystem::path& root) {
  std::map<std::string, std::string> files;
  for (const auto& entry : std::filesystem::recursive_directory_iterator(root)) {
    if (entry.is_regular_file()) files[entry.path().string()] = ReadBytes(entry.path());
  }
  return files;
}

// Result of one CLI run: exit code, stdout, stderr.
struct CliRun {
  int exit_code{-1};
  std::string out;
  std::string err;
};

// `args` split into words as a shell would split plain words: blanks separate, '...' is literal,
// "..." keeps blanks and takes \" \\ escapes, a backslash escapes the next character. No shell
// runs them, so an unquoted ; | & < > ( ) $ or ` (a shell feature) fails the test.
inline std::vector<std::string> SplitArgs(const std::string& args) {
  std::vector<std::string> words;
  std::string word;
  bool in_word = false;
  for (size_t i = 0; i < args.size(); ++i) {
    const char c = args[i];
    if (c == ' ' || c == '\t' || c == '\n') {
      if (in_word) words.push_back(word);
      word.clear();
      in_word = false;
    } else if (c == '\'') {
      const size_t end = args.find('\'', i + 1);
      if (end == std::string::npos) ADD_FAILURE() << "unclosed ' in: " << args;
      word += args.substr(i + 1, end - i - 1);
      i = end == std::string::npos ? args.size() : end;
      in_word = true;
    } else if (c == '"') {
      for (++i; i < args.size() && args[i] != '"'; ++i) {
        if (args[i] == '\\' && i + 1 < args.size()) ++i;
        word += args[i];
      }
      if (i >= args.size()) ADD_FAILURE() << "unclosed \" in: " << args;
      in_word = true;
    } else if (c == '\\' && i + 1 < args.size()) {
      word += args[++i];
      in_word = true;
    } else {
      if (std::string(";|&<>()$`").find(c) != std::string::npos) {
        ADD_FAILURE() << "a shell feature ('" << c << "') in CLI arguments, which no shell runs: "
                      << args;
      }
      word += c;
      in_word = true;
    }
  }
  if (in_word) words.push_back(word);
  return words;
}

// Environment changes for RunCliEnv: a value sets the variable, "" removes it.
using EnvChanges = std::vector<std::pair<std::string, std::string>>;
// Environment changes for RunProgram: a value (possibly empty) sets the variable, nullopt
// removes it.
using ProcessEnv = std::vector<std::pair<std::string, std::optional<std::string>>>;

// Runs `argv` in `cwd` (empty: this process's) from an argument vector (no shell), with `env`.
inline CliRun RunProgram(const std::vector<std::string>& argv, const std::string& cwd,
                         const ProcessEnv& env = {}) {
  ProcessRequest request;
  request.argv = argv;
  request.cwd = cwd;
  request.env = env;
  CliRun run;
  try {
    const ProcessResult r = RunProcess(request);
    run.exit_code = r.exit_code;
    run.out = r.out;
    run.err = r.err;
  } catch (const std::exception& e) {
    ADD_FAILURE() << e.what();
  }
  return run;
}

// Runs the built `sonicboom` with `args` (shell-style words, SplitArgs) in `cwd`, with `env`.
inline CliRun RunCliEnv(const std::string& args, const std::string& cwd, const EnvChanges& env) {
  std::vector<std::string> argv = {std::string(SONICBOOM_CLI)};
  for (std::string& word : SplitArgs(args)) argv.push_back(std::move(word));
  ProcessEnv changes;
  for (const auto& [name, value] : env) {
    changes.emplace_back(name, value.empty() ? std::nullopt : std::optional(value));
  }
  return RunProgram(argv, cwd, changes);
}

// Runs the built `sonicboom` with `args` (shell-style words, SplitArgs) in `cwd`.
inline CliRun RunCli(const std::string& args, const std::string& cwd) {
  return RunCliEnv(args, cwd, {});
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
