#pragma once

/// The exit codes objscan documents (README, "Exit codes").
namespace objscan::app {

inline constexpr int kExitSuccess = 0;
inline constexpr int kExitRuntimeFailure = 1;  ///< something failed while working: I/O, a bug
inline constexpr int kExitBadInput = 2;        ///< bad usage, bad input file, or not built yet
inline constexpr int kExitNoSensor = 3;        ///< live mode, but no sensor is attached
/// Ctrl-C / SIGTERM cut a run short: what was written is complete, the rest was not produced.
inline constexpr int kExitInterrupted = 130;

}  // namespace objscan::app
