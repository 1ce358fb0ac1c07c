#pragma once

#include <cstddef>
#include <string>

#include "objscan/core/organized_cloud.h"
#include "objscan/discovery/scenes.h"
#include "objscan/pipeline/sources.h"

/// A single frame of a <source> as a scene for discovery: what a robot that looks at a table once
/// gets its objects from (`objscan discover <source> --frame N`).
namespace objscan::pipeline {

/// Frame `index` (0-based, in the source's order) of `source` (openFrameSource with `options`;
/// its frame selection is replaced by this one frame, and a live sensor's first `index` frames are
/// skipped), its points on the depth image's pixel grid meshed by meshOrganized. The scene is
/// named "<source>@frame<index>" and its content hash is that of the frame's depth and colour, so
/// a catalog knows the frame when it sees it again. Throws InputError naming the source for an
/// index past its end (saying how many frames it has), a frame that cannot be read or one with no
/// surface; what openFrameSource throws for a source that cannot be opened.
discovery::SceneInput sceneOfFrame(const std::string& source, std::size_t index,
                                   const SourceOptions& options,
                                   const OrganizedMeshConfig& meshing = {});

}  // namespace objscan::pipeline
