#pragma once

#include <cstdint>
#include <optional>
#include <string>

/// How much memory this machine can still give the process, so that work too large for it is
/// refused (or stopped) with a figure and the option to change, never ended by std::bad_alloc.
namespace objscan {

/// The environment variable that sets the memory objscan may use, in bytes (suffixes k, M, G
/// allowed: "2G"); it replaces what the machine reports. For machines shared with other work,
/// and for tests.
inline constexpr char kMemoryLimitEnv[] = "OBJSCAN_MEMORY_LIMIT";

/// Bytes the process can still take: OBJSCAN_MEMORY_LIMIT when set, else MemAvailable of
/// /proc/meminfo lowered to what the control group's memory.max leaves. nullopt when none can be
/// read (then nothing is refused). Throws std::invalid_argument for an OBJSCAN_MEMORY_LIMIT that
/// is not a size.
std::optional<std::uint64_t> availableMemoryBytes();

/// "the 12 GB this machine has free", or "the 2.0 GB OBJSCAN_MEMORY_LIMIT allows" when set.
std::string availableMemoryText(std::uint64_t available);

/// "5.8 GB", "340 MB", "12 kB": one decimal below 10 of a unit.
std::string bytesText(std::uint64_t bytes);

}  // namespace objscan
