// objscan: the command line. Parses flags, calls the library, prints, chooses the exit code
// (README, "Exit codes"). Nothing else lives here.

#include <CLI/CLI.hpp>
#include <csignal>
#include <cstdio>
#include <stdexcept>
#include <string>
#include <vector>

#include "commands.h"
#include "exit_codes.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/pipeline/fuse.h"
#include "options.h"

namespace {

using namespace objscan::app;

constexpr const char* kVersion = OBJSCAN_VERSION;

/// One line on stderr, whatever the message holds.
void printError(const std::string& message) {
  std::string line = message;
  for (char& c : line) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  std::fprintf(stderr, "objscan: error: %s\n", line.c_str());
}

int run(int argc, char** argv) {
  CLI::App app{
      "objscan: turn an RGB-D capture into a fused mesh and a ranked list of the objects in it.",
      "objscan"};
  bool version = false;
  app.add_flag("--version", version, "Print the version and exit");
  app.require_subcommand(0, 1);
  app.fallthrough();
  bool verbose = false;
  bool quiet = false;
  auto* verbose_flag = app.add_flag("-v,--verbose", verbose, "Log details to stderr");
  app.add_flag("-q,--quiet", quiet, "Log only errors to stderr (no progress)")
      ->excludes(verbose_flag);
  app.footer(
      "Exit codes: 0 success, 1 runtime failure, 2 bad usage or bad input, 3 no sensor attached,\n"
      "130 interrupted (Ctrl-C; what was written is complete).\n"
      "Run 'objscan <command> --help' for a command's options.\n");
  addConfigOption(app);
  const std::vector<Command> commands = {
      addInfoCommand(app),   addSynthCommand(app),    addDevicesCommand(app), addRecordCommand(app),
      addFuseCommand(app),   addDiscoverCommand(app), addEvalCommand(app),    addTrainCommand(app),
      addRenderCommand(app), addScanCommand(app)};

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    printError(std::string(e.what()) + " (run 'objscan --help')");
    return kExitBadInput;
  }
  if (version) {
    std::printf("objscan %s\n", kVersion);
    return kExitSuccess;
  }
  objscan::log::setLevel(quiet     ? objscan::log::Level::kError
                         : verbose ? objscan::log::Level::kDebug
                                   : objscan::log::Level::kInfo);
  for (const Command& command : commands) {
    if (command.sub->parsed()) return command.run();
  }
  printError("a command is required (run 'objscan --help')");
  return kExitBadInput;
}

}  // namespace

int main(int argc, char** argv) {
  // Past a file-size limit (ulimit -f) a write then fails with EFBIG, which every writer reports
  // and cleans up after as it does a full disk, instead of SIGXFSZ killing the process mid-file.
  std::signal(SIGXFSZ, SIG_IGN);
  try {
    const int code = run(argc, argv);
    // Output piped to a full disk or a closed pipe must not look like success.
    if (std::fflush(stdout) != 0 || std::ferror(stdout)) {
      printError("cannot write to standard output");
      return kExitRuntimeFailure;
    }
    return code;
  } catch (const objscan::pipeline::Interrupted& e) {
    printError(e.what());
    return kExitInterrupted;
  } catch (const objscan::InputError& e) {
    printError(e.what());
    return kExitBadInput;
  } catch (const std::invalid_argument& e) {
    printError(e.what());
    return kExitBadInput;
  } catch (const objscan::NoSensorError& e) {
    printError(e.what());
    return kExitNoSensor;
  } catch (const std::exception& e) {
    printError(e.what());
    return kExitRuntimeFailure;
  }
}
