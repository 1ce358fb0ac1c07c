#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "objscan/core/triangle_mesh.h"

namespace objscan {

enum class PlyFormat { kAscii, kBinaryLittleEndian, kBinaryBigEndian };

/// "ascii", "binary_little_endian" or "binary_big_endian", as in the PLY header.
const char* toString(PlyFormat format);

/// What a PLY header declares.
struct PlyHeader {
  struct Property {
    std::string name;
    std::string type;        ///< item type as written in the header ("float", "uchar", ...)
    std::string count_type;  ///< list count type; empty for a scalar property
  };
  struct Element {
    std::string name;
    std::size_t count = 0;
    std::vector<Property> properties;
  };
  PlyFormat format = PlyFormat::kAscii;
  std::vector<Element> elements;
  std::vector<std::string> comments;  ///< "comment" and "obj_info" lines, without the keyword
};

/// What reading a PLY file found besides the mesh itself.
struct PlyReadReport {
  PlyHeader header;
  std::size_t file_bytes = 0;
  std::size_t faces = 0;               ///< polygons in the file (before fan triangulation)
  std::size_t degenerate_dropped = 0;  ///< triangles dropped because a vertex repeats
  std::vector<std::string> ignored;    ///< "vertex.s", "material", ... not read into the mesh
  std::size_t trailing_bytes = 0;  ///< after the last element (not whitespace), ignored
  /// ASCII: the last value, when the file ends right after it without a line break.
  std::optional<std::string> unterminated_last_value;
};

/// Reads a PLY mesh (ASCII or binary of either byte order). Vertex properties x, y, z (required),
/// nx, ny, nz, red, green, blue (uchar, or float/double in 0..1), object_id or label (any integer
/// type, into TriangleMesh::labels; a file with both is refused), quality (into
/// TriangleMesh::weights; ignored with a warning when a value is NaN, infinite or negative, as
/// MeshLab's quality may be) and ignore (any integer type, non-zero read as 1, into
/// TriangleMesh::ignore) are read in any order and of any numeric type; other properties and
/// elements are skipped. Faces are the `vertex_indices` (or `vertex_index`) list of any integer
/// count/item type; polygons are fan-triangulated, triangles that repeat a vertex are dropped and
/// counted. A file without faces reads as a point cloud.
///
/// Throws InputError naming the file and the problem for anything that is not a complete, valid
/// PLY mesh: missing/empty/directory, bad magic or header, truncation anywhere (an ASCII file must
/// end with a newline after its last value), counts or list lengths larger than the file can hold,
/// data left over after the last element, unparsable values, face indices out of range, NaN or
/// infinite coordinates/normals, NaN colours.
TriangleMesh readPly(const std::filesystem::path& path, PlyReadReport* report = nullptr);

/// The bytes of the PLY file writePly writes for `mesh` (same layout, same bytes), for a caller
/// that also needs them in memory (a content hash of the file it writes).
/// Throws std::invalid_argument if mesh.validate() fails.
std::string encodePly(const TriangleMesh& mesh, PlyFormat format = PlyFormat::kBinaryLittleEndian);

/// Writes float x y z, [float nx ny nz], [uchar red green blue], [int object_id], [float quality]
/// (the weights), [uchar ignore] per vertex and faces as `list uchar int vertex_indices`, the
/// layout MeshLab, CloudCompare, Open3D and PCL all read. Floats in ASCII are written with the
/// shortest text that reads back to the same value, so both formats round-trip exactly. The file
/// appears atomically (temporary name, then rename).
/// Throws std::invalid_argument if mesh.validate() fails, OutputError if writing fails.
void writePly(const std::filesystem::path& path, const TriangleMesh& mesh,
              PlyFormat format = PlyFormat::kBinaryLittleEndian);

}  // namespace objscan
