#include "objscan/server/live_server.h"

#include <charconv>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <string_view>
#include <system_error>

#include "http_query.h"
#include "live_page.h"  // generated from live_page.html: kLivePage

namespace objscan::server {
namespace {

namespace fs = std::filesystem;

/// How long /api/state?after=N waits for news before answering with the current state.
constexpr std::chrono::milliseconds kLongPoll{1000};

std::uint64_t afterOf(const std::string& query) {
  const std::optional<std::string> value = queryValue(query, "after", 31);
  if (!value || value->empty()) return 0;
  std::uint64_t after = 0;
  const char* last = value->data() + value->size();
  const auto [end, ec] = std::from_chars(value->data(), last, after);
  return ec == std::errc() && end == last ? after : 0;
}

}  // namespace

LiveServer::LiveServer(LiveSession& session, const ServeAddress& address)
    : session_(session),
      server_(
          address, [this](const HttpRequest& request) { return route(request); },
          HttpServerOptions{"--serve", 0, true}) {}

HttpReply LiveServer::route(const HttpRequest& request) {
  const std::string_view path = request.path;
  if (path == "/" || path == "/index.html") {
    return HttpReply::bytes("text/html; charset=utf-8", std::string(kLivePage));
  }
  if (path == "/api/state") {
    return HttpReply::json(session_.stateJson(afterOf(request.query), kLongPoll));
  }
  if (path == "/api/model.jpg" || path == "/api/color.jpg") {
    std::string jpeg = path == "/api/model.jpg" ? session_.modelJpeg() : session_.colorJpeg();
    if (jpeg.empty()) return HttpReply::text(404, "no picture yet");
    return HttpReply::bytes("image/jpeg", std::move(jpeg));
  }
  constexpr std::string_view kResults = "/results/";
  if (path.substr(0, kResults.size()) == kResults) {
    const fs::path file = resultFile(session_.settings().results, path.substr(kResults.size()));
    if (file.empty()) return HttpReply::text(404, "no such file in the results folder");
    return HttpReply::sendFile(file);
  }
  return HttpReply::text(404, "not found");
}

}  // namespace objscan::server
