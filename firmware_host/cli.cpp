#include "cli.hpp"

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <new>
#include <ostream>
#include <string>
#include <vector>

#include "blockmap_build_info.hpp"
#include "commands/commands.hpp"

namespace blockmap::cli {
namespace {

std::string make_version_line() {
  return std::string("blockmap ") + build_info::kVersion + " (" + build_info::kTargetProcessor +
         " " + build_info::kTargetSystem + ", " + build_info::kCompiler + ", " +
         build_info::kBuildType + (build_info::kSanitized ? ", ASan+UBSan" : "") + ")";
}

// A parse error as one line: the reason, and where to look.
void print_usage_error(std::ostream& err, const CLI::Error& error) {
  std::string reason = error.what();
  std::replace(reason.begin(), reason.end(), '\n', ' ');
  err << "blockmap: " << reason << " (see 'blockmap --help')\n";
}

// CLI11 reads "nan" and "inf" as floats, and a range check lets NaN through.
CLI::Validator finite_number() {
  return {[](const std::string& text) -> std::string {
            const double value = std::strtod(text.c_str(), nullptr);
            return std::isfinite(value) ? std::string() : "'" + text + "' is not a finite number";
          },
          ""};
}

// CLI11 wraps "-1" into an unsigned option as 2^64 - 1.
CLI::Validator unsigned_number() {
  return {[](const std::string& text) -> std::string {
            const bool digits =
                !text.empty() && text.find_first_not_of("0123456789") == std::string::npos;
            return digits ? std::string() : "'" + text + "' is not a whole number >= 0";
          },
          ""};
}

// Every number option of every command is checked the same way, so that a new option is too.
void check_numbers(CLI::App& app) {
  for (CLI::App* command : app.get_subcommands([](CLI::App*) { return true; })) {
    for (CLI::Option* option : command->get_options()) {
      const std::string type = option->get_type_name();
      if (type.rfind("FLOAT", 0) == 0) {
        option->check(finite_number());
      } else if (type.rfind("UINT", 0) == 0) {
        option->check(unsigned_number());
      }
    }
  }
}

// Each command reports what it expects to go wrong; anything else still ends as one line and
// a failure status, never as an abort.
int run_command(const Command& command, std::ostream& out, std::ostream& err) {
  const std::string name = command.subcommand->get_name();
  try {
    return command.action(out, err);
  } catch (const std::bad_alloc&) {
    err << "blockmap: " << name << ": out of memory\n";
  } catch (const std::exception& error) {
    std::string reason = error.what();
    std::replace(reason.begin(), reason.end(), '\n', ' ');
    err << "blockmap: " << name << ": " << reason << '\n';
  }
  return kExitFailure;
}

}  // namespace

const char* version_line() {
  static const std::string line = make_version_line();
  return line.c_str();
}

int run(int argc, const char* const* argv, std::ostream& out, std::ostream& err) {
  CLI::App app{
      "blockmap: an onboard, streaming geometric 3D mapper for mobile robots.\n"
      "Turns odometry, IMU, GPS and laser streams into walls, roofs and buildings.",
      "blockmap"};
  app.set_version_flag("--version", version_line(), "Print the version and build, then exit");
  app.require_subcommand(1, 1);
  app.fallthrough(false);

  const std::vector<Command> commands = {add_info_command(app),     add_decode_command(app),
                                         add_planes_command(app),   add_buildings_command(app),
                                         add_simulate_command(app), add_replay_command(app),
                                         add_import_command(app),   add_run_command(app),
                                         add_play_command(app),     add_score_command(app)};
  check_numbers(app);

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& help) {
    return app.exit(help, out, err);
  } catch (const CLI::CallForAllHelp& help) {
    return app.exit(help, out, err);
  } catch (const CLI::CallForVersion&) {
    out << version_line() << '\n';
    return kExitOk;
  } catch (const CLI::ParseError& error) {
    // CLI11 reports a misspelt subcommand as a missing one; name the word the user typed.
    const std::vector<std::string> unparsed = app.remaining();
    if (app.get_subcommands().empty() && !unparsed.empty() && unparsed.front().front() != '-') {
      err << "blockmap: unknown subcommand '" << unparsed.front() << "' (see 'blockmap --help')\n";
    } else {
      print_usage_error(err, error);
    }
    return kExitUsage;
  }

  for (const Command& command : commands) {
    if (command.subcommand->parsed()) {
      return run_command(command, out, err);
    }
  }
  err << "blockmap: no subcommand ran (see 'blockmap --help')\n";
  return kExitUsage;
}

}  // namespace blockmap::cli
