// Where the tests and benchmarks find the source tree, the shared data and the objscan binary of
// this build. The paths are definitions on one source (build_paths.cpp, the objscan_build_paths
// library) and not on every test source: absolute paths in each compile command made every test
// source miss ccache's cache in a checkout elsewhere (CI's fresh one), though nothing in it had
// changed.
#pragma once

namespace objscan::build_paths {

const char* sourceDir();   ///< the source tree
const char* dataDir();     ///< the shared data (CMake's OBJSCAN_DATA_DIR)
const char* objscanExe();  ///< the objscan binary this build makes

}  // namespace objscan::build_paths

#define OBJSCAN_SOURCE_DIR (::objscan::build_paths::sourceDir())
#define OBJSCAN_DATA_DIR (::objscan::build_paths::dataDir())
#define OBJSCAN_EXE (::objscan::build_paths::objscanExe())
