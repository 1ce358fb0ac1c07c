#pragma once

#include <optional>
#include <string>
#include <string_view>

/// Reading a request's query string (HttpRequest::query): with civetweb's own decoder, so that
/// the routes need not include civetweb (it stays inside http_server.cpp and this file's .cpp).
namespace objscan::server {

/// The percent-decoded value of the first `name=` in `query` (undecoded, without '?'), or nothing
/// when it is absent, or longer than `max_bytes`.
std::optional<std::string> queryValue(std::string_view query, const char* name,
                                      std::size_t max_bytes = 256);

}  // namespace objscan::server
