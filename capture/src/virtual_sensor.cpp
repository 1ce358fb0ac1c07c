#include "objscan/capture/virtual_sensor.h"

#include <charconv>
#include <cmath>
#include <stdexcept>
#include <string_view>

namespace objscan::capture {
namespace {

[[noreturn]] void fail(const std::string& uri, std::string_view problem) {
  std::string message = uri;
  message.append(": ").append(problem);
  throw std::invalid_argument(message);
}

template <typename T>
bool parseNumber(std::string_view text, T* value) {
  const auto [end, error] = std::from_chars(text.data(), text.data() + text.size(), *value);
  return error == std::errc() && end == text.data() + text.size();
}

}  // namespace

bool isVirtualSensorUri(const std::string& uri) { return uri.rfind(kVirtualUriPrefix, 0) == 0; }

VirtualSensorUri parseVirtualSensorUri(const std::string& uri) {
  if (!isVirtualSensorUri(uri)) fail(uri, "a virtual sensor URI starts with 'virtual:'");
  std::string_view rest(uri);
  rest.remove_prefix(std::string_view(kVirtualUriPrefix).size());
  VirtualSensorUri parsed;
  const std::size_t query = rest.find('?');
  parsed.source = std::string(rest.substr(0, query));
  if (parsed.source.empty())
    fail(uri, "names no source: use virtual:<folder> or virtual:synth:<seed>");
  if (query == std::string_view::npos) return parsed;

  std::string_view options = rest.substr(query + 1);
  while (!options.empty()) {
    const std::size_t amp = options.find('&');
    const std::string_view option = options.substr(0, amp);
    options = amp == std::string_view::npos ? std::string_view() : options.substr(amp + 1);
    const std::size_t eq = option.find('=');
    const std::string_view key = option.substr(0, eq);
    const std::string_view value =
        eq == std::string_view::npos ? std::string_view() : option.substr(eq + 1);
    if (key == "fps") {
      if (!parseNumber(value, &parsed.fps) || !std::isfinite(parsed.fps) || parsed.fps < 1.0 ||
          parsed.fps > 1000.0) {
        fail(uri, "fps must be a number from 1 to 1000");
      }
    } else if (key == "unplug_after") {
      std::size_t n = 0;
      if (!parseNumber(value, &n)) fail(uri, "unplug_after must be a whole number of frames");
      parsed.unplug_after = n;
    } else if (key == "streams") {
      if (value == "depth,color" || value == "color,depth") {
        parsed.depth = parsed.color = true;
      } else if (value == "depth") {
        parsed.color = false;
      } else if (value == "color") {
        parsed.depth = false;
      } else {
        fail(uri, "streams must be depth,color or depth or color");
      }
    } else {
      std::string problem = "unknown option '";
      problem.append(key).append("' (known: fps, unplug_after, streams)");
      fail(uri, problem);
    }
  }
  return parsed;
}

}  // namespace objscan::capture
