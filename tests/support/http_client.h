// A bare HTTP/1.1 client for the tests of objscan's servers (the live page, the viewer): it sends
// requests byte for byte as given, so a test can also send what no browser would.
#pragma once

#include <string>

namespace objscan::testing {

/// The port of a line that ends in "http://HOST:PORT/" (e.g. "viewer  http://127.0.0.1:PORT/"),
/// or 0.
int portOf(const std::string& line);

/// A TCP connection to 127.0.0.1:port, or -1.
int connectTo(int port);

struct Answer {
  int status = 0;  ///< 0: the server closed the connection without an answer
  std::string headers;  ///< the status line and headers, as sent
  std::string body;
};

/// Sends `request` as it is and reads the answer until the server closes (at most 10 s).
Answer askRaw(int port, const std::string& request);

/// `GET target` with the Host header a browser sends for http://127.0.0.1:PORT/ (or `host`).
Answer get(int port, const std::string& target, std::string host = "");

/// `POST target` with `body`, the Host header a browser sends and Content-Type `type`
/// (none when empty), plus `headers` ("Name: value\r\n" each).
Answer post(int port, const std::string& target, const std::string& body,
            const std::string& type = "application/json", const std::string& headers = "");

}  // namespace objscan::testing
