#include "objscan/discovery/catalog.h"

#include <sqlite3.h>

#include <algorithm>
#include <array>
#include <bit>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string_view>
#include <tuple>

#include <fcntl.h>  // AT_FDCWD
#include <unistd.h>

#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"

namespace objscan::discovery {
namespace {

namespace fs = std::filesystem;

// The schema, version 2 (PRAGMA user_version). Vertex lists live in their own table so that the
// segments table stays a few dozen bytes a row: SQLite keeps up to a page of a row's BLOB inline,
// and recurrenceEntries() scans every segment. AUTOINCREMENT: ids are never reused, so an id kept
// elsewhere (a label file, a viewer's page) cannot come to name another segment after a scene is
// replaced. The CHECKs are the catalog's validation: a violation rolls the whole write back.
// People's labels (kLabelTables) are rows of their own, with who and when; label_events is their
// history, only ever appended to. Both go with their segments when a scene is replaced.
constexpr const char* kLabelTables = R"sql(
CREATE TABLE segment_labels (
  segment_id INTEGER PRIMARY KEY REFERENCES segments(id) ON DELETE CASCADE,
  label INTEGER NOT NULL CHECK (label IN (0, 1, 2)),
  labelled_by TEXT NOT NULL,
  labelled_at TEXT NOT NULL);
CREATE TABLE label_events (
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  segment_id INTEGER NOT NULL REFERENCES segments(id) ON DELETE CASCADE,
  scene_id INTEGER NOT NULL REFERENCES scenes(id) ON DELETE CASCADE,
  label INTEGER CHECK (label IN (0, 1, 2)),
  previous INTEGER CHECK (previous IN (0, 1, 2)),
  labelled_by TEXT NOT NULL,
  labelled_at TEXT NOT NULL,
  undoes INTEGER,
  previous_by TEXT,
  previous_at TEXT);
CREATE INDEX label_events_by_scene ON label_events(scene_id);
CREATE INDEX label_events_by_segment ON label_events(segment_id);
)sql";
constexpr const char* kSchema = R"sql(
CREATE TABLE scenes (
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  name TEXT NOT NULL,
  content_hash TEXT NOT NULL,
  settings TEXT NOT NULL,
  vertex_count INTEGER NOT NULL CHECK (vertex_count >= 0),
  added TEXT NOT NULL DEFAULT (strftime('%Y-%m-%dT%H:%M:%SZ', 'now')),
  UNIQUE (content_hash, settings));
CREATE TABLE segments (
  id INTEGER PRIMARY KEY AUTOINCREMENT,
  scene_id INTEGER NOT NULL REFERENCES scenes(id) ON DELETE CASCADE,
  scale REAL CHECK (scale >= 0),
  centroid_x REAL, centroid_y REAL, centroid_z REAL,
  axes BLOB NOT NULL CHECK (length(axes) = 36),
  eigenvalue_0 REAL, eigenvalue_1 REAL, eigenvalue_2 REAL,
  extent_0 REAL CHECK (extent_0 >= 0),
  extent_1 REAL CHECK (extent_1 >= 0),
  extent_2 REAL CHECK (extent_2 >= 0),
  compactness REAL, symmetry REAL, smoothness REAL, local_convexity REAL, global_convexity REAL);
CREATE INDEX segments_by_scene ON segments(scene_id);
CREATE TABLE segment_vertices (
  segment_id INTEGER PRIMARY KEY REFERENCES segments(id) ON DELETE CASCADE,
  vertices BLOB NOT NULL);
)sql";
constexpr std::array<const char*, 3> kTables = {"scenes", "segments", "segment_vertices"};

// Version 1 to 2: version 1 kept a 0/1 label in segments.label, without who or when. They move
// to segment_labels, each with an event, by "objscan (schema 1)" at the time of the upgrade.
constexpr const char* kUpgradeFrom1 = R"sql(
INSERT INTO segment_labels (segment_id, label, labelled_by, labelled_at)
  SELECT id, label, 'objscan (schema 1)', strftime('%Y-%m-%dT%H:%M:%fZ', 'now')
  FROM segments WHERE label IS NOT NULL ORDER BY id;
INSERT INTO label_events (segment_id, scene_id, label, previous, labelled_by, labelled_at)
  SELECT l.segment_id, s.scene_id, l.label, NULL, l.labelled_by, l.labelled_at
  FROM segment_labels l JOIN segments s ON s.id = l.segment_id ORDER BY l.segment_id;
ALTER TABLE segments DROP COLUMN label;
)sql";

// Column lists shared by the statements that read segments (their order is readSegment()'s),
// and the join that brings each segment's label.
constexpr const char* kSegmentColumns =
    "s.id, s.scene_id, s.scale, s.centroid_x, s.centroid_y, s.centroid_z, s.axes, "
    "s.eigenvalue_0, s.eigenvalue_1, s.eigenvalue_2, s.extent_0, s.extent_1, s.extent_2, "
    "s.compactness, s.symmetry, s.smoothness, s.local_convexity, s.global_convexity, "
    "l.label, l.labelled_by, l.labelled_at";
constexpr const char* kSegmentsWithLabels =
    " FROM segments s LEFT JOIN segment_labels l ON l.segment_id = s.id";
// The columns of a label event (readEvent()'s order).
constexpr const char* kEventColumns =
    "id, segment_id, scene_id, label, previous, labelled_by, labelled_at, undoes, previous_by, "
    "previous_at";

/// Now, in ISO 8601 UTC with milliseconds: "2026-11-25T14:51:46.123Z".
std::string nowUtc() {
  const auto ms = std::chrono::duration_cast<std::chrono::milliseconds>(
                      std::chrono::system_clock::now().time_since_epoch())
                      .count();
  const auto seconds = static_cast<std::time_t>(ms / 1000);
  std::tm utc{};
  gmtime_r(&seconds, &utc);
  char date[24];
  std::strftime(date, sizeof date, "%Y-%m-%dT%H:%M:%S", &utc);
  char out[32];
  std::snprintf(out, sizeof out, "%s.%03dZ", date, static_cast<int>(ms % 1000));
  return out;
}

bool isLabel(int label) { return label >= 0 && label <= 2; }

void requireLabel(int label, std::int64_t segment_id) {
  if (!isLabel(label)) {
    throw std::invalid_argument("a label is 1 (object), 0 (not an object) or 2 (unsure), not " +
                                std::to_string(label) + " (segment " + std::to_string(segment_id) +
                                ")");
  }
}

