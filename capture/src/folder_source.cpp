#include "objscan/capture/folder_source.h"

#include <algorithm>
#include <opencv2/core.hpp>
#include <stdexcept>
#include <utility>
#include <vector>

#include "image_files.h"
#include "objscan/capture/seven_scenes_folder.h"
#include "objscan/capture/tum_folder.h"
#include "objscan/core/error.h"

namespace objscan::capture {
namespace fs = std::filesystem;

namespace {

std::string sizeText(int width, int height) {
  std::string text = std::to_string(width);
  text.append("x").append(std::to_string(height));
  return text;
}

/// The image files of frame i, relative to the folder (an empty path for none).
std::vector<fs::path> imagesOf(const TumFolder& folder, std::size_t i) {
  return {folder.frames()[i].depth, folder.frames()[i].rgb};
}
std::vector<fs::path> imagesOf(const SevenScenesFolder& folder, std::size_t i) {
  return {folder.frames()[i].depth, folder.frames()[i].color};
}

RgbdFrame loadWith(const TumFolder& folder, std::size_t i, const Intrinsics& intrinsics) {
  // TumFolder checks the image size against its own intrinsics, which openFolderSource made sure
  // have the size of these.
  RgbdFrame frame = folder.load(i);
  frame.intrinsics = intrinsics;
  return frame;
}
RgbdFrame loadWith(const SevenScenesFolder& folder, std::size_t i, const Intrinsics& intrinsics) {
  return folder.load(i, intrinsics);
}

/// Replays the selected frames of a TumFolder or SevenScenesFolder.
template <class Folder>
class FolderSource final : public FrameSource {
 public:
  FolderSource(std::unique_ptr<const Folder> folder, SourceInfo info,
               const FrameSelection& selection)
      : folder_(std::move(folder)),
        info_(std::move(info)),
        next_(selection.start),
        stop_(selection.end ? std::min(*selection.end, folder_->size()) : folder_->size()),
        every_(selection.every) {}

  const SourceInfo& info() const override { return info_; }

  FrameResult next() override {
    if (next_ >= stop_) return FrameResult::end();
    const std::size_t i = next_;
    next_ = every_ >= stop_ - i ? stop_ : i + every_;
    try {
      return FrameResult::ok(loadWith(*folder_, i, info_.intrinsics));
    } catch (const InputError& e) {
      // An image that is gone is a fatal problem with the folder, not a bad frame.
      for (const fs::path& image : imagesOf(*folder_, i)) {
        if (!image.empty() && !detail::isFile(folder_->dir() / image)) throw;
      }
      return bad(i, e.what());
    } catch (const cv::Exception& e) {
      return bad(i, e.what());
    }
  }

 private:
  static FrameResult bad(std::size_t i, const std::string& why) {
    std::string reason = "frame ";
    reason.append(std::to_string(i)).append(": ").append(why);
    return FrameResult::bad(std::move(reason));
  }

