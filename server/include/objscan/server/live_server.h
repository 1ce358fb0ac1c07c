#pragma once

#include <memory>
#include <string>

#include "objscan/server/http_server.h"
#include "objscan/server/live_session.h"

/// The live page's routes (`--serve` on scan and fuse), on http_server.h's server.
namespace objscan::server {

/// Serves the live page for `session` until destroyed. Routes (GET and HEAD only):
///   /                 the page
///   /api/state        the state as JSON; ?after=N waits up to a second for a newer one
///   /api/model.jpg    the model from the current pose, hypotheses painted
///   /api/color.jpg    the current colour frame
///   /results/NAME     a file of the results folder, read-only (no folder listings, no hidden
///                     files, nothing outside it)
/// Everything else is 404 (405 for other methods); HttpServer's checks apply to all.
class LiveServer {
 public:
  /// Starts listening. Throws std::invalid_argument (exit 2) when it cannot: the port is in use
  /// or not permitted, or the address is not this machine's.
  LiveServer(LiveSession& session, const ServeAddress& address);
  LiveServer(const LiveServer&) = delete;
  LiveServer& operator=(const LiveServer&) = delete;

  /// http://HOST:PORT/ with the port actually bound.
  const std::string& url() const { return server_.url(); }

 private:
  HttpReply route(const HttpRequest& request);

  LiveSession& session_;
  HttpServer server_;  ///< last: it stops before the session it serves is gone
};

}  // namespace objscan::server
