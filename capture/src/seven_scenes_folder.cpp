#include "objscan/capture/seven_scenes_folder.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <map>
#include <sstream>
#include <string>
#include <string_view>

#include "image_files.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"

namespace objscan::capture {
namespace fs = std::filesystem;
using detail::isFile;

namespace {

constexpr std::string_view kFramePrefix = "frame-";
constexpr std::string_view kDepthSuffix = ".depth.png";
constexpr std::string_view kPoseSuffix = ".pose.txt";
constexpr std::string_view kIntrinsicsName = "camera-intrinsics.txt";
/// The original 7-Scenes depth images mark pixels without a reading with 65535 as well as 0.
constexpr std::uint16_t kInvalidDepthMm = 65535;
/// How far RᵀR may be from the identity (largest entry) for a pose to count as rigid; the
/// datasets print 7 or more significant digits, which keeps them near 1e-7.
constexpr double kRigidTolerance = 1e-3;

/// The kind of one frame-NNNNNN.* file.
enum class FileKind { kDepth, kColorPng, kColorJpg, kPose };

/// Splits "frame-000012.depth.png" into 12 and kDepth; none for any other name.
std::optional<std::pair<std::int64_t, FileKind>> parseFrameFileName(const std::string& name) {
  const std::string_view view(name);
  if (!view.starts_with(kFramePrefix)) return std::nullopt;
  const std::size_t digits_end = view.find('.', kFramePrefix.size());
  if (digits_end == std::string_view::npos) return std::nullopt;
  const std::string_view digits =
      view.substr(kFramePrefix.size(), digits_end - kFramePrefix.size());
  if (digits.empty() || digits.size() > 12) return std::nullopt;
  std::int64_t number = 0;
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), number);
  if (ec != std::errc() || end != digits.data() + digits.size()) return std::nullopt;
  const std::string_view suffix = view.substr(digits_end);
  if (suffix == kDepthSuffix) return std::pair{number, FileKind::kDepth};
  if (suffix == ".color.png") return std::pair{number, FileKind::kColorPng};
  if (suffix == ".color.jpg") return std::pair{number, FileKind::kColorJpg};
  if (suffix == kPoseSuffix) return std::pair{number, FileKind::kPose};
  return std::nullopt;
}

/// Names of the regular files in `dir`. Throws InputError when it cannot be listed.
std::vector<std::string> fileNames(const fs::path& dir) {
  std::vector<std::string> names;
  std::error_code ec;
  fs::directory_iterator it(dir, ec);
  for (; !ec && it != fs::directory_iterator(); it.increment(ec)) {
    std::error_code type_ec;
    if (it->is_regular_file(type_ec)) names.push_back(it->path().filename().string());
  }
  if (ec) throw InputError(dir, "cannot list the folder: " + ec.message());
  return names;
}

/// One line of a small text matrix: its number in the file and its numbers.
struct MatrixRow {
  int line_no = 0;
  std::vector<double> values;
};

std::string lineLabel(int line_no) {
  std::string label = "line ";
  label.append(std::to_string(line_no)).append(": ");
  return label;
}

