#include "live_server.h"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <chrono>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string_view>
#include <system_error>
#include <vector>

#include <civetweb.h>

#include "live_page.h"  // generated from live_page.html: kLivePage
#include "objscan/core/log.h"

namespace objscan::app {
namespace {

namespace fs = std::filesystem;

/// How long /api/state?after=N waits for news before answering with the current state.
constexpr std::chrono::milliseconds kLongPoll{1000};

bool parsePort(std::string_view text, int* port) {
  if (text.empty() || text.size() > 5) return false;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), *port);
  return ec == std::errc() && end == text.data() + text.size() && *port >= 0 && *port <= 65535;
}

bool isIpv4(std::string_view host) {
  int parts = 0;
  std::size_t at = 0;
  while (at <= host.size()) {
    const std::size_t dot = std::min(host.find('.', at), host.size());
    const std::string_view part = host.substr(at, dot - at);
    int value = 0;
    const auto [end, ec] = std::from_chars(part.data(), part.data() + part.size(), value);
    if (part.empty() || part.size() > 3 || ec != std::errc() || end != part.data() + part.size() ||
        value > 255) {
      return false;
    }
    ++parts;
    at = dot + 1;
  }
  return parts == 4;
}

/// Lowers the calling server thread below fusion (nice 10): with both cores busy fusing, the
/// page is answered late rather than the scan slowed.
void *lowerThreadPriority(const mg_context *, int) {
  setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 10);
  return nullptr;
}

/// civetweb's own messages (a client gone mid-reply, a refused oversized request) are about one
/// client, not the scan: kept out of the terminal unless --verbose.
int logMessage(const mg_connection *, const char *message) {
  log::debug(std::string("live page server: ") + message);
  return 1;
}

void reply(mg_connection *conn, int status, const char *type, std::string_view body,
           bool head) {
  mg_response_header_start(conn, status);
  mg_response_header_add(conn, "Content-Type", type, -1);
  mg_response_header_add(conn, "Cache-Control", "no-store", -1);
  mg_response_header_add(conn, "X-Content-Type-Options", "nosniff", -1);
  mg_response_header_add(conn, "Content-Length", std::to_string(body.size()).c_str(), -1);
  mg_response_header_send(conn);
  if (!head && !body.empty()) mg_write(conn, body.data(), body.size());
}

void replyError(mg_connection *conn, int status, std::string_view text, bool head) {
  reply(conn, status, "text/plain; charset=utf-8", std::string(text) + "\n", head);
}

std::uint64_t afterOf(const char *query) {
  if (!query) return 0;
  char value[32];
  if (mg_get_var(query, std::strlen(query), "after", value, sizeof value) <= 0) return 0;
  std::uint64_t after = 0;
  const auto [end, ec] = std::from_chars(value, value + std::strlen(value), after);
  return ec == std::errc() && *end == '\0' ? after : 0;
}

/// The file of the results folder that `relative` names, or empty: no "." or ".." segment, no
/// hidden file or folder (temporary files, the folder's lock), no backslash, and after symbolic
/// links are resolved still inside the folder and a regular file. (civetweb decodes the path in
/// place, so a %00 ends it: "a%00.txt" names "a", which these rules then judge.)
fs::path resultFile(const fs::path& folder, std::string_view relative) {
  if (relative.empty() || relative.size() > 1024) return {};
  if (relative.find('\\') != std::string_view::npos) return {};
  std::size_t at = 0;
  while (at <= relative.size()) {
    const std::size_t slash = std::min(relative.find('/', at), relative.size());
    const std::string_view part = relative.substr(at, slash - at);
    if (part.empty() || part.front() == '.') return {};
    at = slash + 1;
  }
  std::error_code ec;
  const fs::path root = fs::canonical(folder, ec);
  if (ec) return {};
  const fs::path file = fs::canonical(root / fs::path(std::string(relative)), ec);
  if (ec || !fs::is_regular_file(file, ec)) return {};
  const auto [end, ignored] = std::mismatch(root.begin(), root.end(), file.begin(), file.end());
  if (end != root.end()) return {};
  return file;
}

}  // namespace

struct LiveServer::Impl {
  LiveSession &session;
  ServeAddress address;
  mg_context *context = nullptr;
  int port = 0;  ///< the port bound

  /// Whether `host` (a Host header) names this server: the address it listens on, or localhost
  /// on a loopback address, or, listening on every interface, an IPv4 address or this machine's
  /// name; with the port bound. A page of another site that has made its own name point at
  /// 127.0.0.1 (DNS rebinding) sends that name, and is refused.
  bool ownHost(std::string_view host) const {
    std::string_view name = host;
    const std::size_t colon = host.rfind(':');
    if (colon != std::string_view::npos) {
      int given = -1;
      if (!parsePort(host.substr(colon + 1), &given) || given != port) return false;
      name = host.substr(0, colon);
    } else if (port != 80) {
      return false;
    }
    const auto same = [](std::string_view a, std::string_view b) {
      return a.size() == b.size() && mg_strncasecmp(a.data(), b.data(), a.size()) == 0;
    };
    if (same(name, address.host)) return true;
    const bool any = address.host == "0.0.0.0";
    if (same(name, "localhost") && (any || address.host.rfind("127.", 0) == 0)) return true;
    if (!any) return false;
    if (isIpv4(name)) return true;
    char own[256] = "";
    return gethostname(own, sizeof own - 1) == 0 && same(name, own);
  }

