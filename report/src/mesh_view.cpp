#include "objscan/report/mesh_view.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <limits>
#include <stdexcept>

#include "mesh_view_js.h"  // generated from report/web/mesh_view.js
#include "objscan/core/byte_writing.h"
#include "objscan/core/palette.h"
#include "orbit_controls_js.h"  // generated from libjs-three's OrbitControls.js
#include "three_js.h"           // generated from libjs-three's three.min.js

namespace objscan::report {
namespace {

using byte_writing::putLittleEndian;

}  // namespace

std::string_view threeJs() { return web::kThreeJs; }
std::string_view orbitControlsJs() { return web::kOrbitControlsJs; }
std::string_view meshViewJs() {
  // The rank colours from their one definition, core/palette.h, then the script.
  static const std::string script = [] {
    std::string s = "var OBJSCAN_RANK_PALETTE = [";
    for (const auto& c : kRankPalette) {
      s.append("[").append(std::to_string(c[0])).append(", ").append(std::to_string(c[1]));
      s.append(", ").append(std::to_string(c[2])).append("], ");
    }
    s += "];\n";
    s += web::kMeshViewJs;
    return s;
  }();
  return script;
}

ViewMesh viewMesh(const TriangleMesh& mesh, const std::vector<HypothesisRecord>& hypotheses,
                  const std::string& scene, std::size_t max_triangles) {
  ViewMesh view;
  view.preview = decimateByClustering(mesh, max_triangles);
  view.ranks.assign(view.preview.mesh.positions.size(), 0);
  for (const HypothesisRecord& h : hypotheses) {
    if (h.scene != scene || h.rank == 0 || h.rank > std::numeric_limits<std::uint16_t>::max()) {
      continue;
    }
    const auto rank = static_cast<std::uint16_t>(h.rank);
    for (const std::int32_t v : h.vertices) {
      if (v < 0 || static_cast<std::size_t>(v) >= mesh.positions.size()) {
        throw std::invalid_argument("hypothesis " + std::to_string(h.rank) + " names vertex " +
                                    std::to_string(v) + ", outside its scene's " +
                                    std::to_string(mesh.positions.size()));
      }
      const std::int32_t p = view.preview.vertex_map[static_cast<std::size_t>(v)];
      if (p < 0) continue;
      std::uint16_t& r = view.ranks[static_cast<std::size_t>(p)];
      if (r == 0 || rank < r) r = rank;
    }
  }
  return view;
}

std::string meshViewPayload(const ViewMesh& view) {
  const TriangleMesh& mesh = view.preview.mesh;
  const std::size_t n = mesh.positions.size();
  const bool colours = mesh.hasColors();
  std::string out;
  out.reserve(20 + n * (12 + (colours ? 4 : 0) + 2) + 4 + mesh.triangles.size() * 12);
  out.append("OSVM", 4);
  putLittleEndian<std::uint32_t>(out, 1);
  putLittleEndian<std::uint32_t>(out, static_cast<std::uint32_t>(n));
  putLittleEndian<std::uint32_t>(out, static_cast<std::uint32_t>(mesh.triangles.size()));
  putLittleEndian<std::uint32_t>(out, colours ? 1u : 0u);
  for (const Eigen::Vector3f& p : mesh.positions) {
    for (int d = 0; d < 3; ++d) putLittleEndian<float>(out, p[d]);
  }
  if (colours) {
    for (const Rgb8& c : mesh.colors) {
      out.push_back(static_cast<char>(c[0]));
      out.push_back(static_cast<char>(c[1]));
      out.push_back(static_cast<char>(c[2]));
      out.push_back(static_cast<char>(255));
    }
  }
  for (std::size_t i = 0; i < n; ++i)
    putLittleEndian<std::uint16_t>(out, i < view.ranks.size() ? view.ranks[i] : 0);
  if (n % 2 == 1) putLittleEndian<std::uint16_t>(out, 0);
  for (const Eigen::Vector3i& t : mesh.triangles) {
    for (int k = 0; k < 3; ++k)
      putLittleEndian<std::uint32_t>(out, static_cast<std::uint32_t>(t[k]));
  }
  return out;
}

std::string viewCameraJson(const OverviewCamera& camera) {
  const Eigen::Vector3f position = camera.T_W_C.translation();
  // The camera looks along its +z with +y down (objscan's camera frame).
  const Eigen::Vector3f forward = camera.T_W_C.linear() * Eigen::Vector3f::UnitZ();
  const Eigen::Vector3f up = camera.T_W_C.linear() * -Eigen::Vector3f::UnitY();
  const double fov =
      2.0 * std::atan(0.5 * camera.intrinsics.height_px / camera.intrinsics.fy_px) * 180.0 / M_PI;
  // A damaged file's infinities are no JSON: no camera then (the view finds its own).
  if (!position.allFinite() || !forward.allFinite() || !up.allFinite() || forward.isZero()) {
    return "null";
  }
  const auto triple = [](const Eigen::Vector3f& v) {
    char text[96];
    std::snprintf(text, sizeof text, "[%.6g, %.6g, %.6g]", v.x(), v.y(), v.z());
    return std::string(text);
  };
  char fov_text[32];
  std::snprintf(fov_text, sizeof fov_text, "%.4g", std::isfinite(fov) ? fov : 50.0);
  return "{\"position\": " + triple(position) + ", \"forward\": " + triple(forward) +
         ", \"up\": " + triple(up) + ", \"fov_y_deg\": " + fov_text + "}";
}

std::vector<std::uint32_t> previewVertices(const std::vector<std::int32_t>& vertex_map,
                                           const std::vector<std::int32_t>& vertices) {
  std::vector<std::uint32_t> out;
  out.reserve(vertices.size());
  for (const std::int32_t v : vertices) {
    if (v < 0 || static_cast<std::size_t>(v) >= vertex_map.size()) continue;
    const std::int32_t p = vertex_map[static_cast<std::size_t>(v)];
    if (p >= 0) out.push_back(static_cast<std::uint32_t>(p));
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace objscan::report