/// Reads the non-blank lines of a whitespace-separated text matrix. Throws InputError naming the
/// file and line for a token that is not a number or not finite, or a line with a number of
/// values other than `columns`, or a number of lines other than `rows`.
std::vector<MatrixRow> readMatrix(const fs::path& file, std::size_t rows, std::size_t columns,
                                  const std::string& what) {
  const std::string text = readWholeFile(file);
  std::istringstream in(text);
  std::vector<MatrixRow> result;
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    std::istringstream words(line);
    std::string word;
    MatrixRow row{line_no, {}};
    while (words >> word) {
      std::string_view token(word);
      if (token.starts_with('+')) token.remove_prefix(1);
      double v = 0.0;
      const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), v);
      if (ec != std::errc() || end != token.data() + token.size()) {
        std::string problem = lineLabel(line_no);
        problem.append("'").append(word).append("' is not a number");
        throw InputError(file, problem);
      }
      if (!std::isfinite(v)) {
        std::string problem = lineLabel(line_no);
        problem.append("'").append(word).append(
            "' is not a finite number (3DMatch writes -inf for frames where tracking was lost)");
        throw InputError(file, problem);
      }
      row.values.push_back(v);
    }
    if (row.values.empty()) continue;
    if (row.values.size() != columns) {
      std::string problem = lineLabel(line_no);
      problem.append("expected ")
          .append(std::to_string(columns))
          .append(" numbers, found ")
          .append(std::to_string(row.values.size()));
      throw InputError(file, problem);
    }
    result.push_back(std::move(row));
  }
  if (result.size() != rows) {
    std::string problem = "expected ";
    problem.append(std::to_string(rows))
        .append(" lines of ")
        .append(std::to_string(columns))
        .append(" numbers (")
        .append(what)
        .append("), found ")
        .append(std::to_string(result.size()));
    throw InputError(file, problem);
  }
  return result;
}

/// Reads one frame-NNNNNN.pose.txt: a 4x4 camera-to-world matrix with a rigid rotation.
Pose readPoseFile(const fs::path& file) {
  const std::vector<MatrixRow> rows = readMatrix(file, 4, 4, "a 4x4 camera-to-world matrix");
  Eigen::Matrix4d M;
  for (int r = 0; r < 4; ++r) {
    for (int c = 0; c < 4; ++c) M(r, c) = rows[r].values[c];
  }
  if ((M.row(3) - Eigen::RowVector4d(0, 0, 0, 1)).cwiseAbs().maxCoeff() > 1e-9) {
    throw InputError(file, lineLabel(rows[3].line_no).append("the last row must be 0 0 0 1"));
  }
  const Eigen::Matrix3d R = M.topLeftCorner<3, 3>();
  const double off = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  std::string lines = "lines ";
  lines.append(std::to_string(rows[0].line_no))
      .append("-")
      .append(std::to_string(rows[2].line_no))
      .append(": ");
  if (off > kRigidTolerance) {
    std::ostringstream problem;
    problem << lines << "the rotation is not rigid (the largest entry of R^T R - I is " << off
            << ", more than " << kRigidTolerance << ")";
    throw InputError(file, problem.str());
  }
  if (R.determinant() < 0) {
    throw InputError(file, lines.append("the rotation is a reflection (its determinant is -1)"));
  }
  Pose T_W_C = Pose::Identity();
  T_W_C.matrix() = M.cast<float>();
  if (!T_W_C.matrix().allFinite()) {
    throw InputError(file, lines.append("the translation is too large for single precision"));
  }
  return T_W_C;
}

}  // namespace

Intrinsics SevenScenesFolder::defaultIntrinsics() {
  Intrinsics k;
  k.fx_px = 585.0;
  k.fy_px = 585.0;
  k.cx_px = 320.0;
  k.cy_px = 240.0;
  k.width_px = 640;
  k.height_px = 480;
  return k;
}

bool SevenScenesFolder::looksLikeSevenScenesFolder(const fs::path& dir) {
  std::error_code ec;
  if (!fs::is_directory(dir, ec)) return false;
  fs::directory_iterator it(dir, ec);
  for (; !ec && it != fs::directory_iterator(); it.increment(ec)) {
    const auto parsed = parseFrameFileName(it->path().filename().string());
    std::error_code type_ec;
    if (parsed && parsed->second == FileKind::kDepth && it->is_regular_file(type_ec)) return true;
  }
  return false;
}

