// The memory a command may take (--budget-mib): `run` and `replay` size the mapper's arena
// within it, `planes` and `buildings` the cloud file and the detector's arena. Capacities are
// checked against it before anything is allocated, and a configuration over it is refused.
#pragma once

#include <cstddef>
#include <string>

namespace CLI {
class App;
}

namespace blockmap::cli {

// The onboard mapper's budget (docs/mapper.md, Memory).
inline constexpr double kDefaultMapperBudgetMiB = 64.0;
// `planes` and `buildings`, offline, on clouds of a city's scans.
inline constexpr double kDefaultOfflineBudgetMiB = 1024.0;

// --budget-mib, a positive number of MiB, into `budget_mib` (its default shown in --help).
void add_budget_option(CLI::App& command, double& budget_mib);

[[nodiscard]] std::size_t mib_bytes(double mib) noexcept;

// "the configured capacities need N MiB, over the B MiB budget (--budget-mib, or smaller
// capacities)"
[[nodiscard]] std::string over_budget(std::size_t needed_bytes, double budget_mib);

}  // namespace blockmap::cli
