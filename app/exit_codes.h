#pragma once

/// The exit codes objscan documents (README, "Exit codes").
namespace objscan::app {

inline constexpr int kExitSuccess = 0;
inline constexpr int kExitRuntimeFailure = 1;  ///< something failed while working: I/O, a bug
inline constexpr int kExitBadInput = 2;        ///< bad usage, bad input file, or not built yet

}  // namespace objscan::app