SevenScenesFolder::SevenScenesFolder(const fs::path& dir) : dir_(dir) {
  std::error_code ec;
  const fs::file_type type = fs::status(dir, ec).type();
  if (type == fs::file_type::not_found) throw InputError(dir, "no such file or directory");
  if (ec) throw InputError(dir, "cannot access: " + ec.message());
  if (type != fs::file_type::directory) throw InputError(dir, "is not a folder");

  // Frame number -> its files, in number order.
  std::map<std::int64_t, SevenScenesFrameFiles> by_number;
  const auto claim = [&](fs::path& slot, const std::string& name, std::int64_t number) {
    if (!slot.empty()) {
      std::string problem = "frame ";
      problem.append(std::to_string(number))
          .append(" also has ")
          .append(slot.string())
          .append("; remove one of the two");
      throw InputError(dir_ / name, problem);
    }
    slot = name;
  };
  std::vector<std::string> names = fileNames(dir);
  std::sort(names.begin(), names.end());
  for (const std::string& name : names) {
    const auto parsed = parseFrameFileName(name);
    if (!parsed) continue;
    const auto [number, kind] = *parsed;
    SevenScenesFrameFiles& f = by_number[number];
    f.number = number;
    switch (kind) {
      case FileKind::kDepth:
        claim(f.depth, name, number);
        break;
      case FileKind::kColorPng:
      case FileKind::kColorJpg:
        claim(f.color, name, number);
        break;
      case FileKind::kPose:
        claim(f.pose, name, number);
        break;
    }
  }
  std::size_t with_color = 0, with_pose = 0;
  for (auto& [number, f] : by_number) {
    if (f.depth.empty()) continue;  // colour or pose without depth: not a frame
    f.stamp_s = static_cast<double>(number) / kFrameRate_hz;
    with_color += !f.color.empty();
    with_pose += !f.pose.empty();
    frames_.push_back(f);
  }
  if (frames_.empty()) {
    throw InputError(dir, "is not a 7-Scenes folder (it has no frame-NNNNNN.depth.png images)");
  }

  // Colour and poses are for every frame or for none; name the first frame that lacks one.
  const auto requireAll = [&](std::size_t have, fs::path SevenScenesFrameFiles::*member,
                              const std::string& kind, const std::string& suffix) {
    if (have == 0 || have == frames_.size()) return;
    for (const SevenScenesFrameFiles& f : frames_) {
      if (!(f.*member).empty()) continue;
      std::string name = f.depth.string();
      name.resize(name.size() - kDepthSuffix.size());
      name.append(suffix);
      std::string problem = "missing: ";
      problem.append(std::to_string(have))
          .append(" of the ")
          .append(std::to_string(frames_.size()))
          .append(" frames have ")
          .append(kind)
          .append(", so every frame needs one");
      throw InputError(dir_ / name, problem);
    }
  };
  if (with_color > 0) {
    const fs::path& example = std::find_if(frames_.begin(), frames_.end(), [](const auto& f) {
                                return !f.color.empty();
                              })->color;
    requireAll(with_color, &SevenScenesFrameFiles::color, "a colour image",
               std::string(".color").append(example.extension().string()));
  }
  requireAll(with_pose, &SevenScenesFrameFiles::pose, "a pose file", std::string(kPoseSuffix));

  readIntrinsics();
  if (with_pose > 0) readPoses();
}

