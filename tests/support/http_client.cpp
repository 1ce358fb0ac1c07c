#include "http_client.h"

#include <arpa/inet.h>
#include <netinet/in.h>
#include <poll.h>
#include <sys/socket.h>
#include <unistd.h>

#include <chrono>
#include <cstdint>
#include <cstdlib>
#include <string>

namespace objscan::testing {

int portOf(const std::string& line) {
  const std::size_t colon = line.rfind(':');
  return colon == std::string::npos ? 0 : std::atoi(line.c_str() + colon + 1);
}

int connectTo(int port) {
  const int fd = ::socket(AF_INET, SOCK_STREAM | SOCK_CLOEXEC, 0);
  sockaddr_in address{};
  address.sin_family = AF_INET;
  address.sin_port = htons(static_cast<std::uint16_t>(port));
  address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
  if (::connect(fd, reinterpret_cast<sockaddr*>(&address), sizeof address) != 0) {
    ::close(fd);
    return -1;
  }
  return fd;
}

Answer askRaw(int port, const std::string& request) {
  Answer answer;
  const int fd = connectTo(port);
  if (fd < 0) return answer;
  std::size_t sent = 0;
  while (sent < request.size()) {
    const ssize_t n = ::send(fd, request.data() + sent, request.size() - sent, MSG_NOSIGNAL);
    if (n <= 0) break;  // the server may close early on a request it refuses
    sent += static_cast<std::size_t>(n);
  }
  std::string reply;
  const auto start = std::chrono::steady_clock::now();
  for (;;) {
    pollfd p{fd, POLLIN, 0};
    if (::poll(&p, 1, 200) > 0) {
      char buffer[8192];
      const ssize_t n = ::recv(fd, buffer, sizeof buffer, 0);
      if (n <= 0) break;
      reply.append(buffer, static_cast<std::size_t>(n));
    }
    if (std::chrono::steady_clock::now() - start > std::chrono::seconds(10)) break;
  }
  ::close(fd);
  if (reply.rfind("HTTP/1.", 0) == 0 && reply.size() > 12) answer.status = std::stoi(reply.substr(9, 3));
  const std::size_t body = reply.find("\r\n\r\n");
  if (body != std::string::npos) {
    answer.headers = reply.substr(0, body + 2);
    answer.body = reply.substr(body + 4);
  }
  return answer;
}

Answer get(int port, const std::string& target, std::string host) {
  if (host.empty()) host = "127.0.0.1:" + std::to_string(port);
  return askRaw(port, "GET " + target + " HTTP/1.1\r\nHost: " + host +
                          "\r\nConnection: close\r\n\r\n");
}

Answer post(int port, const std::string& target, const std::string& body,
            const std::string& type, const std::string& headers) {
  std::string request = "POST " + target + " HTTP/1.1\r\nHost: 127.0.0.1:" + std::to_string(port) +
                        "\r\nConnection: close\r\nContent-Length: " + std::to_string(body.size()) +
                        "\r\n";
  if (!type.empty()) request += "Content-Type: " + type + "\r\n";
  request += headers;
  request += "\r\n";
  request += body;
  return askRaw(port, request);
}

}  // namespace objscan::testing
