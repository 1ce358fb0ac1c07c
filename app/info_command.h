#pragma once

#include <filesystem>

namespace objscan::app {

/// `objscan info <path>`: prints to stdout what a mesh (.ply), a trajectory (TUM .txt) or a
/// recording (TUM-format folder) holds. Throws InputError for anything it cannot describe.
void runInfo(const std::filesystem::path& path);

}  // namespace objscan::app
