// objscan: the command line. Parses flags, calls the library, prints, chooses the exit code
// (README, "Exit codes"). Nothing else lives here.

#include <algorithm>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <new>
#include <stdexcept>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#ifdef OBJSCAN_MIMALLOC
#include <mimalloc.h>
#endif

#include "commands.h"
#include "exit_codes.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/memory.h"
#include "objscan/pipeline/fuse.h"
#include "options.h"
#include "shell_docs.h"

#ifdef OBJSCAN_MIMALLOC
// Debian's mimalloc is built as C: its operator new ends the process with abort() when memory runs
// out, where the C++ one throws std::bad_alloc, which main reports in one line (exit 1). These
// throwing forms take its place (a program's own definitions come before any library's); the
// rest (delete, the nothrow forms) stay mimalloc's, on the same heap.
void* operator new(std::size_t bytes) {
  if (void* p = mi_malloc(bytes)) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t bytes) { return ::operator new(bytes); }
void* operator new(std::size_t bytes, std::align_val_t alignment) {
  if (void* p = mi_malloc_aligned(bytes, static_cast<std::size_t>(alignment))) return p;
  throw std::bad_alloc();
}
void* operator new[](std::size_t bytes, std::align_val_t alignment) {
  return ::operator new(bytes, alignment);
}
#endif

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
  bool man = false;
  std::string completion;
  app.add_flag("--man", man, "Print the man page objscan(1) (roff) and exit");
  app.add_option("--completion", completion, "Print the completion script for SHELL and exit")
      ->check(CLI::IsMember({"bash"}))
      ->type_name("SHELL");
  app.require_subcommand(0, 1);
  app.fallthrough();
  bool verbose = false;
  bool quiet = false;
  auto* verbose_flag = app.add_flag("-v,--verbose", verbose, "Log details to stderr");
  app.add_flag("-q,--quiet", quiet,
               "Errors only: no progress, warnings or summary (info and devices still print "
               "what they find)")
      ->excludes(verbose_flag);
  app.footer(
      "Exit codes: 0 success, 1 runtime failure, 2 bad usage or bad input, 3 no sensor attached,\n"
      "130 interrupted (Ctrl-C; what was written is complete).\n"
      "Run 'objscan <command> --help' for a command's options.\n");
  addConfigOption(app);
  const auto batch_scan_args = std::make_shared<std::vector<std::string>>();
  const std::vector<Command> commands = {
      addInfoCommand(app),   addSynthCommand(app), addDevicesCommand(app),
      addRecordCommand(app), addFuseCommand(app),  addDiscoverCommand(app),
      addEvalCommand(app),   addTrainCommand(app), addRenderCommand(app),
      addScanCommand(app),   addViewCommand(app),  addBatchCommand(app, batch_scan_args)};

  // "objscan help [COMMAND]" is "objscan [COMMAND] --help", as git and cargo have it.
  std::vector<std::string> args(argv + 1, argv + argc);
  if (!args.empty() && args[0] == "help") {
    args.erase(args.begin());
    if (!args.empty() && std::none_of(commands.begin(), commands.end(), [&](const Command& c) {
          return c.sub->get_name() == args[0];
        })) {
      printError("help: no command '" + args[0] + "' (run 'objscan --help' for the list)");
      return kExitBadInput;
    }
    args.resize(std::min<std::size_t>(args.size(), 1));
    args.emplace_back("--help");
  }
  // `objscan batch ... -- SCAN OPTIONS`: what follows -- is every scan's, not batch's.
  const auto dashes = std::find(args.begin(), args.end(), std::string("--"));
  if (std::find(args.begin(), dashes, std::string("batch")) != dashes && dashes != args.end()) {
    batch_scan_args->assign(dashes + 1, args.end());
    args.erase(dashes, args.end());
  }
  std::reverse(args.begin(), args.end());  // CLI11 takes its vector in reverse order
  try {
    app.parse(args);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    std::string help = "objscan --help";
    for (const Command& command : commands) {
      if (command.sub->parsed()) help = "objscan " + command.sub->get_name() + " --help";
    }
    printError(std::string(e.what()) + " (run '" + help + "')");
    return kExitBadInput;
  }
  if (version) {
    std::printf("objscan %s\n", kVersion);
    return kExitSuccess;
  }
  if (man || !completion.empty()) {
    const std::string text = man ? manPage(app, kVersion) : bashCompletion(app);
    std::fwrite(text.data(), 1, text.size(), stdout);
    return kExitSuccess;
  }
  objscan::log::setLevel(quiet     ? objscan::log::Level::kError
                         : verbose ? objscan::log::Level::kDebug
                                   : objscan::log::Level::kInfo);
  objscan::availableMemoryBytes();  // an OBJSCAN_MEMORY_LIMIT that is no size: before any work
  for (const Command& command : commands) {
    if (!command.sub->parsed()) continue;
    const std::string name = command.sub->get_name();
    if (quiet && name != "info" && name != "devices") {
      // --quiet: errors only. The summary a command prints is a report, not its result (info's
      // and devices' output is their result, so they keep it); the files say everything.
      if (std::freopen("/dev/null", "w", stdout) == nullptr) {
        printError("--quiet: cannot silence standard output");
        return kExitRuntimeFailure;
      }
    }
    return command.run();
  }
  printError("a command is required (run 'objscan --help')");
  return kExitBadInput;
}

}  // namespace

int main(int argc, char** argv) {
#ifdef OBJSCAN_MIMALLOC
  // Memory from here on comes in 2 MB pages (transparent huge pages, where the kernel allows them
  // on request): a page fault then maps 512 times as much. MIMALLOC_LARGE_OS_PAGES=0 overrides.
  if (std::getenv("MIMALLOC_LARGE_OS_PAGES") == nullptr) {
    mi_option_set_enabled(mi_option_large_os_pages, true);
  }
#endif
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
  } catch (const std::filesystem::filesystem_error& e) {
    // A path given on the command line that cannot be looked at (a symbolic link loop, a folder
    // without search permission): name it and the reason, not the library's "filesystem error:
    // status: ..." text. objscan's own writes report OutputError, never this.
    printError((e.path1().empty() ? std::string("a path") : e.path1().string()) + ": " +
               e.code().message());
    return kExitBadInput;
  } catch (const std::bad_alloc&) {
    printError(
        "out of memory: the input is too large for this machine (a larger --voxel-size, or "
        "fewer or smaller scenes, need less)");
    return kExitRuntimeFailure;
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
