#include "objscan/server/http_server.h"

#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <charconv>
#include <chrono>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <optional>
#include <stdexcept>
#include <string_view>
#include <system_error>
#include <thread>
#include <utility>

#include <civetweb.h>

#include "objscan/core/clock.h"
#include "objscan/core/log.h"

namespace objscan::server {
namespace {

namespace fs = std::filesystem;

bool parsePort(std::string_view text, int* port) {
  if (text.empty() || text.size() > 5) return false;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), *port);
  return ec == std::errc() && end == text.data() + text.size() && *port >= 0 && *port <= 65535;
}

/// Dotted-decimal IPv4 as browsers read it: four parts 0 to 255, no leading zeros (a browser reads
/// "010" as octal, so the URL printed would name another address).
bool isIpv4(std::string_view host) {
  int parts = 0;
  std::size_t at = 0;
  while (at <= host.size()) {
    const std::size_t dot = std::min(host.find('.', at), host.size());
    const std::string_view part = host.substr(at, dot - at);
    int value = 0;
    const auto [end, ec] = std::from_chars(part.data(), part.data() + part.size(), value);
    if (part.empty() || part.size() > 3 || ec != std::errc() || end != part.data() + part.size() ||
        value > 255 || (part.size() > 1 && part[0] == '0')) {
      return false;
    }
    ++parts;
    at = dot + 1;
  }
  return parts == 4;
}

void* lowerThreadPriority(const mg_context*, int) {
  setpriority(PRIO_PROCESS, static_cast<id_t>(syscall(SYS_gettid)), 10);
  return nullptr;
}

/// civetweb's own messages (a client gone mid-reply, a refused oversized request) are about one
/// client, not the work: kept out of the terminal unless --verbose.
int logMessage(const mg_connection*, const char* message) {
  log::debug(std::string("server: ") + message);
  return 1;
}

/// The request's path, percent-decoded here from what civetweb hands over undecoded
/// (decode_url "no": civetweb's own decoding ends the path at a %00, so that "mesh.ply%00.txt"
/// would name mesh.ply); nothing when it holds an encoded NUL or other control character, an
/// encoded slash or backslash (a name with a slash in it is not what it seems: "objects%2frank"
/// would pass rules that judge the path segment by segment), or a malformed escape.
std::optional<std::string> decodedPath(std::string_view raw) {
  const auto hex = [](char c) -> int {
    if (c >= '0' && c <= '9') return c - '0';
    if (c >= 'a' && c <= 'f') return c - 'a' + 10;
    if (c >= 'A' && c <= 'F') return c - 'A' + 10;
    return -1;
  };
  std::string path;
  path.reserve(raw.size());
  for (std::size_t i = 0; i < raw.size(); ++i) {
    char c = raw[i];
    if (c == '%') {
      if (i + 2 >= raw.size()) return std::nullopt;
      const int high = hex(raw[i + 1]), low = hex(raw[i + 2]);
      if (high < 0 || low < 0) return std::nullopt;
      c = static_cast<char>(high * 16 + low);
      if (c == '/' || c == '\\') return std::nullopt;
      i += 2;
    }
    const auto byte = static_cast<unsigned char>(c);
    if (byte < 0x20 || byte == 0x7f) return std::nullopt;
    path.push_back(c);
  }
  return path;
}

/// Whether a Content-Type names application/json: that media type exactly (in any case), with or
/// without parameters ("; charset=utf-8"), not a longer one that starts the same
/// ("application/jsonx").
bool isJsonType(std::string_view type) {
  std::string_view media = type.substr(0, type.find(';'));
  const auto space = [](char c) { return c == ' ' || c == '\t'; };
  while (!media.empty() && space(media.front())) media.remove_prefix(1);
  while (!media.empty() && space(media.back())) media.remove_suffix(1);
  constexpr std::string_view kJson = "application/json";
  return media.size() == kJson.size() &&
         mg_strncasecmp(media.data(), kJson.data(), kJson.size()) == 0;
}

/// How long a client may take to send a request's body, and to read a reply: a slow one keeps a
/// server thread, so each is bounded (10 s, and for a reply 1 s more per 256 kB).
constexpr double kBodySeconds = 10.0;
double replySeconds(std::uint64_t bytes) { return 10.0 + static_cast<double>(bytes) / 262144.0; }

