#pragma once

#include <functional>
#include <memory>
#include <string>
#include <vector>

// CLI11 is included by the sources that build the command line: it takes seconds to compile
// at -O3, and most sources that include this header do not use it.
namespace CLI {
class App;
}  // namespace CLI

/// The subcommands of `objscan`: each adds its flags to the command line and returns what to run
/// once they are parsed.
namespace objscan::app {

struct Command {
  CLI::App* sub = nullptr;
  std::function<int()> run;  ///< returns the exit code
};

Command addInfoCommand(CLI::App& app);
Command addDevicesCommand(CLI::App& app);
Command addSynthCommand(CLI::App& app);
Command addRecordCommand(CLI::App& app);
Command addFuseCommand(CLI::App& app);
Command addDiscoverCommand(CLI::App& app);
Command addEvalCommand(CLI::App& app);
Command addTrainCommand(CLI::App& app);
Command addRenderCommand(CLI::App& app);
Command addScanCommand(CLI::App& app);
Command addViewCommand(CLI::App& app);
/// `scan_args`: what follows `--` on the command line (run() takes it off before parsing), the
/// options of every scan.
Command addBatchCommand(CLI::App& app, std::shared_ptr<const std::vector<std::string>> scan_args);

}  // namespace objscan::app
