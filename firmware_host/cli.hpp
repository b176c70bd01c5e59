// The `blockmap` command line (docs/formats.md, command line, lists the contract).
#pragma once

#include <iosfwd>

namespace blockmap::cli {

// Exit statuses: 0 success, 1 the command ran and failed (bad input data, a device error),
// 2 the command line itself was wrong.
inline constexpr int kExitOk = 0;
inline constexpr int kExitFailure = 1;
inline constexpr int kExitUsage = 2;

// Parses argv and runs the chosen subcommand. Results go to `out`; diagnostics, including the
// one-line error for a bad command line, go to `err`.
int run(int argc, const char* const* argv, std::ostream& out, std::ostream& err);

// "blockmap 0.1.0 (x86_64 Linux, GNU 12.2.0, Release)"
[[nodiscard]] const char* version_line();

}  // namespace blockmap::cli
