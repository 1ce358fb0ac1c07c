#pragma once

#include <optional>

#include <Eigen/Core>

#include "objscan/core/triangle_mesh.h"
#include "objscan/discovery/context.h"
#include "objscan/discovery/supports.h"

namespace objscan::discovery {

/// The ground's up: the free side of the ground plane that the camera's up finds among the
/// supports (ContextConfig::view_up; the same ground segmentContexts uses); nothing without the
/// camera's up or without a support near it.
std::optional<Eigen::Vector3f> groundUp(const Supports& supports, const ContextConfig& config);

}  // namespace objscan::discovery
