#pragma once

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include "objscan/core/mesh_formats.h"
#include "objscan/discovery/evaluation.h"
#include "objscan/discovery/scenes.h"
#include "objscan/report/results.h"

/// One writer and one reader for each file of a results folder. Writers write atomically
/// (temporary name, then rename; folders staged as NAME.partial and swapped in whole) and throw
/// OutputError; readers throw InputError naming the file and, for a JSON file, the key that is
/// missing or of the wrong type (a damaged file, or one an older objscan wrote).
namespace objscan::report {

/// A number as the shortest text of at most 9 significant digits that reads back to the same
/// float: settings.json must repeat a run exactly.
std::string exactText(float value);

/// The names of a results folder's files.
inline constexpr const char* kMeshFile = "mesh.ply";
inline constexpr const char* kTrajectoryFile = "trajectory.txt";
inline constexpr const char* kHypothesesFile = "hypotheses.json";
inline constexpr const char* kObjectsFolder = "objects";
/// The meshes of scenes that are not PLY files (SceneRecord::mesh_copy): scene_NNN.ply.
inline constexpr const char* kScenesFolder = "scenes";
inline constexpr const char* kEvaluationFile = "evaluation.json";
inline constexpr const char* kRendersFolder = "renders";
inline constexpr const char* kTimingsFile = "timings.json";
inline constexpr const char* kSettingsFile = "settings.json";
inline constexpr const char* kReportFile = "report.html";

/// The file of rank `rank` in objects/ (".ply") or renders/ (".png"): rank_001.ply, ...
std::string rankFileName(std::size_t rank, const char* extension);

// ---- mesh.ply and trajectory.txt ---------------------------------------------------------------

/// Writes DIR/mesh.ply and DIR/trajectory.txt (each once, atomically) and returns the bytes of
/// mesh.ply (a catalog hashes them).
std::string writeMeshAndTrajectory(const std::filesystem::path& dir, const TriangleMesh& mesh,
                                   const Trajectory& trajectory);

/// Removes what an earlier run derived from an earlier mesh.ply (hypotheses.json, objects/,
/// renders/, evaluation.json, report.html, timings.json, settings.json): a new mesh makes them
/// stale. Throws OutputError when one cannot be removed.
void removeOutputsAfterTheMesh(const std::filesystem::path& dir);

// ---- hypotheses.json and objects/ --------------------------------------------------------------

/// The catalog a discovery run used, as hypotheses.json and settings.json record it; nothing
/// without one.
std::optional<CatalogUse> catalogUseOf(const discovery::SceneDiscovery& run);

/// hypotheses.json's record of a discovery run written into `results_dir`; `model` is the model
/// file scored with (empty for the average). Scenes are named relative to `results_dir`, with
/// their absolute path beside (SceneRecord).
Hypotheses hypothesesFrom(const discovery::SceneDiscovery& run, const std::string& model,
                          const std::filesystem::path& results_dir,
                          MeshFormat object_format = MeshFormat::kPly);

/// Writes DIR/objects/rank_NNN.<format> (each hypothesis's sub-mesh of run.scenes[...].mesh, in
/// the format hypothesesFrom named) and rank_NNN.json (its box and its pose T_W_O: the object
/// frame at the box centre, along the box axes) staged, and DIR/scenes/scene_NNN.ply for each
/// scene with a SceneRecord::mesh_copy, then DIR/hypotheses.json, then swaps objects/ and
/// scenes/ in: a failure before the swap leaves the previous run's files as they were.
void writeDiscovery(const std::filesystem::path& dir, const Hypotheses& hypotheses,
                    const discovery::SceneDiscovery& run, MeshFormat format = MeshFormat::kPly);

void writeHypotheses(const std::filesystem::path& file, const Hypotheses& hypotheses);
/// Requires "hypotheses" (each with a rank >= 1) and each scene's "mesh".
Hypotheses readHypotheses(const std::filesystem::path& file);

// ---- evaluation.json ---------------------------------------------------------------------------

/// evaluation.json's record of an evaluation; `names` are the objects' names by id.
Evaluation evaluationFrom(const discovery::RankingEvaluation& evaluation,
                          const std::string& ground_truth,
                          const std::map<std::int32_t, std::string>& names);
void writeEvaluation(const std::filesystem::path& file, const Evaluation& evaluation);
Evaluation readEvaluation(const std::filesystem::path& file);

// ---- timings.json ------------------------------------------------------------------------------

void writeTimings(const std::filesystem::path& file, const Timings& timings);
Timings readTimings(const std::filesystem::path& file);

// ---- renders/ ----------------------------------------------------------------------------------

/// Writes DIR/renders/ (overview.png, overview_ranks.png, overview_camera.json, rank_NNN.png,
/// contact_sheet.png: those present) into a fresh renders.partial, swapped in whole.
void writePictures(const std::filesystem::path& dir, const Pictures& pictures);
/// Reads DIR/renders/'s pictures (those present; the close-ups of `ranks`) and its camera.
/// InputError for a file that is not a PNG, or a camera file of the wrong shape.
Pictures readPictures(const std::filesystem::path& dir, const std::vector<std::size_t>& ranks);
/// How many of the best hypotheses DIR's pictures paint: its close-ups (renders/rank_001.png and
/// on, while they follow each other); kDefaultPaintedTop when it has none (not rendered yet).
std::size_t paintedTop(const std::filesystem::path& dir);
/// renders/overview_camera.json's reader. Throws InputError naming the file when it is missing or
/// damaged.
OverviewCamera readOverviewCamera(const std::filesystem::path& file);
/// A PNG's size from its header; InputError naming `what` when the bytes are not a PNG.
Picture pictureFromPng(std::string png, const std::string& what);

// ---- settings.json -----------------------------------------------------------------------------

/// The largest settings.json objscan reads: one is a few kB; past this it is not one (and a huge or
/// sparse file is refused before it is read).
inline constexpr std::uintmax_t kMaxSettingsBytes = 1 << 20;

void writeSettings(const std::filesystem::path& file, const Settings& settings);
/// Reads a regular file of at most kMaxSettingsBytes (readWholeFile's checks: a device, a FIFO or
/// a larger file is an InputError before anything is read).
Settings readSettings(const std::filesystem::path& file);
/// The same reader on the file's text (`file` names it in errors).
Settings parseSettings(const std::string& text, const std::filesystem::path& file);

// ---- the folder --------------------------------------------------------------------------------

/// Which parts of a results folder readResults reads besides the JSON files.
struct ResultsParts {
  bool mesh = false;
  bool pictures = true;  ///< renders/: the close-ups of the first max_closeups ranks
  std::size_t max_closeups = 50;
};

/// The places the mesh of `scene` (a scene of DIR/hypotheses.json) may be, in order: the copy
/// discover wrote of a scene that is not a PLY file (SceneRecord::mesh_copy), the folder's
/// own mesh.ply (scan writes it there), the path discover noted relative to the folder, its
/// absolute path (the folder moved without its scene), and (a folder from before paths were
/// relative) the path as it was given, from the working directory.
std::vector<std::filesystem::path> sceneMeshPlaces(const std::filesystem::path& dir,
                                                   const SceneRecord& scene);

/// The mesh `scene` was cut from: the first of sceneMeshPlaces() that exists and has the vertex
/// count hypotheses.json noted (its path into `found`). Throws InputError naming the file when
/// none is there, one has another vertex count (the scene changed since), or it is damaged.
TriangleMesh readSceneMesh(const std::filesystem::path& dir, const SceneRecord& scene,
                           std::filesystem::path* found = nullptr);

/// What a results folder holds: hypotheses.json (required) and every other file present, read by
/// its reader.
ScanResults readResults(const std::filesystem::path& dir, const ResultsParts& parts = {});

}  // namespace objscan::report
