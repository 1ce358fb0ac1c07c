#include "objscan/core/output_folder.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <string>

#include "objscan/core/error.h"
#include "test_support.h"

namespace objscan {
namespace {

namespace fs = std::filesystem;
using testing::TempDir;

/// The message of the FolderBusyError that locking `dir` throws; empty when it throws nothing.
std::string busyMessage(const fs::path& dir) {
  try {
    const OutputFolderLock second(dir);
  } catch (const FolderBusyError& e) {
    return e.what();
  }
  return {};
}

TEST(OutputFolderLock, OneHolderAtATimeNamedByItsProcess) {
  // Issue 18, defect 5: two runs into one --out left a folder mixing both.
  TempDir dir;
  const fs::path out = dir / "a" / "b";
  {
    OutputFolderLock lock = prepareOutputFolder(out);
    EXPECT_TRUE(fs::is_directory(out));
    EXPECT_TRUE(lock.held());
    const std::string message = busyMessage(out);
    EXPECT_NE(message.find(out.string() + ": another objscan run (process " +
                           std::to_string(::getpid()) + ": core_test)"),
              std::string::npos)
        << message;
    // A lock moves with its holder and is released once.
    OutputFolderLock moved = std::move(lock);
    EXPECT_FALSE(lock.held());  // NOLINT(bugprone-use-after-move): the moved-from state is defined
    EXPECT_FALSE(busyMessage(out).empty());
  }
  EXPECT_TRUE(busyMessage(out).empty()) << "released when the holder goes";
  EXPECT_EQ(testing::entryCount(out), 0u) << "the lock leaves nothing in the folder";
}

TEST(OutputFolderLock, AFileInTheWayIsAnOutputErrorNotABusyFolder) {
  TempDir dir;
  testing::writeBytes(dir / "file", "x");
  try {
    const OutputFolderLock lock = prepareOutputFolder(dir / "file");
    ADD_FAILURE() << "no error";
  } catch (const FolderBusyError& e) {
    ADD_FAILURE() << e.what();
  } catch (const OutputError& e) {
    EXPECT_NE(std::string(e.what()).find("cannot create the output folder"), std::string::npos);
  }
}

}  // namespace
}  // namespace objscan