void requireLabeller(const std::string& by) {
  if (const std::string problem = labellerNameProblem(by); !problem.empty()) {
    throw std::invalid_argument("a label needs the name of who set it: " + problem);
  }
}

enum class Access { kRead, kWrite };

/// The open database and its file name, for error messages.
struct Connection {
  sqlite3* db = nullptr;
  fs::path path;

  /// Throws the exception that fits SQLite's result code `rc` from `doing`.
  [[noreturn]] void fail(int rc, const std::string& doing, Access access) const {
    std::string message = db != nullptr ? sqlite3_errmsg(db) : sqlite3_errstr(rc);
    // An I/O error says what the system said ("disk I/O error" alone does not say "disk full").
    if (const int e = db != nullptr ? sqlite3_system_errno(db) : 0;
        e != 0 && (rc & 0xff) == SQLITE_IOERR) {  // the only code SQLite keeps errno for
      message.append(": ").append(std::strerror(e));
    }
    switch (rc & 0xff) {
      case SQLITE_NOTADB:
      case SQLITE_CORRUPT:
        throw InputError(path, "not an SQLite database, or a damaged one (" + message + ")");
      case SQLITE_CONSTRAINT:
        throw std::invalid_argument(path.string() + ": " + doing + ": refused (" + message + ")");
      case SQLITE_BUSY:
      case SQLITE_LOCKED:
        throw OutputError(
            path, doing + ": the catalog stayed locked by another process (" + message + ")");
      default:
        if (access == Access::kWrite) throw OutputError(path, doing + " failed (" + message + ")");
        throw InputError(path, doing + " failed (" + message + ")");
    }
  }
};

/// A prepared statement, finalized on destruction. Bind parameters are numbered from 1, columns
/// from 0, as in SQLite.
class Statement {
 public:
  /// With `checks_schema`, a query that names a table or column the file lacks means the file is
  /// not a catalog of this schema.
  Statement(const Connection& connection, const std::string& sql, Access access,
            bool checks_schema = false)
      : connection_(&connection), access_(access) {
    const int rc = sqlite3_prepare_v3(connection.db, sql.c_str(), static_cast<int>(sql.size()),
                                      SQLITE_PREPARE_PERSISTENT, &statement_, nullptr);
    if (rc == SQLITE_OK) return;
    sqlite3_finalize(statement_);  // the destructor does not run when the constructor throws
    if (checks_schema && (rc & 0xff) == SQLITE_ERROR) {
      throw InputError(connection.path, "not an objscan catalog of schema version 2 (" +
                                            std::string(sqlite3_errmsg(connection.db)) + ")");
    }
    connection.fail(rc, "preparing a query", access);
  }
  ~Statement() { sqlite3_finalize(statement_); }
  Statement(const Statement&) = delete;
  Statement& operator=(const Statement&) = delete;

  /// Starts a use of the statement: clears the last one's bindings and state.
  Statement& start() {
    sqlite3_reset(statement_);
    sqlite3_clear_bindings(statement_);
    return *this;
  }
  /// Ends a use (releases the read lock a SELECT holds until reset).
  void finish() { sqlite3_reset(statement_); }

  Statement& bind(int i, std::int64_t v) { return check(sqlite3_bind_int64(statement_, i, v)); }
  /// NaN is stored as NULL (SQLite's own choice) and reads back as NaN.
  Statement& bind(int i, double v) { return check(sqlite3_bind_double(statement_, i, v)); }
  Statement& bind(int i, const std::string& v) {
    return check(
        sqlite3_bind_text(statement_, i, v.data(), static_cast<int>(v.size()), SQLITE_TRANSIENT));
  }
  Statement& bindBlob(int i, const std::string& bytes) {
    return check(sqlite3_bind_blob(statement_, i, bytes.data(), static_cast<int>(bytes.size()),
                                   SQLITE_TRANSIENT));
  }
  Statement& bindNull(int i) { return check(sqlite3_bind_null(statement_, i)); }

  /// Runs to the next row: true for a row, false when done.
  bool step(const std::string& doing) {
    const int rc = sqlite3_step(statement_);
    if (rc == SQLITE_ROW) return true;
    if (rc == SQLITE_DONE) return false;
    sqlite3_reset(statement_);
    connection_->fail(rc, doing, access_);
  }

  bool isNull(int c) const { return sqlite3_column_type(statement_, c) == SQLITE_NULL; }
  /// An INTEGER column. SQLite would convert text or a real silently (text to 0): anything else
  /// is a damaged catalog.
  std::int64_t integer(int c) const {
    if (sqlite3_column_type(statement_, c) != SQLITE_INTEGER) notANumber(c, "a whole number");
    return sqlite3_column_int64(statement_, c);
  }
  /// A REAL column; NULL (a stored NaN) reads as NaN; text or a blob is a damaged catalog (SQLite
  /// would read "abc" as 0 and change every score normalised with it).
  double real(int c) const {
    const int type = sqlite3_column_type(statement_, c);
    if (type == SQLITE_NULL) return std::numeric_limits<double>::quiet_NaN();
    if (type != SQLITE_FLOAT && type != SQLITE_INTEGER) notANumber(c, "a number");
    return sqlite3_column_double(statement_, c);
  }
  std::string text(int c) const {
    const auto* p = reinterpret_cast<const char*>(sqlite3_column_text(statement_, c));
    return p != nullptr
               ? std::string(p, static_cast<std::size_t>(sqlite3_column_bytes(statement_, c)))
               : std::string();
  }
  std::string_view blob(int c) const {
    const void* p = sqlite3_column_blob(statement_, c);
    const int n = sqlite3_column_bytes(statement_, c);
    return p != nullptr ? std::string_view(static_cast<const char*>(p), static_cast<std::size_t>(n))
                        : std::string_view();
  }

 private:
  [[noreturn]] void notANumber(int c, const char* wanted) const {
    const char* name = sqlite3_column_name(statement_, c);
    const int type = sqlite3_column_type(statement_, c);
    throw InputError(connection_->path,
                     std::string("damaged: column '") + (name != nullptr ? name : "?") +
                         "' holds " +
                         (type == SQLITE_TEXT   ? "text"
                          : type == SQLITE_BLOB ? "a blob"
                          : type == SQLITE_NULL ? "nothing"
                                                : "a fraction") +
                         " where " + wanted +
                         " belongs (restore the catalog or start a new one with --catalog NEW)");
  }

  Statement& check(int rc) {
    if (rc != SQLITE_OK) connection_->fail(rc, "binding a query parameter", access_);
    return *this;
  }

  const Connection* connection_;
  Access access_;
  sqlite3_stmt* statement_ = nullptr;
};