  std::unique_ptr<const Folder> folder_;
  SourceInfo info_;
  std::size_t next_;  ///< the next frame to load, in the folder's list
  std::size_t stop_;  ///< one past the last frame that may be selected
  std::size_t every_;
};

/// "TUM folder <dir>, 50 frames", plus the selection when it is not all of them.
std::string describe(const std::string& kind, const fs::path& dir, std::size_t total,
                     const FrameSelection& selection) {
  std::string text = kind;
  text.append(" folder ").append(dir.string()).append(", ").append(std::to_string(total));
  text.append(" frames");
  if (!selection.selectsAll()) {
    text.append(", ").append(std::to_string(selection.count(total))).append(" selected (from ");
    text.append(std::to_string(selection.start));
    if (selection.end) text.append(" to before ").append(std::to_string(*selection.end));
    text.append(", every ").append(std::to_string(selection.every)).append(")");
  }
  return text;
}

std::string overrideOrigin(const std::string& origin) {
  return origin.empty() ? std::string("the intrinsics override") : origin;
}

/// Checks an intrinsics override: validate() (std::invalid_argument), then its size against the
/// first selected depth image's PNG header (InputError naming the image). A header that cannot be
/// read is left for next() to report as a bad frame.
void checkOverride(const Intrinsics& k, const std::string& origin, const fs::path& first_depth) {
  try {
    k.validate();
  } catch (const std::invalid_argument& e) {
    std::string problem = overrideOrigin(origin);
    problem.append(": ").append(e.what());
    throw std::invalid_argument(problem);
  }
  const std::optional<cv::Size> size = detail::pngImageSize(first_depth);
  if (size && (size->width != k.width_px || size->height != k.height_px)) {
    std::string problem = "image is ";
    problem.append(sizeText(size->width, size->height))
        .append(" but the intrinsics from ")
        .append(overrideOrigin(origin))
        .append(" are for ")
        .append(sizeText(k.width_px, k.height_px));
    throw InputError(first_depth, problem);
  }
}

/// Applies the override (already checked) to `info` and wraps the folder.
template <class Folder>
std::unique_ptr<FrameSource> makeSource(std::unique_ptr<const Folder> folder, SourceInfo info,
                                        const FrameSelection& selection,
                                        const std::optional<Intrinsics>& intrinsics_override,
                                        const std::string& intrinsics_override_origin) {
  if (intrinsics_override) {
    info.intrinsics = *intrinsics_override;
    info.intrinsics_origin = overrideOrigin(intrinsics_override_origin);
    info.intrinsics_assumed = false;
  }
  return std::make_unique<FolderSource<Folder>>(std::move(folder), std::move(info), selection);
}

}  // namespace

std::unique_ptr<FrameSource> openFolderSource(const fs::path& dir, const FrameSelection& selection,
                                              const std::optional<Intrinsics>& intrinsics_override,
                                              const std::string& intrinsics_override_origin) {
  selection.validate();
  std::error_code ec;
  const fs::file_type type = fs::status(dir, ec).type();
  if (type == fs::file_type::not_found) throw InputError(dir, "no such file or directory");
  if (ec) throw InputError(dir, std::string("cannot access: ").append(ec.message()));
  if (type == fs::file_type::regular) {
    throw InputError(dir, "is a file; give the folder that holds the recording");
  }
  if (type != fs::file_type::directory) throw InputError(dir, "is not a folder");

  const auto checkStart = [&](std::size_t total) {
    if (selection.start < total) return;
    std::string problem = "--start (";
    problem.append(std::to_string(selection.start))
        .append(") is past the last frame of ")
        .append(dir.string())
        .append(", which has ")
        .append(std::to_string(total))
        .append(" frames (numbered from 0)");
    throw std::invalid_argument(problem);
  };

  if (TumFolder::looksLikeTumFolder(dir)) {
    auto folder = std::make_unique<const TumFolder>(dir);
    checkStart(folder->size());
    SourceInfo info;
    info.description = describe("TUM", dir, folder->size(), selection);
    info.frame_count = selection.count(folder->size());
    info.intrinsics = folder->intrinsics();
    info.intrinsics_origin =
        folder->intrinsicsFromFile()
            ? (dir / "intrinsics.json").string()
            : std::string("Xtion defaults (the folder has no intrinsics.json)");
    info.intrinsics_assumed = !folder->intrinsicsFromFile();
    info.depth_units =
        "16-bit value / " + std::to_string(static_cast<int>(folder->depthFactor())) + " = metres";
    info.ground_truth = folder->groundTruth();
    if (intrinsics_override) {
      const Intrinsics& k = *intrinsics_override;
      checkOverride(k, intrinsics_override_origin, dir / folder->frames()[selection.start].depth);
      if (k.width_px != info.intrinsics.width_px || k.height_px != info.intrinsics.height_px) {
        std::string problem = "the intrinsics from ";
        problem.append(overrideOrigin(intrinsics_override_origin))
            .append(" are for ")
            .append(sizeText(k.width_px, k.height_px))
            .append(" images but the folder's own (")
            .append(info.intrinsics_origin)
            .append(") are for ")
            .append(sizeText(info.intrinsics.width_px, info.intrinsics.height_px))
            .append(
                ", and a TUM folder checks its images against its own; put the calibration "
                "in ")
            .append((dir / "intrinsics.json").string())
            .append(" instead");
        throw InputError(dir, problem);
      }
    }
    return makeSource(std::unique_ptr<const TumFolder>(std::move(folder)), std::move(info),
                      selection, intrinsics_override, intrinsics_override_origin);
  }

  if (SevenScenesFolder::looksLikeSevenScenesFolder(dir)) {
    auto folder = std::make_unique<const SevenScenesFolder>(dir);
    checkStart(folder->size());
    SourceInfo info;
    info.description = describe("7-Scenes", dir, folder->size(), selection);
    info.frame_count = selection.count(folder->size());
    info.intrinsics = folder->intrinsics();
    info.intrinsics_origin =
        folder->intrinsicsFromFile()
            ? folder->intrinsicsFile().string()
            : std::string("7-Scenes defaults (the folder has no camera-intrinsics.txt)");
    info.intrinsics_assumed = !folder->intrinsicsFromFile();
    info.depth_units = "16-bit millimetres";
    info.ground_truth = folder->groundTruth();
    if (intrinsics_override) {
      checkOverride(*intrinsics_override, intrinsics_override_origin,
                    dir / folder->frames()[selection.start].depth);
    }
    return makeSource(std::unique_ptr<const SevenScenesFolder>(std::move(folder)), std::move(info),
                      selection, intrinsics_override, intrinsics_override_origin);
  }

  throw InputError(dir,
                   "is neither a TUM RGB-D folder (rgb.txt/depth.txt or an associations file) nor "
                   "a 7-Scenes folder (frame-NNNNNN.depth.png)");
}

}  // namespace objscan::capture
