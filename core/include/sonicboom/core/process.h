#pragma once
/// Child processes started from an argument vector (posix_spawn): no shell ever sees a string of
/// the user's, so quotes, `;`, `$( )` and newlines in a path are only bytes of that path.

#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace sonicboom {

/// What to run: argv[0] is the program (a path, or a name looked up in PATH).
struct ProcessRequest {
  std::vector<std::string> argv;
  /// the child's working directory; empty keeps the parent's
  std::string cwd;
  /// changes to the parent's environment: a value sets the variable, nullopt removes it
  std::vector<std::pair<std::string, std::optional<std::string>>> env;
  /// stdin of the child is /dev/null unless this is set (then it is written to a pipe)
  std::optional<std::string> stdin_text;
};

/// How a child ended, and what it wrote.
struct ProcessResult {
  /// the exit status when it exited; -1 when killed by a signal (signal_number says which)
  int exit_code{-1};
  int signal_number{0};
  std::string out;
  std::string err;
  bool exited_zero() const { return exit_code == 0; }
  /// "exit status N" or "killed by signal N (NAME)"
  std::string Ending() const;
  /// the last non-empty line of stderr, or "" when it wrote none
  std::string LastErrLine() const;
};

/// Runs the request to its end, collecting stdout and stderr. Throws IoError naming argv[0]
/// when the program cannot be started (missing, not executable, a working directory that is not).
ProcessResult RunProcess(const ProcessRequest& request);

}  // namespace sonicboom