/// Runs SQL without results (schema, pragmas).
void execute(const Connection& connection, const char* sql, const std::string& doing,
             Access access) {
  const int rc = sqlite3_exec(connection.db, sql, nullptr, nullptr, nullptr);
  if (rc != SQLITE_OK) connection.fail(rc, doing, access);
}

/// BEGIN IMMEDIATE on construction (the write lock is taken up front, so the transaction cannot
/// fail half-way for want of it), ROLLBACK on destruction unless committed.
class Transaction {
 public:
  explicit Transaction(const Connection& connection) : connection_(connection) {
    execute(connection_, "BEGIN IMMEDIATE", "starting a transaction", Access::kWrite);
  }
  ~Transaction() {
    if (!committed_) sqlite3_exec(connection_.db, "ROLLBACK", nullptr, nullptr, nullptr);
  }
  Transaction(const Transaction&) = delete;
  Transaction& operator=(const Transaction&) = delete;
  void commit() {
    execute(connection_, "COMMIT", "committing", Access::kWrite);
    committed_ = true;
  }

 private:
  const Connection& connection_;
  bool committed_ = false;
};

// Little-endian encodings of the BLOB columns, whatever the host's byte order.
void appendLittleEndian(std::uint32_t v, std::string* out) {
  for (int b = 0; b < 4; ++b) out->push_back(static_cast<char>((v >> (8 * b)) & 0xffu));
}
std::uint32_t readLittleEndian(std::string_view bytes, std::size_t i) {
  std::uint32_t v = 0;
  for (std::size_t b = 0; b < 4; ++b) {
    v |= static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[4 * i + b])) << (8 * b);
  }
  return v;
}

std::string encodeAxes(const Eigen::Matrix3f& axes) {
  std::string out;
  out.reserve(36);
  for (int i = 0; i < 9; ++i) appendLittleEndian(std::bit_cast<std::uint32_t>(axes(i)), &out);
  return out;  // column-major, as Eigen stores it
}

std::string encodeVertices(const std::vector<std::int32_t>& vertices) {
  std::string out;
  out.reserve(4 * vertices.size());
  for (std::int32_t v : vertices) appendLittleEndian(static_cast<std::uint32_t>(v), &out);
  return out;
}

/// Characters a name may hold that show nothing: spaces of every width, joiners, fillers.
bool invisible(std::uint32_t c) {
  return c == 0x20 || c == 0xa0 || c == 0xad || c == 0x34f || c == 0x115f || c == 0x1160 ||
         c == 0x1680 || c == 0x17b4 || c == 0x17b5 || c == 0x180e || (c >= 0x2000 && c <= 0x200d) ||
         c == 0x202f || c == 0x205f || (c >= 0x2060 && c <= 0x2064) || c == 0x3000 || c == 0x3164 ||
         c == 0xffa0 || (c >= 0xfe00 && c <= 0xfe0f);
}

/// Characters a name must not hold: controls (C0, DEL, C1; ESC starts terminal escapes), line and
/// paragraph separators, text-direction marks, embeddings, overrides and isolates, the byte order
/// mark, interlinear annotation and tag characters.
const char* refusedKind(std::uint32_t c) {
  if (c < 0x20 || (c >= 0x7f && c <= 0x9f)) return "a control character";
  if (c == 0x2028 || c == 0x2029) return "a line or paragraph separator";
  if (c == 0x061c || c == 0x200e || c == 0x200f || (c >= 0x202a && c <= 0x202e) ||
      (c >= 0x2066 && c <= 0x2069)) {
    return "a text-direction character";
  }
  if (c == 0xfeff) return "a byte order mark";
  if ((c >= 0xfff9 && c <= 0xfffb) || (c >= 0xe0000 && c <= 0xe007f)) {
    return "an invisible format character";
  }
  return nullptr;
}

}  // namespace

std::string labellerNameProblem(std::string_view name) {
  constexpr std::size_t kMaxCharacters = 64;
  const std::string rule =
      " (a name is 1 to 64 characters, at least one visible, without control, line-separator, "
      "text-direction or byte-order-mark characters)";
  if (name.empty()) return "the name is empty" + rule;
  std::size_t characters = 0;
  bool visible = false;
  for (std::size_t i = 0; i < name.size();) {
    // UTF-8, strictly: no overlong form, no surrogate, nothing past U+10FFFF.
    const auto byte = [&](std::size_t k) { return static_cast<unsigned char>(name[k]); };
    const unsigned char lead = byte(i);
    const std::size_t length = lead < 0x80   ? 1
                               : lead < 0xc2 ? 0
                               : lead < 0xe0 ? 2
                               : lead < 0xf0 ? 3
                               : lead < 0xf5 ? 4
                                             : 0;
    std::uint32_t c = length == 1 ? lead : lead & (0x7fu >> length);
    bool valid = length > 0 && i + length <= name.size();
    for (std::size_t k = 1; valid && k < length; ++k) {
      valid = (byte(i + k) & 0xc0) == 0x80;
      c = (c << 6) | (byte(i + k) & 0x3fu);
    }
    valid = valid && !(length == 3 && (c < 0x800 || (c >= 0xd800 && c <= 0xdfff))) &&
            !(length == 4 && (c < 0x10000 || c > 0x10ffff));
    ++characters;
    char at[96];
    if (!valid) {
      std::snprintf(at, sizeof at, "byte %zu is not UTF-8", i + 1);
      return at + rule;
    }
    if (const char* kind = refusedKind(c)) {
      std::snprintf(at, sizeof at, "character %zu is U+%04X, %s", characters,
                    static_cast<unsigned>(c), kind);
      return at + rule;
    }
    visible |= !invisible(c);
    i += length;
  }
  if (characters > kMaxCharacters) {
    return "the name has " + std::to_string(characters) + " characters" + rule;
  }
  if (!visible) return "the name shows nothing (only spaces or invisible characters)" + rule;
  return {};
}

