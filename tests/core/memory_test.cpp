#include "objscan/core/memory.h"

#include <gtest/gtest.h>

#include <cstdlib>
#include <stdexcept>

namespace objscan {
namespace {

TEST(Memory, BytesReadAsAPersonWrites) {
  EXPECT_EQ(bytesText(512), "512 bytes");
  EXPECT_EQ(bytesText(1500), "1.5 kB");
  EXPECT_EQ(bytesText(340'000'000), "340 MB");
  EXPECT_EQ(bytesText(5'800'000'000), "5.8 GB");
}

TEST(Memory, TheEnvironmentLimitReplacesWhatTheMachineReports) {
  ASSERT_EQ(::unsetenv(kMemoryLimitEnv), 0);
  const std::optional<std::uint64_t> machine = availableMemoryBytes();
  ASSERT_TRUE(machine.has_value()) << "/proc/meminfo is readable on Linux";
  EXPECT_GT(*machine, 0u);
  EXPECT_NE(availableMemoryText(*machine).find("this machine has free"), std::string::npos);
  ASSERT_EQ(::setenv(kMemoryLimitEnv, "2G", 1), 0);
  EXPECT_EQ(availableMemoryBytes(), std::optional<std::uint64_t>(2'000'000'000));
  EXPECT_EQ(availableMemoryText(2'000'000'000), "the 2.0 GB OBJSCAN_MEMORY_LIMIT allows");
  ASSERT_EQ(::setenv(kMemoryLimitEnv, "1500000", 1), 0);
  EXPECT_EQ(availableMemoryBytes(), std::optional<std::uint64_t>(1'500'000));
  ASSERT_EQ(::setenv(kMemoryLimitEnv, "3g", 1), 0);
  EXPECT_EQ(availableMemoryBytes(), std::optional<std::uint64_t>(3'000'000'000));
  for (const char* bad : {"lots", "-1G", "2T", "0", "0.5", "1e30", "18446744073709551615"}) {
    ASSERT_EQ(::setenv(kMemoryLimitEnv, bad, 1), 0);
    EXPECT_THROW(availableMemoryBytes(), std::invalid_argument) << bad;
  }
  ::unsetenv(kMemoryLimitEnv);
}

}  // namespace
}  // namespace objscan
