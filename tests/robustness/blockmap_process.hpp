// `blockmap` run as a process of its own, as a user runs it: its exit status or the signal that
// ended it, its stdout and stderr, whether it overran a time limit, and its peak memory.
#pragma once

#include <fcntl.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <chrono>
#include <csignal>
#include <filesystem>
#include <string>
#include <vector>

namespace blockmap::testing {

struct ProcessLimits {
  double timeout_s = 10.0;
  // RLIMIT_FSIZE: the largest file the process may write (0: no limit); past it a write fails
  // with EFBIG, as on a full disk.
  std::size_t max_file_bytes = 0;
  std::string stdout_path;  // a file that stdout goes to (empty: captured)
};

struct ProcessResult {
  bool exited = false;  // false: a signal ended it (an abort, a crash) or the time limit did
  int status = -1;      // its exit status when it exited
  int signal = 0;       // the signal that ended it
  bool timed_out = false;
  double seconds = 0.0;
  std::size_t peak_rss_bytes = 0;
  std::string out;
  std::string err;
};

// Reads what is there on `fd` into `text`; false at its end.
inline bool drain(int fd, std::string& text) {
  char buffer[4096];
  const ssize_t got = ::read(fd, buffer, sizeof buffer);
  if (got > 0) {
    text.append(buffer, static_cast<std::size_t>(got));
  }
  return got > 0 || (got < 0 && errno == EINTR);
}

// Runs `exe` with `args` in `dir`. Its stdout and stderr come through pipes, which no file
// size limit touches.
inline ProcessResult run_process(const std::string& exe, const std::vector<std::string>& args,
                                 const std::filesystem::path& dir, const ProcessLimits& limits) {
  int out_pipe[2] = {-1, -1};
  int err_pipe[2] = {-1, -1};
  if (::pipe(out_pipe) != 0 || ::pipe(err_pipe) != 0) {
    return {};
  }
  const auto start = std::chrono::steady_clock::now();
  const pid_t pid = ::fork();
  if (pid == 0) {
    int out = out_pipe[1];
    if (!limits.stdout_path.empty()) {
      out = ::open(limits.stdout_path.c_str(), O_WRONLY);
    }
    if (::chdir(dir.c_str()) != 0 || out < 0 || ::dup2(out, 1) < 0 || ::dup2(err_pipe[1], 2) < 0) {
      ::_exit(127);
    }
    ::close(out_pipe[0]);
    ::close(err_pipe[0]);
    if (limits.max_file_bytes > 0) {
      const rlimit file_size{limits.max_file_bytes, limits.max_file_bytes};
      ::setrlimit(RLIMIT_FSIZE, &file_size);
      ::signal(SIGXFSZ, SIG_IGN);
    }
    std::vector<char*> argv;
    argv.push_back(const_cast<char*>(exe.c_str()));
    for (const std::string& arg : args) {
      argv.push_back(const_cast<char*>(arg.c_str()));
    }
    argv.push_back(nullptr);
    ::execv(exe.c_str(), argv.data());
    ::_exit(127);
  }
  ::close(out_pipe[1]);
  ::close(err_pipe[1]);
  ProcessResult result;
  pollfd fds[2] = {{out_pipe[0], POLLIN, 0}, {err_pipe[0], POLLIN, 0}};
  bool open[2] = {true, true};
  std::string* texts[2] = {&result.out, &result.err};
  while (open[0] || open[1]) {
    const double elapsed =
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    if (!result.timed_out && elapsed > limits.timeout_s) {
      result.timed_out = true;
      ::kill(pid, SIGKILL);
    }
    constexpr int kPollMs = 20;
    if (::poll(fds, 2, kPollMs) <= 0) {
      continue;
    }
    for (int i = 0; i < 2; ++i) {
      if (open[i] && (fds[i].revents & (POLLIN | POLLHUP | POLLERR)) != 0) {
        open[i] = drain(fds[i].fd, *texts[i]);
        fds[i].fd = open[i] ? fds[i].fd : -1;
      }
    }
  }
  ::close(out_pipe[0]);
  ::close(err_pipe[0]);
  int status = 0;
  rusage usage{};
  ::wait4(pid, &status, 0, &usage);
  result.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  result.exited = WIFEXITED(status) && !result.timed_out;
  result.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  result.signal = WIFSIGNALED(status) ? WTERMSIG(status) : 0;
  result.peak_rss_bytes = static_cast<std::size_t>(usage.ru_maxrss) * 1024;
  return result;
}

}  // namespace blockmap::testing