struct Catalog::Impl {
  explicit Impl(const fs::path& file) {
    connection.path = file;
    std::error_code ec;
    fs::file_status status = fs::status(file, ec);
    if (status.type() == fs::file_type::not_found) {
      createCatalogFile(file);
      status = fs::status(file, ec);
    }
    // What is not a catalog is refused before SQLite opens it: SQLite would make /dev/null's
    // journal /dev/null-journal, and turn an empty file into a catalog.
    if (fs::is_directory(status)) throw InputError(file, "is a folder, not a catalog file");
    if (ec && status.type() != fs::file_type::not_found) {
      throw InputError(file, "cannot be looked at: " + ec.message());
    }
    if (!fs::is_regular_file(status)) {
      throw InputError(file,
                       "is not a regular file (a device, a FIFO or a socket), so not a catalog");
    }
    if (fs::file_size(file, ec) == 0 && !ec) {
      throw InputError(file,
                       "is empty (0 bytes), not a catalog: objscan leaves it as it is (remove "
                       "it, and objscan makes a new catalog there)");
    }
    // Not SQLITE_OPEN_CREATE: should the file be gone meanwhile, that is an error, not a new
    // catalog made by SQLite in place.
    const int rc = sqlite3_open_v2(file.c_str(), &connection.db, SQLITE_OPEN_READWRITE, nullptr);
    if (rc != SQLITE_OK) {
      const std::string message =
          connection.db != nullptr ? sqlite3_errmsg(connection.db) : sqlite3_errstr(rc);
      sqlite3_close(connection.db);  // a handle comes back even on failure (or null: a no-op)
      throw InputError(file, "cannot be opened as a catalog (" + message + ")");
    }
    try {
      open();
    } catch (...) {
      statements.clear();
      sqlite3_close(connection.db);
      throw;
    }
  }

  /// Makes a new, empty catalog at `file`: its tables are created in a file of a temporary name
  /// beside it, which is then linked to `file` (link, unlike rename, never replaces: when another
  /// process made the catalog meanwhile, its file stays and is opened).
  static void createCatalogFile(const fs::path& file) {
    const fs::path folder = file.parent_path();
    std::error_code ec;
    if (!folder.empty() && !fs::is_directory(folder, ec)) {
      throw OutputError(
          file, "cannot create the catalog: the folder " + folder.string() + " does not exist");
    }
    const fs::path temporary = temporarySibling(file);
    Connection made;
    made.path = file;
    const auto fail = [&](const std::string& message) {
      sqlite3_close(made.db);
      made.db = nullptr;
      ::unlink(temporary.c_str());
      throw OutputError(file, "cannot create the catalog (" + message + ")");
    };
    const int rc = sqlite3_open_v2(temporary.c_str(), &made.db,
                                   SQLITE_OPEN_READWRITE | SQLITE_OPEN_CREATE, nullptr);
    if (rc != SQLITE_OK) fail(made.db != nullptr ? sqlite3_errmsg(made.db) : sqlite3_errstr(rc));
    const std::string schema =
        std::string("BEGIN; ") + kSchema + kLabelTables + "PRAGMA user_version = 2; COMMIT;";
    if (sqlite3_exec(made.db, schema.c_str(), nullptr, nullptr, nullptr) != SQLITE_OK) {
      fail(sqlite3_errmsg(made.db));
    }
    if (sqlite3_close(made.db) != SQLITE_OK) fail("closing the new file failed");
    made.db = nullptr;
    int placed = ::link(temporary.c_str(), file.c_str());
    int place_errno = errno;
    if (placed != 0 && (place_errno == EPERM || place_errno == EOPNOTSUPP ||
                        place_errno == ENOTSUP || place_errno == ENOSYS)) {
      // A file system without hard links (vfat, exFAT, some network mounts): a rename that
      // never replaces does the same, where the file system has one.
      placed = ::renameat2(AT_FDCWD, temporary.c_str(), AT_FDCWD, file.c_str(), RENAME_NOREPLACE);
      place_errno = errno;
      if (placed != 0 && (place_errno == EINVAL || place_errno == ENOSYS)) {
        // Neither: a plain rename when nothing is there yet. Only two runs making the same
        // catalog in the same instant on such a file system can then meet: the later one's new
        // catalog replaces the earlier's, and what the earlier adds to it is lost.
        std::error_code exists_ec;
        if (fs::exists(fs::symlink_status(file, exists_ec))) {
          place_errno = EEXIST;
        } else {
          placed = ::rename(temporary.c_str(), file.c_str());
          place_errno = errno;
        }
      }
    }
    ::unlink(temporary.c_str());  // after a rename, nothing is left of that name
    if (placed != 0 && place_errno != EEXIST) fail(std::strerror(place_errno));
  }

  ~Impl() {
    statements.clear();  // every statement finalized before the connection closes
    sqlite3_close(connection.db);
  }
  Impl(const Impl&) = delete;
  Impl& operator=(const Impl&) = delete;

