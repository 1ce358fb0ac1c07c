// The test programs' precompiled header: the third-party and standard headers most of their
// sources include, parsed once for all of them (tests/CMakeLists.txt). Only headers every test
// program can reach: GoogleTest, Eigen and OpenCV's core (through objscan::core), nlohmann-json
// (through the test support library). objscan's own headers stay out, so that a change to one
// rebuilds only the tests that include it.
#pragma once

#include <gtest/gtest.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <optional>
#include <random>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>