/// Writes `bytes` in 64 kB pieces until done, the client goes, or `seconds` have passed.
void writeWithin(mg_connection* conn, std::string_view bytes, double seconds) {
  const auto start = SteadyClock::now();
  for (std::size_t at = 0; at < bytes.size();) {
    const std::size_t n = std::min<std::size_t>(65536, bytes.size() - at);
    if (mg_write(conn, bytes.data() + at, n) <= 0) return;
    at += n;
    if (at < bytes.size() && secondsSince(start) > seconds) {
      log::debug("server: a client read too slowly; its connection is dropped");
      return;
    }
  }
}

/// The Content-Type of a results file, by its extension.
const char* typeOfFile(const fs::path& file) {
  static const std::pair<const char*, const char*> kTypes[] = {
      {".html", "text/html; charset=utf-8"},
      {".json", "application/json"},
      {".png", "image/png"},
      {".jpg", "image/jpeg"},
      {".txt", "text/plain; charset=utf-8"},
      {".csv", "text/csv; charset=utf-8"},
      {".svg", "image/svg+xml"},
      {".glb", "model/gltf-binary"},
      {".gltf", "model/gltf+json"},
      {".obj", "model/obj"},
      {".stl", "model/stl"},
      {".yml", "text/plain; charset=utf-8"}};
  const std::string extension = file.extension().string();
  for (const auto& [e, type] : kTypes) {
    if (extension == e) return type;
  }
  return "application/octet-stream";  // .ply, .sqlite, .oni, ...
}

void sendHeaders(mg_connection* conn, int status, const char* type, std::uint64_t length,
                 const char* content_security_policy = nullptr) {
  mg_response_header_start(conn, status);
  mg_response_header_add(conn, "Content-Type", type, -1);
  if (content_security_policy) {
    mg_response_header_add(conn, "Content-Security-Policy", content_security_policy, -1);
  }
  mg_response_header_add(conn, "Cache-Control", "no-store", -1);
  mg_response_header_add(conn, "X-Content-Type-Options", "nosniff", -1);
  mg_response_header_add(conn, "Content-Length", std::to_string(length).c_str(), -1);
  mg_response_header_send(conn);
}

void send(mg_connection* conn, const HttpReply& r, bool head) {
  if (!r.file.empty()) {
    // Streamed here rather than by civetweb, so that a slow reader is bounded like any reply.
    std::ifstream in(r.file, std::ios::binary);
    std::error_code ec;
    const std::uintmax_t size = fs::file_size(r.file, ec);
    if (!in || ec) {
      send(conn, HttpReply::text(404, "no such file in the results folder"), head);
      return;
    }
    // A results file is the user's data, perhaps from somebody else: a page or picture in it runs
    // sandboxed (an origin of its own), so it cannot use this server's API as the user.
    sendHeaders(conn, 200, typeOfFile(r.file), size,
                "sandbox allow-scripts allow-downloads allow-popups");
    if (head) return;
    const auto start = SteadyClock::now();
    std::string chunk(1 << 16, '\0');
    for (std::uintmax_t left = size; left > 0 && in;) {
      in.read(chunk.data(),
              static_cast<std::streamsize>(std::min<std::uintmax_t>(chunk.size(), left)));
      const auto n = static_cast<std::size_t>(in.gcount());
      if (n == 0 || mg_write(conn, chunk.data(), n) <= 0) return;
      left -= n;
      if (left > 0 && secondsSince(start) > replySeconds(size)) return;
    }
    return;
  }
  const std::string_view body = r.content();
  sendHeaders(conn, r.status, r.type.c_str(), body.size());
  if (!head && !body.empty()) writeWithin(conn, body, replySeconds(body.size()));
}

}  // namespace

HttpReply HttpReply::text(int status, std::string text) {
  HttpReply r;
  r.status = status;
  r.body = std::move(text);
  r.body += '\n';
  return r;
}

HttpReply HttpReply::json(std::string body, int status) {
  HttpReply r;
  r.status = status;
  r.type = "application/json";
  r.body = std::move(body);
  return r;
}

