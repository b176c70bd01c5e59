// SIGINT and SIGTERM, for as long as one of these lives, call `handler` (which must be
// async-signal-safe: set an atomic flag) instead of ending the process; then the defaults are
// back. The daemon and `blockmap play` stop cleanly on them.
#pragma once

#include <csignal>

namespace blockmap::cli::daemon {

class StopSignals {
 public:
  explicit StopSignals(void (*handler)(int)) {
    struct sigaction action {};
    action.sa_handler = handler;
    sigemptyset(&action.sa_mask);
    sigaction(SIGINT, &action, nullptr);
    sigaction(SIGTERM, &action, nullptr);
  }
  ~StopSignals() {
    signal(SIGINT, SIG_DFL);
    signal(SIGTERM, SIG_DFL);
  }
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;
};

}  // namespace blockmap::cli::daemon
