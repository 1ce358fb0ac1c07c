#pragma once

#include <cstddef>
#include <filesystem>
#include <functional>
#include <memory>
#include <string>
#include <string_view>

/// The HTTP server behind `--serve` (scan, fuse) and `objscan view`: civetweb (Debian's
/// libcivetweb), a small, long-maintained C library whose worker threads, connection queue,
/// request size cap and connection timeout are run-time options, which is what keeps many, slow
/// or huge requests away from the work; a shared library, so Debian's security fixes reach objscan
/// without a rebuild (cpp-httplib is header-only; Boost.Beast is a toolkit, not a server).
/// docs/live.md has the choice in full. civetweb stays inside http_server.cpp and, for query
/// values, http_query.cpp.
///
/// What every route gets from it: a request whose Host is not the server's own is refused (403:
/// DNS rebinding); a path with an encoded NUL or other control character, an encoded slash or
/// backslash, or a malformed %-escape is refused (400) before any route sees it; only GET and
/// HEAD, and POST where the server takes bodies (405 otherwise); a
/// request over 16 kB of headers is refused by civetweb; an exception in a handler becomes a 500.
/// A client that sends its body or reads the reply slowly keeps one of the 8 server threads for
/// a bounded time only: about 10 s for a body (up to 15 when it stops short), 10 s plus 1 s per
/// 256 kB for a reply; past that its connection is dropped. A file reply (HttpReply::file) is
/// sandboxed (Content-Security-Policy): the results folder's pages run in an origin of their own.
namespace objscan::server {

/// Where the server listens. The address is 127.0.0.1 unless one is given; port 0 takes any free
/// port.
struct ServeAddress {
  std::string host = "127.0.0.1";
  int port = 0;
};

/// Parses "[ADDR:]PORT" (an IPv4 address in plain dotted decimal, no leading zeros, not a
/// multicast or broadcast one, or "localhost"; and a port 0 to 65535). Throws
/// std::invalid_argument naming the text and what is wrong; `flag` names the option in it.
ServeAddress parseServeAddress(const std::string& text, const std::string& flag = "--serve");

struct HttpRequest {
  std::string method;  ///< "GET", "HEAD" or "POST"
  std::string path;    ///< percent-decoded, as sent: not cleaned of dot segments; no control
                       ///< character, and every '/' in it was sent as one
  std::string query;   ///< undecoded, without '?'
  std::string body;    ///< POST only: the JSON body
  bool head() const { return method == "HEAD"; }
};

struct HttpReply {
  int status = 200;
  std::string type = "text/plain; charset=utf-8";
  std::string body;
  /// Instead of `body`, bytes shared with the server's data (a large mesh is not copied per
  /// request), or bytes that live as long as the program (compiled-in pages and scripts).
  std::shared_ptr<const std::string> shared;
  std::string_view fixed;
  /// When set, the reply is this file (type from its extension).
  std::filesystem::path file;

  static HttpReply text(int status, std::string text);
  static HttpReply json(std::string body, int status = 200);
  static HttpReply bytes(std::string type, std::string body);
  static HttpReply sharedBytes(std::string type, std::shared_ptr<const std::string> body);
  static HttpReply staticBytes(std::string type, std::string_view body);
  static HttpReply sendFile(std::filesystem::path file);
  std::string_view content() const {
    return shared ? std::string_view(*shared) : fixed.empty() ? std::string_view(body) : fixed;
  }
};

struct HttpServerOptions {
  std::string flag = "--serve";  ///< the option that chose the address, for messages
  /// POST requests with a JSON body of at most this many bytes are taken; 0: none (405). A POST
  /// must say Content-Type application/json (that media type, any case, parameters allowed; 415),
  /// give its length (411, 413 past this), and, when it says where it comes from (Origin), come
  /// from this server (403): a page of another site cannot post to it.
  std::size_t max_body_bytes = 0;
  /// Lower the server threads below the work (nice 10): a scan is never slowed by its page.
  bool lower_priority = false;
};

/// Serves `handler`'s routes until destroyed. The handler runs on the server's threads (several
/// at once) and must be thread-safe.
class HttpServer {
 public:
  using Handler = std::function<HttpReply(const HttpRequest&)>;
  /// Starts listening. Throws std::invalid_argument (exit 2) when it cannot: the port is in use
  /// or not permitted, or the address is not this machine's.
  HttpServer(const ServeAddress& address, Handler handler, const HttpServerOptions& options = {});
  ~HttpServer();  ///< stops serving: open requests end, and no new one is taken
  HttpServer(const HttpServer&) = delete;
  HttpServer& operator=(const HttpServer&) = delete;

  /// http://HOST:PORT/ with the port actually bound.
  const std::string& url() const { return url_; }

  struct Impl;

 private:
  std::unique_ptr<Impl> impl_;
  std::string url_;
};

/// The file of `folder` that the URL path `relative` names, or empty: no "." or ".." segment, no
/// hidden file or folder (temporary files, the folder's lock), no backslash, and after symbolic
/// links are resolved still inside the folder and a regular file.
std::filesystem::path resultFile(const std::filesystem::path& folder, std::string_view relative);

}  // namespace objscan::server
