#pragma once

#include <filesystem>
#include <memory>
#include <optional>
#include <string>

#include "objscan/capture/frame_source.h"
#include "objscan/core/intrinsics.h"

namespace objscan::capture {

/// Opens a dataset folder as a FrameSource: a TUM RGB-D recording (see TumFolder) or, failing
/// that, a 7-Scenes / 3DMatch folder (see SevenScenesFolder). The folder's index files, intrinsics
/// and ground truth are read here; images are decoded one frame per next().
///
/// next() returns the selected frames in folder order, each with RgbdFrame::index = its position
/// in the folder's full frame list, then kEndOfStream forever. A frame whose images cannot be
/// decoded, are of the wrong type, or differ in size from each other or from the intrinsics gives
/// kBadFrame with a reason naming the frame and the file, and the next call moves on; an image
/// that has vanished since the folder was opened throws InputError.
///
/// `intrinsics_override` replaces the folder's intrinsics in info() and in every frame;
/// `intrinsics_override_origin` (a file name, "command line", ...) is reported as their origin.
/// Its size is checked at open against the first selected frame's depth image (read from the PNG
/// header, without decoding): a different size throws InputError naming that image, and a later
/// frame of another size is a bad frame. A TUM folder checks its images against its own
/// intrinsics (intrinsics.json or the 640x480 defaults), so there an override of another size
/// than those is an InputError too, which says to put the calibration in intrinsics.json.
///
/// Throws InputError for a path that does not exist, is not a folder, or is a folder of neither
/// layout, and for everything TumFolder or SevenScenesFolder reject; std::invalid_argument for a
/// selection that fails FrameSelection::validate() or starts past the last frame, and for an
/// override that fails Intrinsics::validate().
std::unique_ptr<FrameSource> openFolderSource(
    const std::filesystem::path& dir, const FrameSelection& selection = {},
    const std::optional<Intrinsics>& intrinsics_override = std::nullopt,
    const std::string& intrinsics_override_origin = {});

}  // namespace objscan::capture
