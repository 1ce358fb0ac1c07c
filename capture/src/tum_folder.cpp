#include "objscan/capture/tum_folder.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <optional>
#include <sstream>

#include "image_files.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"

namespace objscan::capture {
namespace fs = std::filesystem;
using detail::isFile;
using detail::readImage;

namespace {

/// TUM's associate.py pairs stamps that differ by at most this much.
constexpr double kMaxAssociationGap_s = 0.02;

/// One data line of a TUM index file, split on whitespace; comments and blank lines give none.
struct IndexLine {
  int line_no = 0;
  std::vector<std::string> fields;
};

std::vector<IndexLine> readIndex(const fs::path& file) {
  const std::string text = readWholeFile(file);
  std::vector<IndexLine> lines;
  std::istringstream in(text);
  std::string line;
  int line_no = 0;
  while (std::getline(in, line)) {
    ++line_no;
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    IndexLine parsed{line_no, {}};
    std::istringstream words(line);
    std::string w;
    while (words >> w) parsed.fields.push_back(w);
    lines.push_back(std::move(parsed));
  }
  return lines;
}

double parseStamp(const fs::path& file, const IndexLine& line, std::size_t field) {
  const std::string& s = line.fields.at(field);
  std::size_t used = 0;
  double v = 0.0;
  try {
    v = std::stod(s, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (used != s.size() || !std::isfinite(v)) {
    throw InputError(file,
                     "line " + std::to_string(line.line_no) + ": '" + s + "' is not a time stamp");
  }
  return v;
}

/// Stamp + file pairs of rgb.txt or depth.txt.
std::vector<std::pair<double, fs::path>> readStampedFiles(const fs::path& file) {
  std::vector<std::pair<double, fs::path>> entries;
  for (const IndexLine& line : readIndex(file)) {
    if (line.fields.size() < 2) {
      throw InputError(file,
                       "line " + std::to_string(line.line_no) + ": expected 'timestamp filename'");
    }
    entries.emplace_back(parseStamp(file, line, 0), line.fields[1]);
  }
  // TUM's own files are in time order; pairing by time needs that, so make sure of it.
  std::stable_sort(entries.begin(), entries.end(),
                   [](const auto& a, const auto& b) { return a.first < b.first; });
  return entries;
}

}  // namespace

bool TumFolder::looksLikeTumFolder(const fs::path& dir) {
  for (const char* name : {"depth.txt", "associations.txt", "associate.txt"}) {
    if (isFile(dir / name)) return true;
  }
  return false;
}

TumFolder::TumFolder(const fs::path& dir) : dir_(dir) {
  std::error_code ec;
  const fs::file_type type = fs::status(dir, ec).type();
  if (type == fs::file_type::not_found) throw InputError(dir, "no such file or directory");
  if (ec) throw InputError(dir, "cannot access: " + ec.message());
  if (type != fs::file_type::directory) throw InputError(dir, "is not a folder");
  if (!looksLikeTumFolder(dir)) {
    throw InputError(dir,
                     "is a folder but not a TUM-format recording (it has no depth.txt, "
                     "associations.txt or associate.txt)");
  }

  if (isFile(dir / "associations.txt")) {
    readAssociations(dir / "associations.txt");
  } else if (isFile(dir / "associate.txt")) {
    readAssociations(dir / "associate.txt");
  } else {
    associateByTime();
  }
  if (frames_.empty()) throw InputError(dir, "the recording lists no frames");

  for (const TumFrameFiles& f : frames_) {
    for (const fs::path* p : {&f.depth, &f.rgb}) {
      if (!p->empty() && !isFile(dir_ / *p)) {
        throw InputError(dir_ / *p, "listed in " + association_source_ + " but missing");
      }
    }
  }

  const fs::path intrinsics_file = dir / "intrinsics.json";
  if (isFile(intrinsics_file)) {
    std::optional<double> depth_factor;
    intrinsics_ = readIntrinsicsJson(intrinsics_file, &depth_factor);
    intrinsics_from_file_ = true;
    if (depth_factor) depth_factor_ = *depth_factor;
  }

  if (isFile(dir / "groundtruth.txt")) {
    ground_truth_ = readTumTrajectory(dir / "groundtruth.txt");
    ground_truth_source_ = "groundtruth.txt";
  }
}

void TumFolder::readAssociations(const fs::path& file) {
  association_source_ = file.filename().string();
  Trajectory gt;
  const std::vector<IndexLine> lines = readIndex(file);
  for (const IndexLine& line : lines) {
    const std::string where = "line " + std::to_string(line.line_no) + ": ";
    if (line.fields.size() != 4 && line.fields.size() != 12) {
      throw InputError(file, where +
                                 "expected 'rgb_t rgb_file depth_t depth_file' (4 fields, or 12 "
                                 "with a ground-truth pose), found " +
                                 std::to_string(line.fields.size()));
    }
    if (line.fields.size() != lines.front().fields.size()) {
      throw InputError(file, where + "has " + std::to_string(line.fields.size()) +
                                 " fields but line " + std::to_string(lines.front().line_no) +
                                 " has " + std::to_string(lines.front().fields.size()) +
                                 "; every line needs the same columns");
    }
    TumFrameFiles f;
    // associate.py writes its two inputs in the order given; tell them apart by folder name.
    const bool depth_first =
        line.fields[1].rfind("depth", 0) == 0 && line.fields[3].rfind("rgb", 0) == 0;
    const std::size_t rgb_col = depth_first ? 2 : 0;
    const std::size_t depth_col = depth_first ? 0 : 2;
    f.rgb_stamp_s = parseStamp(file, line, rgb_col);
    f.rgb = line.fields[rgb_col + 1];
    f.depth_stamp_s = parseStamp(file, line, depth_col);
    f.depth = line.fields[depth_col + 1];
    frames_.push_back(f);
    if (line.fields.size() == 12) {
      std::array<double, 8> v{};
      for (std::size_t k = 0; k < 8; ++k) v[k] = parseStamp(file, line, 4 + k);
      try {
        gt.poses.push_back(stampedPoseFromTum(v));
      } catch (const std::invalid_argument& e) {
        throw InputError(file, where + "ground-truth pose " + e.what());
      }
    }
  }
  // Frames are fused, and their poses written, in time order: a list out of order (lines moved
  // by hand, files joined) is sorted by depth time stamp, as TUM's own files are.
  const auto by_depth_stamp = [](const TumFrameFiles& a, const TumFrameFiles& b) {
    return a.depth_stamp_s < b.depth_stamp_s;
  };
  if (!std::is_sorted(frames_.begin(), frames_.end(), by_depth_stamp)) {
    std::stable_sort(frames_.begin(), frames_.end(), by_depth_stamp);
    std::stable_sort(
        gt.poses.begin(), gt.poses.end(),
        [](const StampedPose& a, const StampedPose& b) { return a.stamp_s < b.stamp_s; });
    log::warning(file.string() +
                 ": the frames are not listed in time order; they are used sorted by depth time "
                 "stamp");
  }
  if (!gt.empty()) {
    ground_truth_ = std::move(gt);
    ground_truth_source_ = association_source_ + " (columns 5-12)";
  }
}

void TumFolder::associateByTime() {
  const auto depth = readStampedFiles(dir_ / "depth.txt");
  std::vector<std::pair<double, fs::path>> rgb;
  if (isFile(dir_ / "rgb.txt")) rgb = readStampedFiles(dir_ / "rgb.txt");
  association_source_ =
      rgb.empty() ? "depth.txt (no colour)" : "depth.txt + rgb.txt (nearest time stamps)";

  // Greedy one-to-one matching by smallest time difference, as TUM's associate.py does.
  struct Candidate {
    double gap_s;
    std::size_t d, r;
  };
  std::vector<Candidate> candidates;
  for (std::size_t d = 0; d < depth.size(); ++d) {
    const auto it = std::lower_bound(rgb.begin(), rgb.end(), depth[d].first,
                                     [](const auto& e, double t) { return e.first < t; });
    for (auto r = it == rgb.begin() ? it : it - 1; r != rgb.end() && r <= it; ++r) {
      const double gap = std::abs(r->first - depth[d].first);
      if (gap <= kMaxAssociationGap_s)
        candidates.push_back({gap, d, static_cast<std::size_t>(r - rgb.begin())});
    }
  }
  std::sort(candidates.begin(), candidates.end(),
            [](const Candidate& a, const Candidate& b) { return a.gap_s < b.gap_s; });
  std::vector<long> rgb_of_depth(depth.size(), -1);
  std::vector<bool> rgb_used(rgb.size(), false);
  for (const Candidate& c : candidates) {
    if (rgb_of_depth[c.d] >= 0 || rgb_used[c.r]) continue;
    rgb_of_depth[c.d] = static_cast<long>(c.r);
    rgb_used[c.r] = true;
  }
  for (std::size_t d = 0; d < depth.size(); ++d) {
    if (!rgb.empty() && rgb_of_depth[d] < 0)
      continue;  // no colour close enough: skip, as associate.py does
    TumFrameFiles f;
    f.depth_stamp_s = depth[d].first;
    f.depth = depth[d].second;
    if (rgb_of_depth[d] >= 0) {
      f.rgb_stamp_s = rgb[rgb_of_depth[d]].first;
      f.rgb = rgb[rgb_of_depth[d]].second;
    }
    frames_.push_back(f);
  }
}

RgbdFrame TumFolder::load(std::size_t i) const {
  const TumFrameFiles& f = frames_.at(i);
  const fs::path depth_path = dir_ / f.depth;
  const cv::Mat raw = readImage(depth_path, ImageDecoding::kStoredGrey, [&](cv::Size size) {
    if (size.width == intrinsics_.width_px && size.height == intrinsics_.height_px) return;
    throw InputError(depth_path,
                     "image is " + std::to_string(size.width) + "x" + std::to_string(size.height) +
                         " but the intrinsics are for " + std::to_string(intrinsics_.width_px) +
                         "x" + std::to_string(intrinsics_.height_px) +
                         (intrinsics_from_file_ ? "" : " (add an intrinsics.json to the folder)"));
  });
  if (raw.type() != CV_16UC1) {
    throw InputError(depth_path, "depth must be a single-channel 16-bit PNG (value / " +
                                     std::to_string(static_cast<int>(depth_factor_)) +
                                     " = metres)");
  }
  RgbdFrame frame;
  frame.index = static_cast<std::int64_t>(i);
  frame.stamp_s = f.depth_stamp_s;
  frame.intrinsics = intrinsics_;
  raw.convertTo(frame.depth_m, CV_32FC1, 1.0 / depth_factor_);

  if (!f.rgb.empty()) {
    const fs::path rgb_path = dir_ / f.rgb;
    frame.color_rgb = readImage(rgb_path, ImageDecoding::kRgb8, [&](cv::Size size) {
      if (size != raw.size()) throw InputError(rgb_path, "colour and depth images differ in size");
    });
  }
  return frame;
}

}  // namespace objscan::capture
