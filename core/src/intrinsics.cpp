#include "objscan/core/intrinsics.h"

#include <cmath>
#include <nlohmann/json.hpp>
#include <stdexcept>
#include <string>

#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"

namespace objscan {
namespace {

constexpr int kMaxSide_px = 16384;

}  // namespace

void Intrinsics::validate() const {
  auto positive = [](double v) { return std::isfinite(v) && v > 0.0; };
  if (!positive(fx_px) || !positive(fy_px)) {
    throw std::invalid_argument(
        "intrinsics: focal lengths fx and fy must be finite and positive (got fx = " +
        std::to_string(fx_px) + ", fy = " + std::to_string(fy_px) + ")");
  }
  if (width_px < 1 || height_px < 1 || width_px > kMaxSide_px || height_px > kMaxSide_px) {
    throw std::invalid_argument("intrinsics: image size must be 1.." + std::to_string(kMaxSide_px) +
                                " pixels on a side (got " + std::to_string(width_px) + "x" +
                                std::to_string(height_px) + ")");
  }
  if (!std::isfinite(cx_px) || !std::isfinite(cy_px) || cx_px < 0.0 || cy_px < 0.0 ||
      cx_px > width_px || cy_px > height_px) {
    throw std::invalid_argument("intrinsics: principal point (cx, cy) = (" + std::to_string(cx_px) +
                                ", " + std::to_string(cy_px) + ") must lie inside the " +
                                std::to_string(width_px) + "x" + std::to_string(height_px) +
                                " image");
  }
}

Intrinsics readIntrinsicsJson(const std::filesystem::path& path,
                              std::optional<double>* depth_factor) {
  const std::string text = readWholeFile(path);
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {  // syntax errors, numbers out of range
    throw InputError(path, std::string("not valid JSON: ") + e.what());
  }
  if (!j.is_object())
    throw InputError(path, "expected a JSON object with fx, fy, cx, cy, width, height");
  auto number = [&](const char* key) {
    if (!j.contains(key) || !j[key].is_number()) {
      throw InputError(
          path, std::string("missing number \"") + key + "\" (need fx, fy, cx, cy, width, height)");
    }
    return j[key].get<double>();
  };
  auto integer = [&](const char* key) {
    const double v = number(key);
    if (v != std::floor(v) || std::abs(v) > kMaxSide_px * 4.0) {
      throw InputError(path, std::string("\"") + key + "\" must be a whole number of pixels");
    }
    return static_cast<int>(v);
  };
  Intrinsics in;
  in.fx_px = number("fx");
  in.fy_px = number("fy");
  in.cx_px = number("cx");
  in.cy_px = number("cy");
  in.width_px = integer("width");
  in.height_px = integer("height");
  try {
    in.validate();
  } catch (const std::invalid_argument& e) {
    throw InputError(path, e.what());
  }
  if (depth_factor != nullptr) {
    depth_factor->reset();
    if (j.contains("depth_factor")) {
      if (!j["depth_factor"].is_number() || !(j["depth_factor"].get<double>() > 0.0)) {
        throw InputError(path,
                         "\"depth_factor\" must be a positive number (raw depth units per metre)");
      }
      *depth_factor = j["depth_factor"].get<double>();
    }
  }
  return in;
}

void writeIntrinsicsJson(const std::filesystem::path& path, const Intrinsics& in,
                         std::optional<double> depth_factor) {
  nlohmann::json j = {{"fx", in.fx_px}, {"fy", in.fy_px},       {"cx", in.cx_px},
                      {"cy", in.cy_px}, {"width", in.width_px}, {"height", in.height_px}};
  if (depth_factor) j["depth_factor"] = *depth_factor;
  writeFileAtomically(path, j.dump(2) + "\n");
}

}  // namespace objscan
