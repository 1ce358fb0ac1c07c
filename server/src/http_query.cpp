#include "http_query.h"

#include <civetweb.h>

#include <vector>

namespace objscan::server {

std::optional<std::string> queryValue(std::string_view query, const char* name,
                                      std::size_t max_bytes) {
  if (query.empty()) return std::nullopt;
  std::vector<char> value(max_bytes + 1, '\0');
  // -1: absent; -2: longer than the buffer; else the decoded length.
  const int n = mg_get_var(query.data(), query.size(), name, value.data(), value.size());
  if (n < 0) return std::nullopt;
  return std::string(value.data(), static_cast<std::size_t>(n));
}

}  // namespace objscan::server
