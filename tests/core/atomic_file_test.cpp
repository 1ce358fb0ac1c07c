#include "objscan/core/atomic_file.h"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cerrno>

#include "objscan/core/error.h"
#include "test_support.h"

namespace objscan {
namespace {

TEST(AtomicFile, WritesAndReplacesWholeContents) {
  testing::TempDir dir;
  writeFileAtomically(dir / "f", "first version, longer");
  writeFileAtomically(dir / "f", "second");
  EXPECT_EQ(readWholeFile(dir / "f"), "second");
  EXPECT_EQ(testing::entryCount(dir.path()), 1u);
}

TEST(AtomicFile, ReplacedFileKeepsItsPermissions) {
  testing::TempDir dir;
  writeFileAtomically(dir / "f", "first");
  std::filesystem::permissions(
      dir / "f", std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  writeFileAtomically(dir / "f", "second");
  EXPECT_EQ(std::filesystem::status(dir / "f").permissions(),
            std::filesystem::perms::owner_read | std::filesystem::perms::owner_write);
  EXPECT_EQ(readWholeFile(dir / "f"), "second");
}

TEST(AtomicFile, FailedWriteLeavesTheOldFileAndNoTemporary) {
  // A file-size limit makes write() fail with EFBIG part-way, as a full disk would, and works
  // for root too (directory permissions do not).
  testing::TempDir dir;
  writeFileAtomically(dir / "f", "old");
  bool threw = false;
  {
    const testing::FileSizeLimit limit(4);
    try {
      writeFileAtomically(dir / "f", std::string(1000, 'n'));
    } catch (const OutputError& e) {
      threw = true;
      EXPECT_NE(std::string(e.what()).find("write failed"), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(threw);
  EXPECT_EQ(readWholeFile(dir / "f"), "old");
  EXPECT_EQ(testing::entryCount(dir.path()), 1u);
}

TEST(AtomicFile, StagedFilesAreWrittenWholeOrNotAtAll) {
  testing::TempDir dir;
  const std::filesystem::path staging = dir / "objects.partial";
  std::filesystem::create_directory(staging);
  writeStagedFile(staging / "a.ply", "mesh");
  EXPECT_EQ(readWholeFile(staging / "a.ply"), "mesh");
  // A staged file is new: one already there is a mistake, named, and left as it was.
  EXPECT_THROW(writeStagedFile(staging / "a.ply", "other"), OutputError);
  EXPECT_EQ(readWholeFile(staging / "a.ply"), "mesh");
  // A write that fails part-way (a file-size limit, as a full disk) leaves no half file.
  bool threw = false;
  {
    const testing::FileSizeLimit limit(4);
    try {
      writeStagedFile(staging / "b.ply", std::string(1000, 'n'));
    } catch (const OutputError& e) {
      threw = true;
      EXPECT_NE(std::string(e.what()).find("b.ply"), std::string::npos) << e.what();
      EXPECT_NE(std::string(e.what()).find("write failed"), std::string::npos) << e.what();
    }
  }
  EXPECT_TRUE(threw);
  EXPECT_EQ(testing::entryCount(staging), 1u);
  makeStagedFolderDurable(staging);
  EXPECT_EQ(readWholeFile(staging / "a.ply"), "mesh");
}

TEST(AtomicFile, FailedRenameRemovesTheTemporary) {
  testing::TempDir dir;
  std::filesystem::create_directories(dir / "target" / "inside");
  EXPECT_THROW(writeFileAtomically(dir / "target", "data"), OutputError);
  EXPECT_TRUE(std::filesystem::is_directory(dir / "target" / "inside"));
  EXPECT_EQ(testing::entryCount(dir.path()), 1u);
  EXPECT_THROW(writeFileAtomically(dir / "missing" / "f", "x"), OutputError);
}

TEST(AtomicFile, AFileNamedNearTheNameLimitIsWritten) {
  // Its temporary name "<name>.tmp-PID-N" would pass 255 bytes (record --out with a long name
  // wrote the .oni and then failed on its sidecar).
  testing::TempDir dir;
  const std::filesystem::path file = dir / (std::string(250, 'a') + ".json");
  writeFileAtomically(file, "{}");
  EXPECT_EQ(readWholeFile(file), "{}");
  EXPECT_EQ(testing::entryCount(dir.path()), 1u);
}

// What a run killed mid-write leaves (the fault audit): the next run into the folder removes it, but not
// a temporary of a process that still runs, nor files that only look alike.
TEST(AtomicFile, StaleTemporariesOfDeadWritersAreRemoved) {
  testing::TempDir dir;
  std::filesystem::create_directories(dir / "objects");
  const std::string self = std::to_string(::getpid());
  // 999999999 is past Linux's largest pid (2^22): no such process.
  for (const char* name : {"mesh.ply.tmp-999999999-42", ".objscan.tmp-999999999-1"}) {
    testing::writeBytes(dir / name, "half");
  }
  // Kept: a live writer's (this process, pid 1), names that only look alike, a subfolder's.
  for (const std::string& name :
       {"hypotheses.json.tmp-" + self + "-3", std::string("a.tmp-1-5"), std::string("notes.tmp-x"),
        std::string("photo.tmp-999999999-1.jpg"), std::string("backup.tmp-2024-01-05"),
        std::string("x.tmp-999999999-1234567890"), std::string("objects/r.ply.tmp-999999999-7"),
        std::string("mesh.ply")}) {
    testing::writeBytes(dir / name, "kept");
  }
  EXPECT_EQ(removeStaleTemporaries(dir.path()), 2u);
  EXPECT_FALSE(std::filesystem::exists(dir / "mesh.ply.tmp-999999999-42"));
  EXPECT_FALSE(std::filesystem::exists(dir / ".objscan.tmp-999999999-1"));
  EXPECT_TRUE(std::filesystem::exists(dir / ("hypotheses.json.tmp-" + self + "-3")));
  EXPECT_TRUE(std::filesystem::exists(dir / "a.tmp-1-5"));  // pid 1 runs
  EXPECT_TRUE(std::filesystem::exists(dir / "objects/r.ply.tmp-999999999-7"));
  EXPECT_EQ(testing::entryCount(dir.path()), 8u);
}

TEST(AtomicFile, ReadWholeFileErrorsNameThePath) {
  testing::TempDir dir;
  testing::expectInputError([&] { readWholeFile(dir / "absent"); }, dir / "absent",
                            "no such file or directory");
  testing::expectInputError([&] { readWholeFile(dir.path()); }, dir.path(), "is a directory");
  testing::writeBytes(dir / "empty", "");
  EXPECT_EQ(readWholeFile(dir / "empty"), "");
}

}  // namespace
}  // namespace objscan

namespace objscan {
namespace {

TEST(AtomicFile, WriteProbeLeavesNothingAndReportsTheError) {
  testing::TempDir dir;
  EXPECT_EQ(probeWritableFolder(dir.path()), 0);
  EXPECT_EQ(testing::entryCount(dir.path()), 0u);
  EXPECT_EQ(probeWritableFolder(dir / "missing"), ENOENT);
  // sysfs takes no new files, even from root (whom permissions would not stop).
  EXPECT_NE(probeWritableFolder("/sys"), 0);
}

}  // namespace
}  // namespace objscan