  void open() {
    sqlite3_extended_result_codes(connection.db, 1);
    sqlite3_busy_timeout(connection.db, 10'000);
    execute(connection, "PRAGMA foreign_keys = ON", "enabling foreign keys", Access::kRead);
    // Reading the version and the table names reads the file's header and schema page: this is
    // where a file that is not an SQLite database, or whose schema is damaged, is found out.
    auto [version, tables] = readSchema();
    // Damage further in is found before anything is written (an upgrade, a scene) or read: SQLite's
    // quick_check reads every page (O(N), about 0.1 s per 100 MB when cached).
    requireUndamaged();
    if (version > kSchemaVersion) {
      throw InputError(connection.path, "catalog schema version " + std::to_string(version) +
                                            " is newer than this objscan's (" +
                                            std::to_string(kSchemaVersion) +
                                            "); use a newer objscan");
    }
    for (const char* table : kTables) {
      if (std::find(tables.begin(), tables.end(), table) == tables.end()) {
        throw InputError(connection.path, std::string("an SQLite database but not an objscan "
                                                      "catalog (it has no '") +
                                              table + "' table)");
      }
    }
    if (version == 1) version = upgradeFrom1();
    if (version != kSchemaVersion) {
      throw InputError(connection.path, "not an objscan catalog (schema version " +
                                            std::to_string(version) + ", expected " +
                                            std::to_string(kSchemaVersion) + ")");
    }
    prepareStatements();
  }

  /// Upgrades a version-1 catalog to version 2 in one transaction; returns the version now (2,
  /// also when another process upgraded it meanwhile). A file that cannot be written is an
  /// OutputError; one that is not what version 1 was, an InputError; the file is then unchanged.
  int upgradeFrom1() {
    const fs::path& file = connection.path;
    const auto run = [&](const char* sql) {
      const int rc = sqlite3_exec(connection.db, sql, nullptr, nullptr, nullptr);
      if (rc == SQLITE_OK) return;
      const std::string message = sqlite3_errmsg(connection.db);
      switch (rc & 0xff) {
        case SQLITE_ERROR:
          throw InputError(file, "not an objscan catalog of schema version 1 (" + message + ")");
        case SQLITE_CONSTRAINT:
          throw InputError(file,
                           "damaged: its schema-version-1 labels cannot be upgraded to "
                           "version 2 (" +
                               message + ")");
        case SQLITE_NOTADB:
        case SQLITE_CORRUPT:
          connection.fail(rc, "upgrading", Access::kWrite);
        default:
          throw OutputError(file,
                            "a catalog of schema version 1, which this objscan upgrades to "
                            "version 2 when it opens it, and the upgrade failed (" +
                                message +
                                "); the file is unchanged: make it (and its folder) writable, "
                                "or let the process that holds it finish, and run again");
      }
    };
    run("BEGIN IMMEDIATE");
    try {
      if (readSchema().first == 1) {  // else another process upgraded it meanwhile
        run(kLabelTables);
        run(kUpgradeFrom1);
        run("PRAGMA user_version = 2");
      }
      run("COMMIT");
    } catch (...) {
      sqlite3_exec(connection.db, "ROLLBACK", nullptr, nullptr, nullptr);
      throw;
    }
    return readSchema().first;
  }

  /// Throws InputError when PRAGMA quick_check finds the file damaged (its first finding).
  void requireUndamaged() {
    Statement check(connection, "PRAGMA quick_check(1)", Access::kRead);
    check.start();
    const std::string finding = check.step("checking the file") ? check.text(0) : "no answer";
    check.finish();
    if (finding != "ok") {
      throw InputError(connection.path,
                       "damaged: SQLite's quick_check finds \"" + finding +
                           "\"; it is left as it is (restore a copy, or start a new catalog "
                           "with --catalog NEW)");
    }
  }

  std::pair<int, std::vector<std::string>> readSchema() {
    Statement version(connection, "PRAGMA user_version", Access::kRead);
    version.start();
    const int v =
        version.step("reading the schema version") ? static_cast<int>(version.integer(0)) : 0;
    version.finish();
    Statement names(connection,
                    "SELECT name FROM sqlite_schema WHERE type = 'table' AND name NOT LIKE "
                    "'sqlite\\_%' ESCAPE '\\'",
                    Access::kRead);
    names.start();
    std::vector<std::string> tables;
    while (names.step("reading the schema")) tables.push_back(names.text(0));
    names.finish();
    return {v, tables};
  }

  /// Preparing every statement up front also checks that the tables have the columns they use.
  void prepareStatements() {
    const auto prepare = [&](const std::string& sql, Access access) {
      statements.push_back(std::make_unique<Statement>(connection, sql, access, true));
      return statements.back().get();
    };
    find_scene = prepare(
        "SELECT id, name, content_hash, vertex_count, settings FROM scenes "
        "WHERE content_hash = ?1 AND settings = ?2",
        Access::kRead);
    list_scenes =
        prepare("SELECT id, name, content_hash, vertex_count, settings FROM scenes ORDER BY id",
                Access::kRead);
    delete_scene =
        prepare("DELETE FROM scenes WHERE content_hash = ?1 AND settings = ?2", Access::kWrite);
    insert_scene = prepare(
        "INSERT INTO scenes (name, content_hash, settings, vertex_count) VALUES (?1, ?2, ?3, ?4)",
        Access::kWrite);
    insert_segment = prepare(
        "INSERT INTO segments (scene_id, scale, centroid_x, centroid_y, centroid_z, axes, "
        "eigenvalue_0, eigenvalue_1, eigenvalue_2, extent_0, extent_1, extent_2, compactness, "
        "symmetry, smoothness, local_convexity, global_convexity) "
        "VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, ?9, ?10, ?11, ?12, ?13, ?14, ?15, ?16, ?17)",
        Access::kWrite);
    insert_vertices = prepare("INSERT INTO segment_vertices (segment_id, vertices) VALUES (?1, ?2)",
                              Access::kWrite);
    list_segments = prepare(std::string("SELECT ") + kSegmentColumns + ", NULL" +
                                kSegmentsWithLabels + " WHERE s.scene_id = ?1 ORDER BY s.id",
                            Access::kRead);
    list_segments_with_vertices =
        prepare(std::string("SELECT ") + kSegmentColumns + ", v.vertices" + kSegmentsWithLabels +
                    " LEFT JOIN segment_vertices v ON v.segment_id = s.id "
                    "WHERE s.scene_id = ?1 ORDER BY s.id",
                Access::kRead);
    scenes_with_hash = prepare(
        "SELECT id, name, content_hash, vertex_count, settings FROM scenes "
        "WHERE content_hash = ?1 OR substr(content_hash, 1, length(?1) + 4) = ?1 || ' up ' "
        "ORDER BY id",
        Access::kRead);
    segment_label = prepare(
        std::string("SELECT s.scene_id, l.label, l.labelled_by, l.labelled_at") +
            kSegmentsWithLabels + " WHERE s.id = ?1",
        Access::kWrite);
    put_label = prepare(
        "INSERT INTO segment_labels (segment_id, label, labelled_by, labelled_at) "
        "VALUES (?1, ?2, ?3, ?4) ON CONFLICT (segment_id) DO UPDATE SET label = excluded.label, "
        "labelled_by = excluded.labelled_by, labelled_at = excluded.labelled_at",
        Access::kWrite);
    clear_label = prepare("DELETE FROM segment_labels WHERE segment_id = ?1", Access::kWrite);
    insert_event = prepare(
        "INSERT INTO label_events (segment_id, scene_id, label, previous, labelled_by, "
        "labelled_at, undoes, previous_by, previous_at) VALUES (?1, ?2, ?3, ?4, ?5, ?6, ?7, ?8, "
        "?9)",
        Access::kWrite);
    find_event =
        prepare(std::string("SELECT ") + kEventColumns + " FROM label_events WHERE id = ?1",
                Access::kWrite);
    segment_events = prepare(std::string("SELECT ") + kEventColumns +
                                 " FROM label_events WHERE segment_id = ?1 ORDER BY id",
                             Access::kWrite);
    list_events = prepare(std::string("SELECT ") + kEventColumns +
                              " FROM label_events WHERE scene_id = ?1 ORDER BY id",
                          Access::kRead);
    label_counts = prepare(std::string("SELECT count(*), count(l.label), "
                                       "coalesce(sum(l.label = 1), 0), "
                                       "coalesce(sum(l.label = 0), 0), "
                                       "coalesce(sum(l.label = 2), 0)") +
                               kSegmentsWithLabels + " WHERE s.scene_id = ?1",
                           Access::kRead);
    recurrence_entries = prepare(
        "SELECT scene_id, extent_0, extent_1, extent_2, compactness, symmetry, smoothness, "
        "local_convexity, global_convexity, id FROM segments ORDER BY id",
        Access::kRead);
    count_segments = prepare("SELECT count(*) FROM segments", Access::kRead);
  }

  static CatalogScene readScene(const Statement& s) {
    CatalogScene scene;
    scene.id = s.integer(0);
    scene.name = s.text(1);
    scene.content_hash = s.text(2);
    scene.vertex_count = static_cast<std::size_t>(s.integer(3));
    scene.settings = s.text(4);
    return scene;
  }

  CatalogSegment readSegment(const Statement& s) const {
    CatalogSegment segment;
    const auto real = [&](int c) { return static_cast<float>(s.real(c)); };
    segment.id = s.integer(0);
    segment.scene_id = s.integer(1);
    segment.scale = real(2);
    segment.centroid = {real(3), real(4), real(5)};
    const std::string_view axes = s.blob(6);
    if (axes.size() != 36) {
      throw InputError(connection.path, "damaged: segment " + std::to_string(segment.id) +
                                            " has axes of " + std::to_string(axes.size()) +
                                            " bytes, not 36");
    }
    for (int i = 0; i < 9; ++i) {
      segment.axes(i) = std::bit_cast<float>(readLittleEndian(axes, static_cast<std::size_t>(i)));
    }
    segment.eigenvalues = {real(7), real(8), real(9)};
    segment.extents = {real(10), real(11), real(12)};
    if (!(segment.extents.allFinite() && segment.extents.minCoeff() >= 0.0f)) {
      throw InputError(connection.path, "damaged: segment " + std::to_string(segment.id) +
                                            " has a negative or undefined extent");
    }
    segment.measures.compactness = s.real(13);
    segment.measures.symmetry = s.real(14);
    segment.measures.smoothness = s.real(15);
    segment.measures.local_convexity = s.real(16);
    segment.measures.global_convexity = s.real(17);
    if (!s.isNull(18)) {
      segment.label = static_cast<int>(s.integer(18));
      segment.labelled_by = s.text(19);
      segment.labelled_at = s.text(20);
    }
    const std::string_view vertices = s.blob(21);
    if (vertices.size() % 4 != 0) {
      throw InputError(connection.path, "damaged: segment " + std::to_string(segment.id) +
                                            " has a vertex list of " +
                                            std::to_string(vertices.size()) + " bytes");
    }
    segment.vertices.resize(vertices.size() / 4);
    for (std::size_t i = 0; i < segment.vertices.size(); ++i) {
      segment.vertices[i] = static_cast<std::int32_t>(readLittleEndian(vertices, i));
    }
    return segment;
  }

  static std::optional<int> optionalLabel(const Statement& s, int c) {
    if (s.isNull(c)) return std::nullopt;
    return static_cast<int>(s.integer(c));
  }

  static LabelEvent readEvent(const Statement& s) {
    LabelEvent e;
    e.id = s.integer(0);
    e.segment_id = s.integer(1);
    e.scene_id = s.integer(2);
    e.label = optionalLabel(s, 3);
    e.previous = optionalLabel(s, 4);
    e.by = s.text(5);
    e.at = s.text(6);
    if (!s.isNull(7)) e.undoes = s.integer(7);
    if (!s.isNull(8)) e.previous_by = s.text(8);
    if (!s.isNull(9)) e.previous_at = s.text(9);
    return e;
  }

  struct SegmentLabelRow {
    std::int64_t scene_id = 0;
    std::optional<int> label;
    std::string by, at;  ///< empty without a label
  };
  /// The segment's scene and label; nothing for an unknown segment.
  std::optional<SegmentLabelRow> labelOf(std::int64_t segment_id) {
    Statement& s = segment_label->start().bind(1, segment_id);
    std::optional<SegmentLabelRow> found;
    if (s.step("reading a label")) {
      found.emplace(SegmentLabelRow{s.integer(0), optionalLabel(s, 1), {}, {}});
      if (found->label) {
        found->by = s.text(2);
        found->at = s.text(3);
      }
    }
    s.finish();
    return found;
  }

  /// A segment's events, oldest first.
  std::vector<LabelEvent> eventsOf(std::int64_t segment_id) {
    Statement& s = segment_events->start().bind(1, segment_id);
    std::vector<LabelEvent> out;
    try {
      while (s.step("reading label events")) out.push_back(readEvent(s));
    } catch (...) {
      s.finish();
      throw;
    }
    s.finish();
    return out;
  }

  /// Stores one label (or clears it) and its event; inside a transaction the caller holds.
  /// `scene_id`: the scene the segment must be in (nothing: any). The label is kept as made by
  /// `by` at `at`, or, with `undone` (an undo), as the undone event found it: its previous label
  /// with that label's own who and when (the event records the undoer). Throws
  /// std::invalid_argument for an unknown segment or one of another scene.
  LabelEvent applyLabel(std::int64_t segment_id, std::optional<std::int64_t> scene_id,
                        std::optional<int> label, const std::string& by, const std::string& at,
                        const LabelEvent* undone = nullptr) {
    const auto current = labelOf(segment_id);
    if (!current || (scene_id && current->scene_id != *scene_id)) {
      throw std::invalid_argument(
          connection.path.string() + ": segment " + std::to_string(segment_id) + " is not in " +
          (scene_id ? "scene " + std::to_string(*scene_id) : std::string("the catalog")));
    }
    LabelEvent e;
    e.segment_id = segment_id;
    e.scene_id = current->scene_id;
    e.label = label;
    e.previous = current->label;
    e.previous_by = current->by;
    e.previous_at = current->at;
    e.by = by;
    e.at = at;
    if (undone) e.undoes = undone->id;
    if (label) {
      Statement& s = put_label->start()
                         .bind(1, segment_id)
                         .bind(2, static_cast<std::int64_t>(*label))
                         .bind(3, undone && !undone->previous_by.empty() ? undone->previous_by : by)
                         .bind(4, undone && !undone->previous_at.empty() ? undone->previous_at : at);
      s.step("setting a label");
      s.finish();
    } else {
      Statement& s = clear_label->start().bind(1, segment_id);
      s.step("clearing a label");
      s.finish();
    }
    insertEvent(e);
    e.id = sqlite3_last_insert_rowid(connection.db);
    return e;
  }

  void insertEvent(const LabelEvent& e) {
    Statement& s = insert_event->start().bind(1, e.segment_id).bind(2, e.scene_id);
    if (e.label) {
      s.bind(3, static_cast<std::int64_t>(*e.label));
    } else {
      s.bindNull(3);
    }
    if (e.previous) {
      s.bind(4, static_cast<std::int64_t>(*e.previous));
    } else {
      s.bindNull(4);
    }
    s.bind(5, e.by).bind(6, e.at);
    if (e.undoes) {
      s.bind(7, *e.undoes);
    } else {
      s.bindNull(7);
    }
    if (e.previous) {
      s.bind(8, e.previous_by).bind(9, e.previous_at);
    } else {
      s.bindNull(8).bindNull(9);
    }
    s.step("recording a label event");
    s.finish();
  }

  /// The event with this id.
  std::optional<LabelEvent> event(Statement* query, std::int64_t id) {
    Statement& s = query->start().bind(1, id);
    std::optional<LabelEvent> found;
    if (s.step("reading a label event")) found = readEvent(s);
    s.finish();
    return found;
  }

  Connection connection;
  std::vector<std::unique_ptr<Statement>> statements;
  Statement* find_scene = nullptr;
  Statement* list_scenes = nullptr;
  Statement* delete_scene = nullptr;
  Statement* insert_scene = nullptr;
  Statement* insert_segment = nullptr;
  Statement* insert_vertices = nullptr;
  Statement* list_segments = nullptr;
  Statement* list_segments_with_vertices = nullptr;
  Statement* scenes_with_hash = nullptr;
  Statement* segment_label = nullptr;
  Statement* put_label = nullptr;
  Statement* clear_label = nullptr;
  Statement* insert_event = nullptr;
  Statement* find_event = nullptr;
  Statement* segment_events = nullptr;
  Statement* list_events = nullptr;
  Statement* label_counts = nullptr;
  Statement* recurrence_entries = nullptr;
  Statement* count_segments = nullptr;
};

Catalog::Catalog(const fs::path& path) : impl_(std::make_unique<Impl>(path)) {}
Catalog::~Catalog() = default;
Catalog::Catalog(Catalog&&) noexcept = default;
Catalog& Catalog::operator=(Catalog&&) noexcept = default;

std::optional<CatalogScene> Catalog::findScene(const std::string& content_hash,
                                               const std::string& settings) const {
  Statement& s = impl_->find_scene->start().bind(1, content_hash).bind(2, settings);
  std::optional<CatalogScene> found;
  if (s.step("looking up a scene")) found = Impl::readScene(s);
  s.finish();
  return found;
}

std::int64_t Catalog::addScene(const CatalogScene& scene,
                               const std::vector<CatalogSegment>& segments) {
  const Connection& c = impl_->connection;
  if (scene.vertex_count > static_cast<std::size_t>(std::numeric_limits<std::int64_t>::max())) {
    throw std::invalid_argument("a scene's vertex count must fit in 63 bits");
  }
  Transaction transaction(c);
  const std::string now = nowUtc();
  // Each statement is reset right after its step, also when the step throws (step() resets).
  Statement& del = impl_->delete_scene->start().bind(1, scene.content_hash).bind(2, scene.settings);
  del.step("replacing a scene");
  del.finish();
  Statement& ins = impl_->insert_scene->start()
                       .bind(1, scene.name)
                       .bind(2, scene.content_hash)
                       .bind(3, scene.settings)
                       .bind(4, static_cast<std::int64_t>(scene.vertex_count));
  ins.step("adding a scene");
  ins.finish();
  const std::int64_t scene_id = sqlite3_last_insert_rowid(c.db);
  for (const CatalogSegment& g : segments) {
    Statement& s = impl_->insert_segment->start();
    s.bind(1, scene_id).bind(2, static_cast<double>(g.scale));
    for (int d = 0; d < 3; ++d) s.bind(3 + d, static_cast<double>(g.centroid[d]));
    s.bindBlob(6, encodeAxes(g.axes));
    for (int d = 0; d < 3; ++d) s.bind(7 + d, static_cast<double>(g.eigenvalues[d]));
    for (int d = 0; d < 3; ++d) s.bind(10 + d, static_cast<double>(g.extents[d]));
    const std::array<double, 5> m = recurrenceMeasures(g.measures);
    for (int j = 0; j < 5; ++j) s.bind(13 + j, m[static_cast<std::size_t>(j)]);
    s.step("adding a segment");
    s.finish();
    const std::int64_t segment_id = sqlite3_last_insert_rowid(c.db);
    if (!g.vertices.empty()) {
      Statement& v = impl_->insert_vertices->start()
                         .bind(1, segment_id)
                         .bindBlob(2, encodeVertices(g.vertices));
      v.step("adding a segment's vertices");
      v.finish();
    }
    if (g.label) {
      requireLabel(*g.label, segment_id);
      if (!g.labelled_by.empty()) requireLabeller(g.labelled_by);
      impl_->applyLabel(segment_id, scene_id, g.label,
                        g.labelled_by.empty() ? "objscan" : g.labelled_by, now);
    }
  }
  transaction.commit();
  return scene_id;
}

std::vector<CatalogScene> Catalog::scenes() const {
  Statement& s = impl_->list_scenes->start();
  std::vector<CatalogScene> out;
  while (s.step("listing scenes")) out.push_back(Impl::readScene(s));
  s.finish();
  return out;
}

std::vector<CatalogSegment> Catalog::segments(std::int64_t scene_id, bool with_vertices) const {
  Statement& s =
      (with_vertices ? impl_->list_segments_with_vertices : impl_->list_segments)->start();
  s.bind(1, scene_id);
  std::vector<CatalogSegment> out;
  try {
    while (s.step("reading segments")) out.push_back(impl_->readSegment(s));
  } catch (...) {
    s.finish();
    throw;
  }
  s.finish();
  return out;
}

std::vector<CatalogScene> Catalog::scenesWithHash(const std::string& content_hash) const {
  Statement& s = impl_->scenes_with_hash->start().bind(1, content_hash);
  std::vector<CatalogScene> out;
  while (s.step("listing scenes")) out.push_back(Impl::readScene(s));
  s.finish();
  return out;
}

void Catalog::setLabels(std::int64_t scene_id,
                        const std::vector<std::pair<std::int64_t, int>>& segment_labels,
                        const std::string& by) {
  requireLabeller(by);
  for (const auto& [segment_id, label] : segment_labels) requireLabel(label, segment_id);
  Transaction transaction(impl_->connection);
  // The time is taken once the write lock is held, so that events' times follow their ids.
  const std::string now = nowUtc();
  for (const auto& [segment_id, label] : segment_labels) {
    impl_->applyLabel(segment_id, scene_id, label, by, now);
  }
  transaction.commit();
}

LabelEvent Catalog::setLabel(std::int64_t segment_id, std::optional<int> label,
                             const std::string& by) {
  requireLabeller(by);
  if (label) requireLabel(*label, segment_id);
  Transaction transaction(impl_->connection);
  LabelEvent e = impl_->applyLabel(segment_id, std::nullopt, label, by, nowUtc());
  transaction.commit();
  return e;
}

namespace {

std::string labelText(const std::optional<int>& label) {
  if (!label) return "no label";
  switch (*label) {
    case 0:
      return "not an object";
    case 1:
      return "object";
    case 2:
      return "unsure";
    default:
      return "label " + std::to_string(*label);
  }
}

}  // namespace

LabelEvent Catalog::undoLabel(std::int64_t event_id, const std::string& by) {
  requireLabeller(by);
  Transaction transaction(impl_->connection);
  const std::optional<LabelEvent> undone = impl_->event(impl_->find_event, event_id);
  if (!undone) {
    throw std::invalid_argument(impl_->connection.path.string() + ": no label event " +
                                std::to_string(event_id));
  }
  // The event can be undone when nothing after it on the segment is still in effect: each later
  // event was itself undone (label, relabel, undo, undo goes back two steps). An undo of the
  // event itself means it was undone already; anything else, that somebody changed the label
  // since (even back to the same value).
  std::vector<const LabelEvent*> after;  // later events still in effect
  const std::vector<LabelEvent> events = impl_->eventsOf(undone->segment_id);
  const std::string segment = "segment " + std::to_string(undone->segment_id);
  for (const LabelEvent& x : events) {
    if (x.id <= event_id) continue;
    if (x.undoes && !after.empty() && after.back()->id == *x.undoes) {
      after.pop_back();
    } else if (x.undoes == event_id && after.empty()) {
      throw LabelConflict("label event " + std::to_string(event_id) + " of " + segment +
                          " was already undone (by " + x.by + " at " + x.at + ")");
    } else {
      after.push_back(&x);
    }
  }
  if (!after.empty()) {
    const LabelEvent& latest = *after.back();
    throw LabelConflict(segment + "'s label was changed after event " + std::to_string(event_id) +
                        " (to " + labelText(latest.label) + " by " + latest.by + " at " +
                        latest.at + "): it is not undone");
  }
  LabelEvent e = impl_->applyLabel(undone->segment_id, std::nullopt, undone->previous, by,
                                   nowUtc(), &*undone);
  transaction.commit();
  return e;
}

LabelCounts Catalog::labelCounts(std::int64_t scene_id) const {
  Statement& s = impl_->label_counts->start().bind(1, scene_id);
  LabelCounts counts;
  if (s.step("counting labels")) {
    const auto n = [&](int c) { return static_cast<std::size_t>(s.integer(c)); };
    counts = {n(0), n(1), n(2), n(3), n(4)};
  }
  s.finish();
  return counts;
}

std::vector<LabelEvent> Catalog::labelEvents(std::int64_t scene_id) const {
  Statement& s = impl_->list_events->start().bind(1, scene_id);
  std::vector<LabelEvent> out;
  try {
    while (s.step("reading label events")) out.push_back(Impl::readEvent(s));
  } catch (...) {
    s.finish();
    throw;
  }
  s.finish();
  return out;
}

std::vector<RecurrenceEntry> Catalog::recurrenceEntries() const {
  Statement& s = impl_->recurrence_entries->start();
  std::vector<RecurrenceEntry> out;
  while (s.step("reading segments")) {
    RecurrenceEntry& e = out.emplace_back();
    e.scene_id = s.integer(0);
    for (int d = 0; d < 3; ++d) {
      e.extents[d] = static_cast<float>(s.real(1 + d));
      // Recurrence compares log-extents: a negative one would silently switch it off.
      if (!(std::isfinite(e.extents[d]) && e.extents[d] >= 0.0f)) {
        s.finish();
        throw InputError(impl_->connection.path, "damaged: a segment of scene " +
                                                     std::to_string(e.scene_id) +
                                                     " has a negative or undefined extent");
      }
    }
    for (int j = 0; j < 5; ++j) e.measures[static_cast<std::size_t>(j)] = s.real(4 + j);
    e.segment_id = s.integer(9);
  }
  s.finish();
  return out;
}

bool Catalog::writable() const { return sqlite3_db_readonly(impl_->connection.db, "main") == 0; }

std::size_t Catalog::segmentCount() const {
  Statement& s = impl_->count_segments->start();
  const std::size_t n = s.step("counting segments") ? static_cast<std::size_t>(s.integer(0)) : 0;
  s.finish();
  return n;
}

namespace {

// FNV-1a, 64 bits (Fowler, Noll, Vo): one xor and one multiply per byte.
constexpr std::uint64_t kFnvOffset = 0xcbf29ce484222325ull;

std::uint64_t fnv1a(std::uint64_t h, const char* bytes, std::size_t n) {
  for (std::size_t i = 0; i < n; ++i)
    h = (h ^ static_cast<unsigned char>(bytes[i])) * 0x100000001b3ull;
  return h;
}

std::string hex16(std::uint64_t h) {
  static constexpr char kHex[] = "0123456789abcdef";
  std::string out(16, '0');
  for (int i = 15; i >= 0; --i, h >>= 4) out[static_cast<std::size_t>(i)] = kHex[h & 0xfu];
  return out;
}

}  // namespace

std::string contentHash(const fs::path& file) {
  std::error_code ec;
  if (fs::is_directory(file, ec)) throw InputError(file, "is a folder, not a mesh file");
  std::ifstream in(file, std::ios::binary);
  if (!in) throw InputError(file, "cannot be opened: " + std::string(std::strerror(errno)));
  std::uint64_t h = kFnvOffset;
  std::vector<char> buffer(1 << 20);
  while (in) {
    in.read(buffer.data(), static_cast<std::streamsize>(buffer.size()));
    h = fnv1a(h, buffer.data(), static_cast<std::size_t>(in.gcount()));
  }
  if (in.bad()) throw InputError(file, "could not be read to the end");
  return hex16(h);
}

std::string contentHashOfBytes(std::string_view bytes) {
  return hex16(fnv1a(kFnvOffset, bytes.data(), bytes.size()));
}

std::size_t mergeCatalog(Catalog& into, const Catalog& from,
                         const std::function<bool(const CatalogScene&)>& take) {
  std::size_t added = 0;
  for (const CatalogScene& scene : from.scenes()) {
    if (take && !take(scene)) continue;
    if (into.findScene(scene.content_hash, scene.settings)) continue;
    into.addScene(scene, from.segments(scene.id, true));
    ++added;
  }
  return added;
}

}  // namespace objscan::discovery
