#include "serve.h"

#include <chrono>
#include <cstdio>
#include <optional>
#include <thread>
#include <utility>

#include <CLI/CLI.hpp>

#include "objscan/core/clock.h"
#include "objscan/core/log.h"
#include "options.h"
#include "stop_signals.h"

namespace objscan::app {

void addServeOptions(CLI::App* sub, ServeOptions& o) {
  sub->add_option("--serve", o.address,
                  "Show the scan live in a browser at http://ADDR:PORT/ ([ADDR:]PORT; ADDR "
                  "defaults to 127.0.0.1, PORT 0 takes any free port), with the objects found "
                  "while it runs");
  sub->add_option("--serve-wait", o.wait_s,
                  "With --serve: after the run, keep serving the results this many seconds "
                  "(default: until Ctrl-C)")
      ->check(CLI::NonNegativeNumber);
  sub->add_flag("--no-live-discovery", [&o](std::int64_t) { o.discovery = false; },
                "With --serve: do not look for objects while fusing");
  sub->add_option("--live-discovery-every", o.discovery_interval_s,
                  "With --serve: seconds between online discovery rounds (default 3)")
      ->check(positiveNumber());
}

std::unique_ptr<LiveRun> LiveRun::start(const ServeOptions& options,
                                        server::LiveSettings settings) {
  if (options.address.empty()) return nullptr;
  const server::ServeAddress address = server::parseServeAddress(options.address);
  settings.discovery = options.discovery;
  settings.discovery_interval_s = options.discovery_interval_s;
  std::unique_ptr<LiveRun> run(new LiveRun(options, address, std::move(settings)));
  if (address.host.rfind("127.", 0) != 0) {
    log::warning("--serve " + options.address + ": the live page and the results folder can be " +
                 "read by anyone who reaches this machine on that port (there is no password)");
  }
  std::printf("live page     %s\n", run->server_.url().c_str());
  std::fflush(stdout);
  return run;
}

LiveRun::LiveRun(const ServeOptions& options, const server::ServeAddress& address,
                 server::LiveSettings settings)
    : options_(options), session_(std::move(settings)), server_(session_, address) {}

void LiveRun::stageStarted(pipeline::ScanStage stage) {
  if (stage != pipeline::ScanStage::kFusing) session_.setStage(pipeline::toString(stage));
}

void LiveRun::watchFusion(pipeline::FusionHooks& hooks) {
  hooks.on_frame = [this](const pipeline::FrameEvent& e) { session_.onFrame(e); };
  hooks.extra_memory_bytes = [this] { return session_.extraMemoryBytes(); };
  hooks.before_meshing = [this] { session_.setStage("meshing the volume"); };
}

void LiveRun::finish(server::LiveFinal final, bool keep_serving) {
  const bool linger = keep_serving && !(options_.wait_s && *options_.wait_s <= 0.0);
  // A Ctrl-C after the capture ended (on a sensor, the first one ends capture and is cleared)
  // but before the results were shown asks to end: no waiting.
  const bool asked_to_end = StopSignals::stopRequested();
  // The handlers go in before the final state is published: whoever watches the page may stop
  // the server the moment it sees the end, and must not meet the default action (exit 143).
  std::optional<StopSignals> signals;
  if (linger && !asked_to_end) signals.emplace();
  session_.finish(std::move(final));
  if (!linger) {
    // A page that is watching learns the end before the server goes (its long poll is answered
    // at once); at most 1.5 s, and not at all when no page asked lately.
    const auto start = SteadyClock::now();
    while (session_.pageActive() && !session_.finalServed() && secondsSince(start) < 1.5) {
      std::this_thread::sleep_for(std::chrono::milliseconds(20));
    }
    return;
  }
  if (asked_to_end) return;
  char how_long[64] = "until Ctrl-C";
  if (options_.wait_s) std::snprintf(how_long, sizeof how_long, "for %g s", *options_.wait_s);
  std::printf("live page     %s shows the results %s\n", server_.url().c_str(), how_long);
  std::fflush(stdout);
  StopSignals::waitForStop(options_.wait_s);
}

}  // namespace objscan::app
