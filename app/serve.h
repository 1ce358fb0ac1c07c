#pragma once

#include <memory>
#include <optional>
#include <string>

#include "objscan/pipeline/fuse.h"
#include "objscan/pipeline/scan.h"
#include "objscan/server/live_server.h"
#include "objscan/server/live_session.h"

// CLI11 is included by the sources that build the command line: it takes seconds to compile
// at -O3, and most sources that include this header do not use it.
namespace CLI {
class App;
}  // namespace CLI

/// `--serve [ADDR:]PORT` for fuse and scan: the live session and its server, started before the
/// source is opened and kept after the run until Ctrl-C (or --serve-wait), so that the page can
/// show the final results and link the report.
namespace objscan::app {

struct ServeOptions {
  std::string address;              ///< --serve; empty: nothing of the live page runs
  std::optional<double> wait_s;     ///< --serve-wait; nothing: serve the results until Ctrl-C
  bool discovery = true;            ///< --no-live-discovery clears it
  double discovery_interval_s = 3;  ///< --live-discovery-every
};

/// --serve, --serve-wait, --no-live-discovery, --live-discovery-every.
void addServeOptions(CLI::App* sub, ServeOptions& o);

/// A live session and its server, for one command run; it watches the scan (frames, stages).
class LiveRun : public pipeline::ScanObserver {
 public:
  /// Nothing when options.address is empty. Otherwise starts the server (std::invalid_argument,
  /// exit 2, when it cannot listen) and prints its address.
  static std::unique_ptr<LiveRun> start(const ServeOptions& options, server::LiveSettings settings);

  /// Makes fusion report every frame to the session.
  void watchFusion(pipeline::FusionHooks& hooks) override;
  /// The stages after fusion (setStage ends the session's online discovery).
  void stageStarted(pipeline::ScanStage stage) override;
  /// The run is over: the page shows `final`; then, with `keep_serving`, serves the results until
  /// Ctrl-C or --serve-wait (a run stopped by Ctrl-C ends at once).
  void finish(server::LiveFinal final, bool keep_serving = true);

 private:
  LiveRun(const ServeOptions& options, const server::ServeAddress& address,
          server::LiveSettings settings);
  ServeOptions options_;
  server::LiveSession session_;
  server::LiveServer server_;
};

}  // namespace objscan::app
