#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "objscan/discovery/discover.h"
#include "objscan/discovery/scenes.h"
#include "objscan/pipeline/fuse.h"
#include "objscan/pipeline/pictures.h"
#include "objscan/report/results.h"
#include "objscan/report/results_io.h"

// CLI11 is included by the sources that build the command line: it takes seconds to compile
// at -O3, and most sources that include this header do not use it.
namespace CLI {
class App;
class Validator;
}  // namespace CLI

/// Flags several commands share, each bound to the library's config it sets.
namespace objscan::app {

using report::exactText;

/// A file or folder given relative to the working directory, made absolute (as settings.json
/// records it, so that `--config OUT/settings.json` reads the same files from any directory).
/// Sources that are not paths stay as they are: synth:<seed>, live[:uri], --poses groundtruth;
/// virtual:<source> has its source made absolute.
std::string absolutePath(const std::string& value);

/// A whole number of at least `min` (frames, splits, vertices): refuses a sign, a fraction and a
/// number too large for a count with "must be a whole number of at least MIN (got 'TEXT')",
/// where CLI11's own checks print a 300-digit bound or wrap around to 18446744073709551615.
CLI::Validator wholeNumberFrom(std::uint64_t min);

/// A finite number above 0 (seconds, sizes): "must be a number above 0 (got 'TEXT')".
CLI::Validator positiveNumber();

/// fuse's and scan's: voxel size, truncation, depth range, poses, frame selection, intrinsics.
void addFusionOptions(CLI::App* sub, pipeline::FuseOptions& o);

/// discover's, eval's, train's and scan's: --min-size, --paper-segmentation, --color-cuts,
/// --no-object-set, --max-iou.
void addDiscoveryOptions(CLI::App* sub, discovery::DiscoveryConfig& config);

/// discover's and scan's --object-format ply|obj|stl|glb.
void addObjectFormat(CLI::App* sub, std::string& format);

/// --intrinsics: the camera of unorganized PCD scenes.
void addSceneReading(CLI::App* sub, discovery::SceneReading& reading);

/// eval's and train's: the labelled scenes and the catalog.
void addLabelledScenes(CLI::App* sub, std::vector<std::filesystem::path>& scenes,
                       std::optional<std::filesystem::path>& catalog);

/// render's and scan's: --top, --size, --view, --ranks-image.
void addPictureOptions(CLI::App* sub, pipeline::PictureOptions& o);

/// --config FILE: a settings.json (one a results folder holds) whose options become the given
/// command's defaults; flags given on the command line override them. A file of another command,
/// or one that is not such a file, is a usage error naming it.
void addConfigOption(CLI::App& app);

/// How the parsed `sub` was run: every option by its long name (a positional by its name), as
/// given or its default (empty where it has none), and objscan's version.
report::Settings commandSettings(const CLI::App& sub);

}  // namespace objscan::app
