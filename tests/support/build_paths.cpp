#include "build_paths.h"

// The paths come as definitions on this one source (CMakeLists.txt, objscan_build_paths).
namespace objscan::build_paths {

const char* sourceDir() { return OBJSCAN_BUILD_SOURCE_DIR; }
const char* dataDir() { return OBJSCAN_BUILD_DATA_DIR; }
const char* objscanExe() { return OBJSCAN_BUILD_EXE; }

}  // namespace objscan::build_paths
