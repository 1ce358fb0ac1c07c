#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>

#include "objscan/core/organized_cloud.h"
#include "objscan/discovery/scenes.h"
#include "objscan/pipeline/sources.h"

/// A single frame of a <source> as a scene for discovery: what a robot that looks at a table once
/// gets its objects from (`objscan discover <source> --frame N`).
namespace objscan::pipeline {

/// Frame `index` (0-based, in the source's order) of `source` (openFrameSource with `options`,
/// whose frame selection is replaced by this one frame), its points on the depth image's pixel
/// grid meshed by meshOrganized. A virtual sensor's frame is read from the source it streams (the
/// sensor would drop frames on a loaded machine); a live sensor's first `index` frames are skipped.
/// The scene is named "<source>@frame<index>"; with `hash`, its content hash is that of the
/// frame's depth, colour and camera, so a catalog knows the frame when it sees it again. Throws
/// InputError naming the source for an index past its end (saying how many frames it has, where
/// the source knows), a frame that cannot be read or one with no surface; what openFrameSource
/// throws for a source that cannot be opened.
discovery::SceneInput sceneOfFrame(const std::string& source, std::size_t index,
                                   const SourceOptions& options,
                                   const OrganizedMeshConfig& meshing = {}, bool hash = true);

/// A scene as discover's command line names it: loadScene(argument, reading), or with `frame`,
/// sceneOfFrame of the <source> `argument` (reading's intrinsics replacing the source's).
discovery::SceneInput readScene(const std::filesystem::path& argument,
                                const discovery::SceneReading& reading,
                                std::optional<std::size_t> frame);

}  // namespace objscan::pipeline