HttpReply HttpReply::bytes(std::string type, std::string body) {
  HttpReply r;
  r.type = std::move(type);
  r.body = std::move(body);
  return r;
}

HttpReply HttpReply::sharedBytes(std::string type, std::shared_ptr<const std::string> body) {
  HttpReply r;
  r.type = std::move(type);
  r.shared = std::move(body);
  return r;
}

HttpReply HttpReply::staticBytes(std::string type, std::string_view body) {
  HttpReply r;
  r.type = std::move(type);
  r.fixed = body;
  return r;
}

HttpReply HttpReply::sendFile(fs::path file) {
  HttpReply r;
  r.file = std::move(file);
  return r;
}

struct HttpServer::Impl {
  ServeAddress address;
  Handler handler;
  HttpServerOptions options;
  mg_context* context = nullptr;
  /// The port bound: known before the server starts when one was asked for, else set right after
  /// (a request can only come once the port is known to a client, and it is atomic regardless).
  std::atomic<int> port{0};
  std::atomic<int> in_flight{0};  ///< requests being answered

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

  int handle(mg_connection* conn) {
    // Counted while it runs: the destructor lets a reply being written finish (civetweb's stop
    // would cut it after its headers, and a page would read an empty answer).
    in_flight.fetch_add(1);
    struct Done {
      std::atomic<int>& count;
      ~Done() { count.fetch_sub(1); }
    } done{in_flight};
    // Nothing may leave a civetweb callback as an exception (it would end the whole program).
    bool head = false;
    try {
      HttpReply r = route(conn, &head);
      send(conn, r, head);
      return r.status;
    } catch (const std::exception& e) {
      log::debug(std::string("server: ") + e.what());
    } catch (...) {
      log::debug("server: an unknown error");
    }
    try {
      send(conn, HttpReply::text(500, "internal error"), head);
    } catch (...) {  // out of memory for the reply: the connection is closed without one
    }
    return 500;
  }

  HttpReply route(mg_connection* conn, bool* head) {
    const mg_request_info* info = mg_get_request_info(conn);
    HttpRequest request;
    request.method = info->request_method ? info->request_method : "";
    *head = request.head();
    const char* host = mg_get_header(conn, "Host");
    if (host && !ownHost(host)) {
      return HttpReply::text(403, "this server answers only to its own address");
    }
    const std::optional<std::string> path =
        decodedPath(info->local_uri_raw ? info->local_uri_raw : "");
    if (!path) {
      return HttpReply::text(400,
                             "the path holds an encoded NUL, control character, slash or "
                             "backslash, or a malformed %-escape");
    }
    const bool post = request.method == "POST" && options.max_body_bytes > 0;
    if (request.method != "GET" && !*head && !post) {
      return HttpReply::text(405, options.max_body_bytes > 0
                                      ? "only GET, HEAD and POST are served here"
                                      : "only GET and HEAD are served here");
    }
    // The decoded path as sent, not civetweb's cleaned one: a path that needs cleaning (dot
    // segments) is refused by the routes rather than quietly turned into another.
    request.path = *path;
    request.query = info->query_string ? info->query_string : "";
    if (post) {
      if (std::optional<HttpReply> refused = readBody(conn, info, &request.body)) return *refused;
    }
    return handler(request);
  }