  int handle(mg_connection *conn) {
    // Nothing may leave a civetweb callback as an exception (it would end the whole scan).
    try {
      return route(conn);
    } catch (const std::exception &e) {
      log::debug(std::string("live page server: ") + e.what());
    } catch (...) {
      log::debug("live page server: an unknown error");
    }
    try {
      replyError(conn, 500, "internal error", false);
    } catch (...) {  // out of memory for the reply: the connection is closed without one
    }
    return 500;
  }

  int route(mg_connection *conn) {
    const mg_request_info *request = mg_get_request_info(conn);
    const std::string_view method = request->request_method ? request->request_method : "";
    const bool head = method == "HEAD";
    const char *host = mg_get_header(conn, "Host");
    if (host && !ownHost(host)) {
      replyError(conn, 403, "this server answers only to its own address", head);
      return 403;
    }
    if (method != "GET" && !head) {
      replyError(conn, 405, "only GET and HEAD are served here", false);
      return 405;
    }
    // The decoded path as sent, not civetweb's cleaned one: a path that needs cleaning (dot
    // segments) is refused below rather than quietly turned into another.
    const std::string_view path = request->local_uri_raw ? request->local_uri_raw : "";
    if (path == "/" || path == "/index.html") {
      reply(conn, 200, "text/html; charset=utf-8", kLivePage, head);
      return 200;
    }
    if (path == "/api/state") {
      const std::string state = session.stateJson(afterOf(request->query_string), kLongPoll);
      reply(conn, 200, "application/json", state, head);
      return 200;
    }
    if (path == "/api/model.jpg" || path == "/api/color.jpg") {
      const std::string jpeg = path == "/api/model.jpg" ? session.modelJpeg() : session.colorJpeg();
      if (jpeg.empty()) {
        replyError(conn, 404, "no picture yet", head);
        return 404;
      }
      reply(conn, 200, "image/jpeg", jpeg, head);
      return 200;
    }
    constexpr std::string_view kResults = "/results/";
    if (path.substr(0, kResults.size()) == kResults) {
      const fs::path file = resultFile(session.settings().results, path.substr(kResults.size()));
      if (file.empty()) {
        replyError(conn, 404, "no such file in the results folder", head);
        return 404;
      }
      // civetweb sends the file (Content-Type from its extension, ranges, HEAD).
      mg_send_mime_file2(conn, file.c_str(), nullptr, "X-Content-Type-Options: nosniff\r\n");
      return 200;
    }
    replyError(conn, 404, "not found", head);
    return 404;
  }
};

ServeAddress parseServeAddress(const std::string &text) {
  ServeAddress address;
  const std::size_t colon = text.rfind(':');
  const std::string port = colon == std::string::npos ? text : text.substr(colon + 1);
  if (colon != std::string::npos) address.host = text.substr(0, colon);
  if (address.host == "localhost") address.host = "127.0.0.1";
  if (!parsePort(port, &address.port)) {
    throw std::invalid_argument("--serve '" + text + "': the port must be a number from 0 to " +
                                "65535 (0: any free port), as PORT or ADDRESS:PORT");
  }
  if (!isIpv4(address.host)) {
    throw std::invalid_argument("--serve '" + text + "': '" + address.host +
                                "' is not an IPv4 address (e.g. 127.0.0.1, or 0.0.0.0 for every " +
                                "interface)");
  }
  return address;
}

LiveServer::LiveServer(LiveSession &session, const ServeAddress &address)
    : impl_(new Impl{session, address}) {
  mg_init_library(0);
  const std::string listening = address.host + ":" + std::to_string(address.port);
  // A few threads: the page needs two or three connections, and a request beyond them waits in
  // the queue; a connection that sends nothing is dropped after 5 s, and a request over 16 kB
  // (headers included) is refused, so neither many nor slow nor huge requests tie the server up.
  const char *options[] = {"listening_ports",
                           listening.c_str(),
                           "num_threads",
                           "8",
                           "connection_queue",
                           "64",
                           "request_timeout_ms",
                           "5000",
                           "max_request_size",
                           "16384",
                           "enable_keep_alive",
                           "no",
                           "enable_directory_listing",
                           "no",
                           "access_control_allow_origin",
                           "",
                           "static_file_cache_control",
                           "no-store",
                           nullptr};
  mg_callbacks callbacks{};
  callbacks.begin_request = [](mg_connection *conn) -> int {
    auto *impl = static_cast<Impl *>(mg_get_user_data(mg_get_context(conn)));
    return impl->handle(conn);
  };
  callbacks.init_thread = lowerThreadPriority;
  callbacks.log_message = logMessage;
  char error_text[256] = "";
  unsigned error_code = 0;
  mg_error_data error{&error_code, error_text, sizeof error_text};
  mg_init_data init{&callbacks, impl_.get(), options};
  impl_->context = mg_start2(&init, &error);
  if (!impl_->context) {
    mg_exit_library();
    std::string why = error_text[0] ? error_text : "civetweb could not start";
    throw std::invalid_argument("--serve " + listening + ": cannot listen: " + why +
                                " (is another program on that port? pick another, or 0 for any "
                                "free port)");
  }
  mg_server_port ports[4];
  const int n = mg_get_server_ports(impl_->context, 4, ports);
  const int port = n > 0 ? ports[0].port : address.port;
  impl_->port = port;
  const std::string shown = address.host == "0.0.0.0" ? std::string("127.0.0.1") : address.host;
  url_ = "http://" + shown + ":" + std::to_string(port) + "/";
}

LiveServer::~LiveServer() {
  if (impl_->context) mg_stop(impl_->context);
  mg_exit_library();
}

}  // namespace objscan::app
