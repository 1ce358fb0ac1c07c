#include "objscan/capture/oni_container.h"

#include <gtest/gtest.h>

#include "objscan/core/error.h"
#include "test_support.h"

namespace objscan::capture {
namespace {

using objscan::testing::expectInputError;
using objscan::testing::TempDir;
using objscan::testing::writeBytes;

std::string le32(std::uint32_t v) {
  std::string s(4, '\0');
  for (int i = 0; i < 4; ++i) s[i] = static_cast<char>(v >> (8 * i));
  return s;
}

std::string le64(std::uint64_t v) { return le32(static_cast<std::uint32_t>(v)) + le32(v >> 32); }

/// An OpenNI string field: u32 size including the terminating NUL, then the characters and NUL.
std::string oniString(const std::string& s) {
  std::string out = le32(static_cast<std::uint32_t>(s.size() + 1));
  out.append(s);
  out.push_back('\0');
  return out;
}

// Record types (OpenNI2 Source/Core/OniDataRecords.h).
constexpr std::uint32_t kGeneralProperty = 0x06, kNodeRemoved = 0x07, kNodeDataBegin = 0x08,
                        kNodeStateReady = 0x09, kNewData = 0x0A, kEnd = 0x0B, kNodeAdded = 0x0D,
                        kSeekTable = 0x0E;

/// Lays out an .oni file byte by byte as OpenNI2's recorder writes one (Source/Core/
/// OniDataRecords.cpp, OniRecorder.cpp); integers little-endian, no padding:
///   file header, 24 bytes: "NI10", version 1.0.1.0 as u8 u8 u16 u32, u64 maximum time stamp,
///     u32 maximum node id (0 until the recorder closes the file);
///   records: a 28-byte header {u32 magic "NIR\0", u32 type, u32 node id, u32 fields size
///     (header included), u32 payload size, u64 undo position}, the fields, then the payload.
class OniBuilder {
 public:
  OniBuilder() {
    bytes_ = "NI10";
    bytes_ += std::string{1, 0, 1, 0} + le32(0);  // version 1.0.1.0
    bytes_ += le64(~0ull) + le32(0);              // max time stamp: "unknown", max node id
  }

  /// Appends a record; returns its position.
  std::size_t record(std::uint32_t type, std::uint32_t node, const std::string& fields = "",
                     const std::string& payload = "", std::uint64_t undo_pos = 0) {
    const std::size_t pos = bytes_.size();
    bytes_ += le32(0x0052494E) + le32(type) + le32(node) +
              le32(static_cast<std::uint32_t>(28 + fields.size())) +
              le32(static_cast<std::uint32_t>(payload.size())) + le64(undo_pos);
    bytes_ += fields;
    bytes_ += payload;
    return pos;
  }

  /// NodeAdded fields: name, u32 node type (2 depth, 3 image), codec fourcc, u32 frame count,
  /// u64 min and max time stamp, u64 seek table position. The recorder writes frames 0xFFFFFFFF
  /// and seek position 0, then rewrites the record in place when it detaches the stream.
  static std::string nodeAddedFields(const std::string& name, std::uint32_t type,
                                     const std::string& codec, std::uint32_t frames,
                                     std::uint64_t seek_pos) {
    return oniString(name) + le32(type) + codec + le32(frames) + le64(0) + le64(~0ull) +
           le64(seek_pos);
  }

  std::size_t nodeAdded(std::uint32_t node, const std::string& name, std::uint32_t type,
                        const std::string& codec) {
    return record(kNodeAdded, node, nodeAddedFields(name, type, codec, 0xFFFFFFFF, 0));
  }

  /// Overwrites the NodeAdded record at `pos` with the same size, as the recorder does at detach.
  void rewriteNodeAdded(std::size_t pos, std::uint32_t node, const std::string& name,
                        std::uint32_t type, const std::string& codec, std::uint32_t frames,
                        std::uint64_t seek_pos) {
    OniBuilder one;
    one.record(kNodeAdded, node, nodeAddedFields(name, type, codec, frames, seek_pos));
    const std::string rec = one.bytes_.substr(24);
    bytes_.replace(pos, rec.size(), rec);
  }

  /// A property: name, u32 data size, data (all fields, no payload).
  void property(std::uint32_t node, const std::string& name, const std::string& data) {
    record(kGeneralProperty, node,
           oniString(name) + le32(static_cast<std::uint32_t>(data.size())) + data);
  }

