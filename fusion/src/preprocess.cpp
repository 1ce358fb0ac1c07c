#include "objscan/fusion/preprocess.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <Eigen/Geometry>
#include <opencv2/imgproc.hpp>

namespace objscan::fusion {

namespace {

constexpr float kNaN = std::numeric_limits<float>::quiet_NaN();

void require(bool ok, const std::string& what) {
  if (!ok) throw std::invalid_argument(what);
}

/// Runs body(row) for every row in [0, rows), in parallel.
template <typename Body>
void forEachRow(int rows, const Body& body) {
  tbb::parallel_for(tbb::blocked_range<int>(0, rows), [&](const tbb::blocked_range<int>& r) {
    for (int v = r.begin(); v != r.end(); ++v) body(v);
  });
}

/// Fills `vertices` (resized; its memory reused from frame to frame) with the back-projected depth.
void backProject(const cv::Mat& depth_m, const Intrinsics& in,
                 std::vector<Eigen::Vector3f>* vertices) {
  vertices->resize(depth_m.total());
  const float fx_inv = 1.0f / static_cast<float>(in.fx_px);
  const float fy_inv = 1.0f / static_cast<float>(in.fy_px);
  const float cx = static_cast<float>(in.cx_px), cy = static_cast<float>(in.cy_px);
  forEachRow(depth_m.rows, [&](int v) {
    const float* d = depth_m.ptr<float>(v);
    Eigen::Vector3f* out = vertices->data() + static_cast<std::size_t>(v) * depth_m.cols;
    for (int u = 0; u < depth_m.cols; ++u) {
      const float z = d[u];
      out[u] = z > 0.0f ? Eigen::Vector3f((static_cast<float>(u) - cx) * z * fx_inv,
                                          (static_cast<float>(v) - cy) * z * fy_inv, z)
                        : Eigen::Vector3f(kNaN, kNaN, kNaN);
    }
  });
}

/// computeNormals into `normals` (resized, memory reused).
void normalsInto(const std::vector<Eigen::Vector3f>& vertices_C, int width, int height,
                 std::vector<Eigen::Vector3f>* normals) {
  normals->resize(vertices_C.size());
  forEachRow(height, [&](int v) {
    Eigen::Vector3f* out = normals->data() + static_cast<std::size_t>(v) * width;
    std::fill(out, out + width, Eigen::Vector3f::Constant(kNaN));
    if (v + 1 == height) return;
    for (int u = 0; u + 1 < width; ++u) {
      const std::size_t i = static_cast<std::size_t>(v) * width + u;
      const Eigen::Vector3f& p = vertices_C[i];
      const Eigen::Vector3f& right = vertices_C[i + 1];
      const Eigen::Vector3f& down = vertices_C[i + width];
      if (!p.allFinite() || !right.allFinite() || !down.allFinite()) continue;
      Eigen::Vector3f n = (right - p).cross(down - p);
      const float norm = n.norm();
      if (!(norm > 0.0f)) continue;
      n /= norm;
      out[u] = n.dot(p) > 0.0f ? Eigen::Vector3f(-n) : n;
    }
  });
}

/// Vertices and normals at every `stride`-th pixel of every `stride`-th row only, computed from the
/// depth as backProject and normalsInto would compute them there (the same arithmetic, so the
/// same values), into compact maps of ceil(cols / stride) x ceil(rows / stride) samples.
void sampledVerticesAndNormals(const cv::Mat& depth_m, const Intrinsics& in, int stride,
                               std::vector<Eigen::Vector3f>* vertices,
                               std::vector<Eigen::Vector3f>* normals) {
  const int width = depth_m.cols, height = depth_m.rows;
  const int cols = (width + stride - 1) / stride, rows = (height + stride - 1) / stride;
  vertices->resize(static_cast<std::size_t>(cols) * rows);
  normals->resize(vertices->size());
  const float fx_inv = 1.0f / static_cast<float>(in.fx_px);
  const float fy_inv = 1.0f / static_cast<float>(in.fy_px);
  const float cx = static_cast<float>(in.cx_px), cy = static_cast<float>(in.cy_px);
  const Eigen::Vector3f nan = Eigen::Vector3f::Constant(kNaN);
  forEachRow(rows, [&](int row) {
    const int v = row * stride;
    const float* d = depth_m.ptr<float>(v);
    const float* below = v + 1 < height ? depth_m.ptr<float>(v + 1) : nullptr;
    const float y = static_cast<float>(v) - cy, y_below = static_cast<float>(v + 1) - cy;
    Eigen::Vector3f* vert = vertices->data() + static_cast<std::size_t>(row) * cols;
    Eigen::Vector3f* norm = normals->data() + static_cast<std::size_t>(row) * cols;
    for (int col = 0; col < cols; ++col) {
      const int u = col * stride;
      const float z = d[u];
      const float x = static_cast<float>(u) - cx;
      if (!(z > 0.0f)) {
        vert[col] = nan;
        norm[col] = nan;
        continue;
      }
      const Eigen::Vector3f p(x * z * fx_inv, y * z * fy_inv, z);
      vert[col] = p;
      norm[col] = nan;
      if (!below || u + 1 >= width) continue;
      const float z_right = d[u + 1], z_down = below[u];
      if (!(z_right > 0.0f) || !(z_down > 0.0f)) continue;
      const Eigen::Vector3f right((static_cast<float>(u + 1) - cx) * z_right * fx_inv,
                                  y * z_right * fy_inv, z_right);
      const Eigen::Vector3f down(x * z_down * fx_inv, y_below * z_down * fy_inv, z_down);
      Eigen::Vector3f n = (right - p).cross(down - p);
      const float length = n.norm();
      if (!(length > 0.0f)) continue;
      n /= length;
      norm[col] = n.dot(p) > 0.0f ? Eigen::Vector3f(-n) : n;
    }
  });
}

/// Half resolution: each pixel averages the valid pixels of its 2x2 block that lie within
/// `band_m` of the nearest of them (so that a block straddling an edge does not average the
/// foreground with the background).
void halfResolution(const cv::Mat& depth_m, float band_m, cv::Mat* half_out) {
  half_out->create(depth_m.rows / 2, depth_m.cols / 2, CV_32FC1);
  cv::Mat& half = *half_out;
  forEachRow(half.rows, [&](int v) {
    const float* a = depth_m.ptr<float>(2 * v);
    const float* b = depth_m.ptr<float>(2 * v + 1);
    float* out = half.ptr<float>(v);
    for (int u = 0; u < half.cols; ++u) {
      const float d[4] = {a[2 * u], a[2 * u + 1], b[2 * u], b[2 * u + 1]};
      float nearest = std::numeric_limits<float>::infinity();
      for (float x : d) {
        if (x > 0.0f) nearest = std::min(nearest, x);
      }
      float sum = 0.0f;
      int n = 0;
      for (float x : d) {
        if (x > 0.0f && x - nearest <= band_m) {
          sum += x;
          ++n;
        }
      }
      out[u] = n > 0 ? sum / static_cast<float>(n) : 0.0f;
    }
  });
}

}  // namespace

void PreprocessConfig::validate() const {
  require(std::isfinite(min_depth_m) && min_depth_m >= 0.0f,
          "the minimum depth must be a finite number >= 0 m");
  require(std::isfinite(max_depth_m) && max_depth_m > min_depth_m,
          "the maximum depth must be finite and larger than the minimum depth");
  require(bilateral_radius_px >= 0 && bilateral_radius_px <= 10,
          "the bilateral filter radius must be 0 (off) to 10 pixels");
  require(bilateral_radius_px == 0 ||
              (bilateral_sigma_space_px > 0.0f && bilateral_sigma_depth_m > 0.0f),
          "the bilateral filter's sigmas must be positive");
  require(pyramid_levels >= 1 && pyramid_levels <= 5, "the pyramid must have 1 to 5 levels");
}

void clipDepth(const cv::Mat& depth_m, const PreprocessConfig& config, cv::Mat* clipped) {
  if (depth_m.type() != CV_32FC1) throw std::invalid_argument("depth must be CV_32FC1 metres");
  if (clipped->data == depth_m.data) throw std::invalid_argument("clipDepth cannot work in place");
  clipped->create(depth_m.size(), CV_32FC1);
  forEachRow(depth_m.rows, [&](int v) {
    const float* in = depth_m.ptr<float>(v);
    float* o = clipped->ptr<float>(v);
    for (int u = 0; u < depth_m.cols; ++u) {
      const float z = in[u];
      // NaN fails both comparisons and is dropped with the rest.
      o[u] = z >= config.min_depth_m && z <= config.max_depth_m ? z : 0.0f;
    }
  });
}

cv::Mat clipDepth(const cv::Mat& depth_m, const PreprocessConfig& config) {
  cv::Mat out;
  clipDepth(depth_m, config, &out);
  return out;
}

Intrinsics levelIntrinsics(const Intrinsics& full, int level) {
  Intrinsics in = full;
  const double s = 1.0 / static_cast<double>(1 << level);
  in.fx_px = full.fx_px * s;
  in.fy_px = full.fy_px * s;
  in.cx_px = (full.cx_px + 0.5) * s - 0.5;
  in.cy_px = (full.cy_px + 0.5) * s - 0.5;
  in.width_px = full.width_px >> level;
  in.height_px = full.height_px >> level;
  return in;
}

std::vector<Eigen::Vector3f> computeNormals(const std::vector<Eigen::Vector3f>& vertices_C,
                                            int width, int height) {
  std::vector<Eigen::Vector3f> normals;
  normalsInto(vertices_C, width, height, &normals);
  return normals;
}

void buildPyramid(const cv::Mat& clipped_depth_m, const Intrinsics& intrinsics,
                  const PreprocessConfig& config, DepthPyramid* pyramid,
                  int finest_sample_stride_px) {
  if (finest_sample_stride_px < 1) {
    throw std::invalid_argument("buildPyramid: the finest level's sample stride must be >= 1");
  }
  pyramid->levels.resize(static_cast<std::size_t>(config.pyramid_levels));
  for (int level = 0; level < config.pyramid_levels; ++level) {
    DepthLevel& l = pyramid->levels[static_cast<std::size_t>(level)];
    l.intrinsics = levelIntrinsics(intrinsics, level);
    if (level > 0) {
      halfResolution(pyramid->levels[static_cast<std::size_t>(level) - 1].depth_m,
                     3.0f * config.bilateral_sigma_depth_m, &l.depth_m);
    } else if (config.bilateral_radius_px > 0) {
      // OpenCV's filter weighs neighbours by exp(-dz^2 / 2 sigma^2): a missing reading (0) next
      // to a surface metres away gets weight ~0 and stays 0, and does not pull valid pixels to 0.
      cv::bilateralFilter(clipped_depth_m, l.depth_m, 2 * config.bilateral_radius_px + 1,
                          config.bilateral_sigma_depth_m, config.bilateral_sigma_space_px);
      // Keep holes holes: the filter may spread a little depth into a missing pixel.
      forEachRow(l.depth_m.rows, [&](int v) {
        const float* in = clipped_depth_m.ptr<float>(v);
        float* out = l.depth_m.ptr<float>(v);
        for (int u = 0; u < l.depth_m.cols; ++u) out[u] = in[u] == 0.0f ? 0.0f : out[u];
      });
    } else {
      clipped_depth_m.copyTo(l.depth_m);
    }
    l.sample_stride_px = level == 0 ? finest_sample_stride_px : 1;
    if (l.sample_stride_px > 1) {
      sampledVerticesAndNormals(l.depth_m, l.intrinsics, l.sample_stride_px, &l.vertices_C,
                                &l.normals_C);
    } else {
      backProject(l.depth_m, l.intrinsics, &l.vertices_C);
      normalsInto(l.vertices_C, l.depth_m.cols, l.depth_m.rows, &l.normals_C);
    }
  }
}

DepthPyramid buildPyramid(const cv::Mat& clipped_depth_m, const Intrinsics& intrinsics,
                          const PreprocessConfig& config, int finest_sample_stride_px) {
  DepthPyramid pyramid;
  buildPyramid(clipped_depth_m, intrinsics, config, &pyramid, finest_sample_stride_px);
  return pyramid;
}

}  // namespace objscan::fusion
