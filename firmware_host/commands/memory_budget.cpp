#include "commands/memory_budget.hpp"

#include <CLI/CLI.hpp>
#include <cstdio>
#include <limits>

namespace blockmap::cli {
namespace {

constexpr double kBytesPerMiB = 1024.0 * 1024.0;
// A tebibyte: more than any machine this runs on has.
constexpr double kMaxBudgetMiB = 1024.0 * 1024.0;

}  // namespace

void add_budget_option(CLI::App& command, double& budget_mib) {
  command
      .add_option("--budget-mib", budget_mib,
                  "the memory budget the configured capacities must fit in")
      ->check(CLI::PositiveNumber & CLI::Range(0.0, kMaxBudgetMiB))
      ->capture_default_str();
}

std::size_t mib_bytes(double mib) noexcept {
  const double bytes = mib * kBytesPerMiB;
  constexpr std::size_t kMaxBytes = std::numeric_limits<std::size_t>::max() / 2;
  return bytes < static_cast<double>(kMaxBytes) ? static_cast<std::size_t>(bytes) : kMaxBytes;
}

std::string over_budget(std::size_t needed_bytes, double budget_mib) {
  char text[160];
  std::snprintf(text, sizeof text,
                "the configured capacities need %.1f MiB, over the %.1f MiB budget "
                "(--budget-mib, or smaller capacities)",
                static_cast<double>(needed_bytes) / kBytesPerMiB, budget_mib);
  return text;
}

}  // namespace blockmap::cli
