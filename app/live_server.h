#pragma once

#include <memory>
#include <string>

#include "live_session.h"

/// The HTTP server behind `--serve`: civetweb (Debian's libcivetweb), a small, long-maintained C
/// library whose worker threads, connection queue, request size cap and connection timeout are
/// run-time options, which is what keeps many, slow or huge requests away from the scan; a shared
/// library, so Debian's security fixes reach objscan without a rebuild (cpp-httplib is
/// header-only; Boost.Beast is a toolkit, not a server). docs/live.md has the choice in full.
/// civetweb stays inside live_server.cpp.
namespace objscan::app {

/// Where `--serve [ADDR:]PORT` listens. The address is 127.0.0.1 unless one is given; port 0
/// takes any free port.
struct ServeAddress {
  std::string host = "127.0.0.1";
  int port = 0;
};

/// Parses "[ADDR:]PORT" (an IPv4 address or "localhost", and a port 0 to 65535). Throws
/// std::invalid_argument naming the text and what is wrong.
ServeAddress parseServeAddress(const std::string& text);

/// Serves the live page for `session` until destroyed. Routes (GET and HEAD only):
///   /                 the page
///   /api/state        the state as JSON; ?after=N waits up to a second for a newer one
///   /api/model.jpg    the model from the current pose, hypotheses painted
///   /api/color.jpg    the current colour frame
///   /results/NAME     a file of the results folder, read-only (no folder listings, no hidden
///                     files, nothing outside it)
/// Everything else is 404 (405 for other methods); a request over 16 kB is refused by civetweb.
class LiveServer {
 public:
  /// Starts listening. Throws std::invalid_argument (exit 2) when it cannot: the port is in use
  /// or not permitted, or the address is not this machine's.
  LiveServer(LiveSession& session, const ServeAddress& address);
  ~LiveServer();  ///< stops serving: open requests end, and no new one is taken
  LiveServer(const LiveServer&) = delete;
  LiveServer& operator=(const LiveServer&) = delete;

  /// http://HOST:PORT/ with the port actually bound.
  const std::string& url() const { return url_; }

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
  std::string url_;
};

}  // namespace objscan::app
