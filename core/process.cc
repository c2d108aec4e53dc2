// Child processes from an argument vector: posix_spawn with pipes for stdin, stdout and stderr,
// read together with poll so a child that fills one pipe cannot stall on the other.
#include "sonicboom/core/process.h"

#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <csignal>
#include <cstring>
#include <map>

#include <fmt/format.h>

#include "sonicboom/core/errors.h"

extern char** environ;

namespace sonicboom {
namespace {

// A pipe whose ends close with the object.
struct Pipe {
  std::array<int, 2> fd{-1, -1};
  Pipe() {
    if (pipe2(fd.data(), O_CLOEXEC) != 0) {
      throw IoError(fmt::format("cannot make a pipe: {}", std::strerror(errno)));
    }
  }
  ~Pipe() {
    CloseRead();
    CloseWrite();
  }
  void CloseRead() { Close(0); }
  void CloseWrite() { Close(1); }
  void Close(int i) {
    if (fd[i] >= 0) ::close(fd[i]);
    fd[i] = -1;
  }
};

// The parent's environment with the request's changes applied, as NAME=VALUE strings.
std::vector<std::string> ChildEnvironment(const ProcessRequest& request) {
  std::map<std::string, std::string> vars;
  for (char** e = environ; e != nullptr && *e != nullptr; ++e) {
    const std::string entry(*e);
    const size_t eq = entry.find('=');
    if (eq != std::string::npos) vars[entry.substr(0, eq)] = entry.substr(eq + 1);
  }
  for (const auto& [name, value] : request.env) {
    if (value) {
      vars[name] = *value;
    } else {
      vars.erase(name);
    }
  }
  std::vector<std::string> out;
  for (const auto& [name, value] : vars) out.push_back(name + "=" + value);
  return out;
}

// NULL-terminated char* views of strings that outlive the spawn.
std::vector<char*> Pointers(std::vector<std::string>& strings) {
  std::vector<char*> p;
  for (std::string& s : strings) p.push_back(s.data());
  p.push_back(nullptr);
  return p;
}

// Feeds stdin and drains stdout and stderr until both close.
void Exchange(Pipe& in, Pipe& out, Pipe& err, const std::string& input, ProcessResult* result) {
  size_t written = 0;
  if (input.empty()) in.CloseWrite();
  std::array<char, 65536> buf{};
  while (out.fd[0] >= 0 || err.fd[0] >= 0) {
    std::array<pollfd, 3> fds{};
    fds[0] = {out.fd[0], POLLIN, 0};
    fds[1] = {err.fd[0], POLLIN, 0};
    fds[2] = {in.fd[1], POLLOUT, 0};
    if (poll(fds.data(), fds.size(), -1) < 0) {
      if (errno == EINTR) continue;
      throw IoError(fmt::format("poll on a child's pipes: {}", std::strerror(errno)));
    }
    for (int i = 0; i < 2; ++i) {
      if ((fds[i].revents & (POLLIN | POLLHUP | POLLERR)) == 0) continue;
      Pipe& p = i == 0 ? out : err;
      const ssize_t n = ::read(p.fd[0], buf.data(), buf.size());
      if (n > 0) {
        (i == 0 ? result->out : result->err).append(buf.data(), static_cast<size_t>(n));
      } else if (n == 0 || errno != EINTR) {
        p.CloseRead();
      }
    }
    if (in.fd[1] >= 0 && (fds[2].revents & (POLLOUT | POLLERR | POLLHUP)) != 0) {
      const ssize_t n = ::write(in.fd[1], input.data() + written, input.size() - written);
      if (n > 0) written += static_cast<size_t>(n);
      if (n < 0 || written == input.size()) in.CloseWrite();
    }
  }
}

}  // namespace

std::string ProcessResult::Ending() const {
  if (signal_number != 0) {
    const char* name = sigabbrev_np(signal_number);
    return fmt::format("killed by signal {} (SIG{})", signal_number, name ? name : "?");
  }
  return fmt::format("exit status {}", exit_code);
}

std::string ProcessResult::LastErrLine() const {
  size_t end = err.find_last_not_of(" \t\r\n");
  if (end == std::string::npos) return "";
  const size_t start = err.rfind('\n', end);
  return err.substr(start == std::string::npos ? 0 : start + 1,
                    end - (start == std::string::npos ? 0 : start + 1) + 1);
}

ProcessResult RunProcess(const ProcessRequest& request) {
  if (request.argv.empty()) throw IoError("RunProcess: no program given");
  Pipe in, out, err;
  posix_spawn_file_actions_t actions;
  posix_spawn_file_actions_init(&actions);
  posix_spawn_file_actions_adddup2(&actions, in.fd[0], STDIN_FILENO);
  posix_spawn_file_actions_adddup2(&actions, out.fd[1], STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&actions, err.fd[1], STDERR_FILENO);
  if (!request.cwd.empty()) posix_spawn_file_actions_addchdir_np(&actions, request.cwd.c_str());
  std::vector<std::string> argv = request.argv;
  std::vector<std::string> env = ChildEnvironment(request);
  std::vector<char*> argv_p = Pointers(argv);
  std::vector<char*> env_p = Pointers(env);
  // a name without a slash is looked up in PATH, as a shell would
  const bool search = request.argv[0].find('/') == std::string::npos;
  pid_t pid = 0;
  const int rc = search ? posix_spawnp(&pid, argv_p[0], &actions, nullptr, argv_p.data(),
                                       env_p.data())
                        : posix_spawn(&pid, argv_p[0], &actions, nullptr, argv_p.data(),
                                      env_p.data());
  posix_spawn_file_actions_destroy(&actions);
  if (rc != 0) {
    const std::string where = request.cwd.empty() ? "" : " in " + request.cwd;
    throw IoError(fmt::format("{}: cannot be started{}: {}", request.argv[0], where,
                              std::strerror(rc)));
  }
  in.CloseRead();
  out.CloseWrite();
  err.CloseWrite();
  ProcessResult result;
  // a child that exits before reading its stdin must not end this process with SIGPIPE
  const std::string input = request.stdin_text.value_or("");
  void (*previous)(int) = input.empty() ? SIG_DFL : std::signal(SIGPIPE, SIG_IGN);
  Exchange(in, out, err, input, &result);
  if (!input.empty()) std::signal(SIGPIPE, previous);
  int status = 0;
  while (waitpid(pid, &status, 0) < 0 && errno == EINTR) {
  }
  if (WIFEXITED(status)) {
    result.exit_code = WEXITSTATUS(status);
  } else if (WIFSIGNALED(status)) {
    result.signal_number = WTERMSIG(status);
  }
  return result;
}

}  // namespace sonicboom