void SevenScenesFolder::readIntrinsics() {
  fs::path file;
  for (const fs::path& candidate : {dir_ / kIntrinsicsName, dir_ / ".." / kIntrinsicsName}) {
    if (isFile(candidate)) {
      file = candidate;
      break;
    }
  }
  if (file.empty()) return;  // the 7-Scenes calibration

  const std::vector<MatrixRow> rows =
      readMatrix(file, 3, 3, "the camera matrix fx 0 cx / 0 fy cy / 0 0 1");
  const auto& K = rows;
  if (K[0].values[1] != 0.0 || K[1].values[0] != 0.0 || K[2].values[0] != 0.0 ||
      K[2].values[1] != 0.0 || K[2].values[2] != 1.0) {
    throw InputError(file,
                     "is not a pinhole camera matrix: expected 'fx 0 cx / 0 fy cy / 0 0 1' (no "
                     "skew)");
  }
  Intrinsics k;
  k.fx_px = K[0].values[0];
  k.cx_px = K[0].values[2];
  k.fy_px = K[1].values[1];
  k.cy_px = K[1].values[2];
  // The file does not give the image size; the first depth image does (7-Scenes' 640x480 when its
  // header cannot be read, in which case load() reports the image).
  const fs::path first_depth = dir_ / frames_.front().depth;
  const std::optional<cv::Size> size = detail::pngImageSize(first_depth);
  k.width_px = size ? size->width : 640;
  k.height_px = size ? size->height : 480;
  try {
    k.validate();
  } catch (const std::invalid_argument& e) {
    std::string problem = e.what();
    problem.append(" (for the ")
        .append(std::to_string(k.width_px))
        .append("x")
        .append(std::to_string(k.height_px))
        .append(" images of ")
        .append(first_depth.filename().string())
        .append(")");
    throw InputError(file, problem);
  }
  intrinsics_ = k;
  intrinsics_file_ = file;
}

void SevenScenesFolder::readPoses() {
  Trajectory trajectory;
  trajectory.poses.reserve(frames_.size());
  for (const SevenScenesFrameFiles& f : frames_) {
    trajectory.poses.push_back({f.stamp_s, readPoseFile(dir_ / f.pose)});
  }
  ground_truth_ = std::move(trajectory);
}

RgbdFrame SevenScenesFolder::load(std::size_t i, const Intrinsics& intrinsics) const {
  const SevenScenesFrameFiles& f = frames_.at(i);
  const fs::path depth_path = dir_ / f.depth;
  const cv::Mat raw = detail::readImage(depth_path, ImageDecoding::kStoredGrey, [&](cv::Size size) {
    if (size.width == intrinsics.width_px && size.height == intrinsics.height_px) return;
    std::string problem = "image is ";
    problem.append(std::to_string(size.width))
        .append("x")
        .append(std::to_string(size.height))
        .append(" but the intrinsics are for ")
        .append(std::to_string(intrinsics.width_px))
        .append("x")
        .append(std::to_string(intrinsics.height_px));
    if (!intrinsicsFromFile() && intrinsics == intrinsics_) {
      problem.append(" (add a camera-intrinsics.txt to the folder)");
    }
    throw InputError(depth_path, problem);
  });
  if (raw.type() != CV_16UC1) {
    throw InputError(depth_path, "depth must be a single-channel 16-bit PNG (millimetres)");
  }
  RgbdFrame frame;
  frame.index = static_cast<std::int64_t>(i);
  frame.stamp_s = f.stamp_s;
  frame.intrinsics = intrinsics;
  frame.depth_m.create(raw.size(), CV_32FC1);
  for (int v = 0; v < raw.rows; ++v) {
    const std::uint16_t* in = raw.ptr<std::uint16_t>(v);
    float* out = frame.depth_m.ptr<float>(v);
    for (int u = 0; u < raw.cols; ++u) {
      // Division, not multiplication by 0.001f, so that the result is the float nearest mm / 1000.
      out[u] = in[u] == kInvalidDepthMm ? 0.0f : static_cast<float>(in[u]) / 1000.0f;
    }
  }

  if (!f.color.empty()) {
    const fs::path color_path = dir_ / f.color;
    frame.color_rgb = detail::readImage(color_path, ImageDecoding::kRgb8, [&](cv::Size size) {
      if (size == raw.size()) return;
      std::string problem = "colour image is ";
      problem.append(std::to_string(size.width))
          .append("x")
          .append(std::to_string(size.height))
          .append(" but the depth image ")
          .append(f.depth.string())
          .append(" is ")
          .append(std::to_string(raw.cols))
          .append("x")
          .append(std::to_string(raw.rows));
      throw InputError(color_path, problem);
    });
  }
  return frame;
}

}  // namespace objscan::capture