  /// Seek table payload: (frames + 1) entries {u64 time stamp, u32 configuration, u64 position},
  /// the first one empty.
  std::size_t seekTable(std::uint32_t node, const std::vector<std::uint64_t>& frame_positions) {
    std::string payload = le64(0) + le32(0) + le64(0);
    for (std::size_t i = 0; i < frame_positions.size(); ++i) {
      payload += le64(33000 * i) + le32(0) + le64(frame_positions[i]);
    }
    return record(kSeekTable, node, "", payload);
  }

  void setMaxNodeId(std::uint32_t id) { bytes_.replace(20, 4, le32(id)); }
  const std::string& bytes() const { return bytes_; }

 private:
  std::string bytes_;
};

struct StreamSpec {
  std::uint32_t node;
  const char* name;
  std::uint32_t type;
  const char* codec;
  int width, height;
};
const StreamSpec kDepth{1, "Depth", 2, "16zT", 320, 240};
const StreamSpec kColor{2, "Image", 3, "NONE", 640, 480};

/// A depth + colour recording in the order OpenNI2's recorder writes one: per stream NodeAdded and
/// properties; NodeStateReady and NodeDataBegin at start; a NewData record per frame (16-byte
/// payloads), each pointing back to its stream's previous frame. When `closed`: per stream
/// NodeRemoved, SeekTable and the rewritten NodeAdded, then the End record and the patched
/// maximum node id. `declared_depth_frames` overrides the count the depth NodeAdded declares.
std::string recording(int frames, bool closed, int declared_depth_frames = -1) {
  OniBuilder b;
  std::vector<std::size_t> added;
  for (const StreamSpec& s : {kDepth, kColor}) {
    added.push_back(b.nodeAdded(s.node, s.name, s.type, s.codec));
    b.property(s.node, "xnIsGenerating", le64(1));
    b.property(s.node, "xnMapOutputMode", le32(s.width) + le32(s.height) + le32(30));
  }
  for (const StreamSpec& s : {kDepth, kColor}) {
    b.record(kNodeStateReady, s.node);
    b.record(kNodeDataBegin, s.node, le32(0xFFFFFFFF) + le64(~0ull));
  }
  std::vector<std::uint64_t> positions[2];
  for (int f = 1; f <= frames; ++f) {
    for (int i = 0; i < 2; ++i) {
      const std::uint64_t undo = positions[i].empty() ? 0 : positions[i].back();
      positions[i].push_back(b.record(kNewData, i + 1, le64(33000 * (f - 1)) + le32(f),
                                      std::string(16, static_cast<char>(f)), undo));
    }
  }
  if (!closed) return b.bytes();
  int i = 0;
  for (const StreamSpec& s : {kDepth, kColor}) {
    b.record(kNodeRemoved, s.node, "", "", added[i]);
    const std::size_t table = b.seekTable(s.node, positions[i]);
    const int declared = (i == 0 && declared_depth_frames >= 0) ? declared_depth_frames : frames;
    b.rewriteNodeAdded(added[i], s.node, s.name, s.type, s.codec, declared, table);
    ++i;
  }
  b.record(kEnd, 0);
  b.setMaxNodeId(2);
  return b.bytes();
}

TEST(OniContainer, FinishedTwoStreamRecordingIsSound) {
  TempDir dir;
  const auto file = dir / "scan.oni";
  writeBytes(file, recording(3, true));
  const OniFileSummary summary = inspectOniFile(file);
  EXPECT_TRUE(summary.finished);
  EXPECT_EQ(summary.problem, "");
  EXPECT_EQ(summary.bytes, recording(3, true).size());
  ASSERT_EQ(summary.streams.size(), 2u);
  const OniStreamSummary& depth = summary.streams[0];
  const OniStreamSummary& color = summary.streams[1];
  EXPECT_EQ(depth.type, "depth");
  EXPECT_EQ(color.type, "color");
  EXPECT_EQ(depth.node_name, "Depth");
  EXPECT_EQ(color.node_id, 2u);
  EXPECT_EQ(depth.data_records, 3u);
  EXPECT_EQ(color.data_records, 3u);
  EXPECT_EQ(depth.declared_frames, 3u);
  EXPECT_EQ(color.declared_frames, 3u);
  for (const OniStreamSummary& s : summary.streams) {
    EXPECT_TRUE(s.data_begun);
    EXPECT_TRUE(s.removed);
    EXPECT_TRUE(s.has_seek_table);
  }
  EXPECT_EQ(depth.width, 320);
  EXPECT_EQ(depth.height, 240);
  EXPECT_EQ(color.width, 640);
  EXPECT_EQ(oniCodecName(depth.codec_id), "16z with tables (lossless)");
  EXPECT_EQ(oniCodecName(color.codec_id), "uncompressed");
  // The same file is fine when tolerating unfinished ones.
  EXPECT_TRUE(inspectOniFile(file, true).finished);
}

// OpenNI2's recorder closes a file by truncating it to its current end, but XnLib's Linux
// xnOSTruncateFile64 calls ftruncate(fd, old position + new position): every recording closed on
// Linux is twice as long as its records, the second half zeros (seen in DummyDevice recordings).
TEST(OniContainer, ZeroPaddingAfterTheEndRecordIsIgnored) {
  TempDir dir;
  const auto file = dir / "linux.oni";
  const std::string records = recording(3, true);
  writeBytes(file, records + std::string(records.size(), '\0'));
  const OniFileSummary summary = inspectOniFile(file);
  EXPECT_TRUE(summary.finished);
  EXPECT_EQ(summary.bytes, 2 * records.size());
  EXPECT_EQ(summary.streams.at(0).data_records, 3u);
}

TEST(OniContainer, DescribeGivesOneLinePerStreamWithSizeFramesAndCodec) {
  TempDir dir;
  const auto file = dir / "scan.oni";
  writeBytes(file, recording(3, true));
  EXPECT_EQ(describe(inspectOniFile(file)),
            "depth 320x240, 3 frames, 16z with tables (lossless)\n"
            "color 640x480, 3 frames, uncompressed\n");
  EXPECT_EQ(oniCodecName(0x4745504A), "JPEG (lossy)");  // 'J' 'P' 'E' 'G', first in the low byte
}

TEST(OniContainer, EveryTruncationIsReportedAndNeverCrashes) {
  TempDir dir;
  const auto file = dir / "cut.oni";
  const std::string whole = recording(3, true);
  for (std::size_t size = 0; size < whole.size(); ++size) {
    SCOPED_TRACE("cut at byte " + std::to_string(size));
    writeBytes(file, whole.substr(0, size));
    expectInputError([&] { inspectOniFile(file); }, file,
                     size < 4 ? "not an OpenNI recording" : "truncated");
    OniFileSummary tolerated;
    ASSERT_NO_THROW(tolerated = inspectOniFile(file, true));
    EXPECT_FALSE(tolerated.finished);
    EXPECT_NE(tolerated.problem, "");
    EXPECT_EQ(tolerated.bytes, size);
    for (const OniStreamSummary& s : tolerated.streams) EXPECT_LE(s.data_records, 3u);
  }
}

TEST(OniContainer, RecordingThatWasNeverClosedIsUnfinished) {
  TempDir dir;
  const auto file = dir / "live.oni";
  writeBytes(file, recording(5, false));
  expectInputError([&] { inspectOniFile(file); }, file,
                   "was not finished: the recording stopped without a clean close (no end record");
  const OniFileSummary summary = inspectOniFile(file, true);
  EXPECT_FALSE(summary.finished);
  EXPECT_NE(summary.problem.find("was not finished"), std::string::npos) << summary.problem;
  ASSERT_EQ(summary.streams.size(), 2u);
  for (const OniStreamSummary& s : summary.streams) {
    EXPECT_EQ(s.declared_frames, std::nullopt);
    EXPECT_EQ(s.data_records, 5u);
    EXPECT_TRUE(s.data_begun);
    EXPECT_FALSE(s.removed);
    EXPECT_FALSE(s.has_seek_table);
  }
}

TEST(OniContainer, NotAnOniFileOrBadRecordMagicIsRejected) {
  TempDir dir;
  const auto zip = dir / "scan.zip";
  writeBytes(zip, "PK\x03\x04" + std::string(100, 'x'));
  expectInputError([&] { inspectOniFile(zip); }, zip, "not an OpenNI recording (no NI10 header)");
  expectInputError([&] { inspectOniFile(zip, true); }, zip, "not an OpenNI recording");

  std::string bytes = recording(3, true);
  bytes[24] = 'X';  // the first record's magic
  const auto file = dir / "bad.oni";
  writeBytes(file, bytes);
  expectInputError([&] { inspectOniFile(file); }, file, "corrupt at byte 24: bad record magic");
  expectInputError([&] { inspectOniFile(file, true); }, file, "bad record magic");
}

TEST(OniContainer, UnknownRecordTypeIsCorrupt) {
  TempDir dir;
  std::string bytes = recording(3, true);
  bytes.replace(28, 4, le32(0x42));  // the first record's type
  const auto file = dir / "bad.oni";
  writeBytes(file, bytes);
  expectInputError([&] { inspectOniFile(file, true); }, file, "unknown record type 66");
}

TEST(OniContainer, DirectoryAndMissingFileAreInputErrors) {
  TempDir dir;
  expectInputError([&] { inspectOniFile(dir.path()); }, dir.path(), "is a directory");
  expectInputError([&] { inspectOniFile(dir / "none.oni", true); }, dir / "none.oni",
                   "does not exist");
}

TEST(OniContainer, HugeSizeFieldIsReportedNotAllocated) {
  TempDir dir;
  const auto file = dir / "huge.oni";
  OniBuilder b;
  b.nodeAdded(1, "Depth", 2, "16zT");
  const std::size_t frame = b.record(kNewData, 1, le64(0) + le32(1), std::string(16, 'd'));
  std::string bytes = b.bytes();
  bytes.replace(frame + 16, 4, le32(0xFFFFFFFF));  // payload size
  writeBytes(file, bytes);
  expectInputError([&] { inspectOniFile(file, true); }, file,
                   "frame 1 of the depth stream claims 4.0 GB, more than OpenNI's player accepts");

  bytes = b.bytes();
  bytes.replace(frame + 12, 4, le32(0xFFFFFFF0));  // fields size
  writeBytes(file, bytes);
  expectInputError([&] { inspectOniFile(file, true); }, file, "claims 4.0 GB");

  // A size an OpenNI record can have, running past the end of the file: a cut-off file.
  bytes = b.bytes();
  bytes.replace(frame + 16, 4, le32(1'000'000));
  writeBytes(file, bytes);
  expectInputError(
      [&] { inspectOniFile(file); }, file,
      "truncated at byte " + std::to_string(bytes.size()) + " inside frame 1 of the depth stream");
}

TEST(OniContainer, DeclaredFrameCountDisagreeingWithFramesIsReported) {
  TempDir dir;
  const auto file = dir / "short.oni";
  // A depth stream whose NodeAdded record and seek table say 50 frames, with 48 in the body.
  OniBuilder b;
  const std::size_t added = b.nodeAdded(1, "Depth", 2, "16zT");
  b.record(kNodeStateReady, 1);
  b.record(kNodeDataBegin, 1, le32(0xFFFFFFFF) + le64(~0ull));
  std::vector<std::uint64_t> positions;
  for (int f = 1; f <= 48; ++f) {
    positions.push_back(
        b.record(kNewData, 1, le64(f) + le32(f), "x", positions.empty() ? 0 : positions.back()));
  }
  b.record(kNodeRemoved, 1, "", "", added);
  positions.resize(50, positions.back());
  const std::size_t table = b.seekTable(1, positions);
  b.rewriteNodeAdded(added, 1, "Depth", 2, "16zT", 50, table);
  b.record(kEnd, 0);
  b.setMaxNodeId(1);
  writeBytes(file, b.bytes());
  expectInputError([&] { inspectOniFile(file); }, file, "declares 50 depth frames but holds 48");
  const OniFileSummary summary = inspectOniFile(file, true);
  EXPECT_FALSE(summary.finished);
  EXPECT_EQ(summary.problem, "declares 50 depth frames but holds 48");
  EXPECT_EQ(summary.streams.at(0).data_records, 48u);
}

TEST(OniContainer, SeekTableSizedForAnotherFrameCountIsCorrupt) {
  TempDir dir;
  const auto file = dir / "table.oni";
  writeBytes(file, recording(3, true, /*declared_depth_frames=*/5));
  expectInputError([&] { inspectOniFile(file, true); }, file,
                   "the seek table of the depth stream holds 4 entries, but the stream declares 5 "
                   "frames");
}

TEST(OniContainer, FrameForStreamNeverAddedIsCorrupt) {
  TempDir dir;
  const auto file = dir / "orphan.oni";
  OniBuilder b;
  b.nodeAdded(1, "Depth", 2, "16zT");
  const std::size_t frame = b.record(kNewData, 7, le64(0) + le32(1), "x");
  writeBytes(file, b.bytes());
  expectInputError([&] { inspectOniFile(file, true); }, file,
                   "corrupt at byte " + std::to_string(frame) +
                       ": a frame record for stream 7, which no record added");
}

}  // namespace
}  // namespace objscan::capture