  /// Reads a POST's body into `body`, or the reply that refuses it.
  std::optional<HttpReply> readBody(mg_connection* conn, const mg_request_info* info,
                                    std::string* body) const {
    const char* type = mg_get_header(conn, "Content-Type");
    if (!type || !isJsonType(type)) {
      return HttpReply::text(415, "a POST here carries Content-Type: application/json");
    }
    if (const char* origin = mg_get_header(conn, "Origin")) {
      std::string_view o = origin;
      constexpr std::string_view kHttp = "http://";
      if (o.substr(0, kHttp.size()) != kHttp || !ownHost(o.substr(kHttp.size()))) {
        return HttpReply::text(403, "a POST here must come from this server's own pages");
      }
    }
    if (info->content_length < 0) return HttpReply::text(411, "a POST here gives its length");
    if (static_cast<std::uint64_t>(info->content_length) > options.max_body_bytes) {
      return HttpReply::text(413, "the body is larger than the " +
                                      std::to_string(options.max_body_bytes) + " bytes taken here");
    }
    body->resize(static_cast<std::size_t>(info->content_length));
    std::size_t got = 0;
    const auto start = SteadyClock::now();
    while (got < body->size()) {
      // A byte at a time: civetweb's read waits for all it is asked for, and the deadline is
      // only looked at between reads (a body is at most a few kB).
      const int n = mg_read(conn, body->data() + got, 1);
      if (n <= 0) return HttpReply::text(400, "the body ended before its announced length");
      got += static_cast<std::size_t>(n);
      if (got < body->size() && secondsSince(start) > kBodySeconds) {
        return HttpReply::text(408, "the body came too slowly");
      }
    }
    return std::nullopt;
  }
};

ServeAddress parseServeAddress(const std::string& text, const std::string& flag) {
  ServeAddress address;
  const std::size_t colon = text.rfind(':');
  const std::string port = colon == std::string::npos ? text : text.substr(colon + 1);
  if (colon != std::string::npos) address.host = text.substr(0, colon);
  if (address.host == "localhost") address.host = "127.0.0.1";
  if (!parsePort(port, &address.port)) {
    throw std::invalid_argument(flag + " '" + text + "': the port must be a number from 0 to " +
                                "65535 (0: any free port), as PORT or ADDRESS:PORT");
  }
  if (!isIpv4(address.host)) {
    throw std::invalid_argument(
        flag + " '" + text + "': '" + address.host +
        "' is not an IPv4 address in dotted decimal without leading zeros " +
        "(e.g. 127.0.0.1, or 0.0.0.0 for every interface)");
  }
  if (const int first = std::atoi(address.host.c_str()); first >= 224) {
    throw std::invalid_argument(
        flag + " '" + text + "': '" + address.host +
        "' is a multicast, reserved or broadcast address, which no browser " +
        "can reach a server on");
  }
  return address;
}

HttpServer::HttpServer(const ServeAddress& address, Handler handler,
                       const HttpServerOptions& options)
    : impl_(new Impl{address, std::move(handler), options}) {
  mg_init_library(0);
  const std::string listening = address.host + ":" + std::to_string(address.port);
  // A few threads: a page needs two or three connections, and a request beyond them waits in
  // the queue; a connection that sends nothing is dropped after 5 s, and a request over 16 kB
  // (headers included) is refused, so neither many nor slow nor huge requests tie the server up.
  // The path comes undecoded: decodedPath refuses what civetweb's decoding would hide (%00 ends
  // its string).
  const char* civetweb_options[] = {"listening_ports",
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
                                    "decode_url",
                                    "no",
                                    "access_control_allow_origin",
                                    "",
                                    "static_file_cache_control",
                                    "no-store",
                                    nullptr};
  mg_callbacks callbacks{};
  callbacks.begin_request = [](mg_connection* conn) -> int {
    auto* impl = static_cast<Impl*>(mg_get_user_data(mg_get_context(conn)));
    return impl->handle(conn);
  };
  if (options.lower_priority) callbacks.init_thread = lowerThreadPriority;
  callbacks.log_message = logMessage;
  char error_text[256] = "";
  unsigned error_code = 0;
  mg_error_data error{&error_code, error_text, sizeof error_text};
  impl_->port = address.port;
  mg_init_data init{&callbacks, impl_.get(), civetweb_options};
  impl_->context = mg_start2(&init, &error);
  if (!impl_->context) {
    mg_exit_library();
    std::string why = error_text[0] ? error_text : "civetweb could not start";
    throw std::invalid_argument(options.flag + " " + listening + ": cannot listen: " + why +
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

HttpServer::~HttpServer() {
  // Replies being written are finished first (at most 2 s: a long poll answers within 1 s).
  const auto start = std::chrono::steady_clock::now();
  while (impl_->in_flight.load() > 0 &&
         std::chrono::steady_clock::now() - start < std::chrono::seconds(2)) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  if (impl_->context) mg_stop(impl_->context);
  mg_exit_library();
}

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

}  // namespace objscan::server
