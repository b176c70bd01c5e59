// `blockmap info`: which build this is and what the machine under it offers, so that a
// deployment on the robot can be checked at a glance (is this the armhf build? sanitized?).
#include <CLI/CLI.hpp>
#include <atomic>
#include <cstdint>
#include <ostream>
#include <thread>

#include "blockmap/core/memory.hpp"
#include "blockmap/hal/linux/steady_clock.hpp"
#include "blockmap_build_info.hpp"
#include "cli.hpp"
#include "commands/commands.hpp"

namespace blockmap::cli {

Command add_info_command(CLI::App& app) {
  CLI::App* info = app.add_subcommand(
      "info", "Print the build and the machine's properties that the runtime relies on");
  return {info, [](std::ostream& out, std::ostream& /*err*/) {
            const hal::linux_backend::SteadyClock clock;
            out << version_line() << '\n'
                << "eigen: " << build_info::kEigenVersion << '\n'
                << "pointer_bits: " << sizeof(void*) * 8 << '\n'
                << "lock_free_64bit_counters: "
                << (std::atomic<std::uint64_t>::is_always_lock_free ? "yes" : "no") << '\n'
                << "cache_line_bytes_assumed: " << kCacheLineBytes << '\n'
                << "hardware_threads: " << std::thread::hardware_concurrency() << '\n'
                << "monotonic_clock_s: " << seconds_from_ns(clock.now_ns()) << '\n';
            return kExitOk;
          }};
}

}  // namespace blockmap::cli
