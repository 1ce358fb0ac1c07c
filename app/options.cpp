#include "options.h"

#include <algorithm>
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <memory>
#include <set>
#include <string>
#include <system_error>

#include <CLI/CLI.hpp>

#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/intrinsics.h"
#include "objscan/core/log.h"
#include "objscan/render/snapshots.h"
#include "objscan/report/results_io.h"

namespace objscan::app {
namespace {

/// CLI11's reader of --config files, for settings.json.
class SettingsFile : public CLI::Config {
 public:
  explicit SettingsFile(const CLI::App* app) : app_(app) {}

  std::string to_config(const CLI::App*, bool, bool, std::string) const override {
    return {};  // settings.json is written by report::writeSettings, from the parsed options
  }

  std::vector<CLI::ConfigItem> from_config(std::istream&) const override {
    // Read by name with the settings reader's checks and size cap, not from CLI11's stream (which
    // would take /dev/zero to the end of memory); settingsFileCheck has refused what is no
    // regular file before CLI11 opened it.
    const std::string file = app_->get_config_ptr()->as<std::string>();
    const std::vector<CLI::App*> given = app_->get_subcommands();
    const std::string command = given.empty() ? std::string() : given.front()->get_name();
    if (!command.empty() && command != "fuse" && command != "discover" && command != "eval" &&
        command != "scan") {
      // render and the others write no settings.json of their own: there is nothing to repeat.
      throw CLI::ConfigError("objscan " + command +
                             " takes no --config (a settings.json repeats a run of objscan "
                             "fuse, discover, eval or scan)");
    }
    report::Settings settings;
    try {
      settings = report::readSettings(file);
    } catch (const InputError& e) {
      throw CLI::ConfigError(e.what());
    }
    if (settings.command != command) {
      throw CLI::ConfigError(file + ": the settings of objscan " + settings.command + ", not of " +
                             (command.empty() ? std::string("no command") : command));
    }
    if (settings.objscan_version != OBJSCAN_VERSION) {
      log::warning(file + ": written by objscan " + settings.objscan_version + ", this is " +
                   OBJSCAN_VERSION + "; its options are taken as they are");
    }
    std::vector<CLI::ConfigItem> out;
    bool carve_named = false, carved = false, no_carve_named = false;
    for (const report::OptionSetting& o : settings.options) {
      if (o.name == "carve") {
        carve_named = true;
        carved = !o.values.empty() && o.values.front() == "true";
      }
      no_carve_named = no_carve_named || o.name == "no-carve";
    }
    // A file from when fusion averaged by default names "carve" (not given: it averaged) and no
    // "no-carve": it replays as --no-carve, so that it fuses as it did then.
    if (carve_named && !carved && !no_carve_named) {
      const CLI::Option* no_carve = given.front()->get_option_no_throw("--no-carve");
      if (no_carve != nullptr && !givenHere(*no_carve)) {
        CLI::ConfigItem item;
        item.parents = {command};
        item.name = "no-carve";
        item.inputs = {"true"};
        out.push_back(std::move(item));
      }
    }
    for (const report::OptionSetting& o : settings.options) {
      if (o.values.empty()) continue;  // unset: the command's default
      CLI::Option* opt = given.front()->get_option_no_throw("--" + o.name);
      if (opt == nullptr) opt = given.front()->get_option_no_throw(o.name);
      if (opt == nullptr) {
        throw CLI::ConfigError(file + ": \"options." + o.name + "\" is not an option of objscan " +
                               command + " (written by another version?)");
      }
      if (o.flag && o.values.front() != "true") continue;  // a flag not given
      if (givenHere(*opt)) continue;                       // the command line's value wins
      CLI::ConfigItem item;
      item.parents = {command};
      item.name = o.name;
      item.inputs = o.values;
      out.push_back(std::move(item));
    }
    return out;
  }

 private:
  /// The option, or one it excludes (--frames / --seconds, --catalog / --no-catalog), was given
  /// on the command line: the file's value gives way.
  static bool givenHere(const CLI::Option& opt) {
    if (opt.count() > 0) return true;
    for (const CLI::Option* other : opt.get_excludes()) {
      if (other->count() > 0) return true;
    }
    return false;
  }

 public:
 private:
  const CLI::App* app_;
};

/// Options whose values name files or folders (sources among them).
bool namesPaths(const std::string& option) {
  static const std::set<std::string> kPathOptions = {
      "source", "meshes", "scenes", "dir", "out",        "record",
      "catalog", "model", "poses", "intrinsics", "ground-truth", "object-dir"};
  return kPathOptions.contains(option);
}

/// --config names a regular file of at most report::kMaxSettingsBytes. Checked before CLI11 opens
/// it (its results are validated when it asks for the file's name): opening a FIFO would wait for
/// a writer forever.
const CLI::Validator settingsFileCheck(
    [](std::string& path) -> std::string {
      // CLI11 would say "DIR was not readable (missing?)" for a folder.
      std::error_code ec;
      if (std::filesystem::is_directory(path, ec)) {
        return path + " is a folder: give the settings.json in it (" +
               (std::filesystem::path(path) / report::kSettingsFile).string() + ")";
      }
      if (!std::filesystem::exists(path, ec) && !ec) return path + ": no such file";
      try {
        (void)readWholeFile(path, report::kMaxSettingsBytes);
      } catch (const InputError& e) {
        return e.what();
      }
      return {};
    },
    "");

}  // namespace

std::string absolutePath(const std::string& value) {
  const auto starts = [&](std::string_view prefix) { return value.rfind(prefix, 0) == 0; };
  if (value.empty() || value == "live" || value == "groundtruth" || starts("live:") ||
      value == "freenect" || starts("freenect:") || starts("synth:")) {
    return value;
  }
  if (starts("virtual:")) {
    const std::size_t begin = std::string_view("virtual:").size();
    const std::size_t query = std::min(value.find('?', begin), value.size());
    return "virtual:" + absolutePath(value.substr(begin, query - begin)) + value.substr(query);
  }
  std::error_code ec;
  const std::filesystem::path absolute = std::filesystem::absolute(value, ec);
  return ec ? value : absolute.lexically_normal().string();
}

void addConfigOption(CLI::App& app) {
  // On the top level, as CLI11 reads config files only there; `objscan scan --config FILE` reaches
  // it because the subcommands fall through to it.
  app.set_config("--config", "",
                 "A settings.json of an earlier run (OUT/settings.json), after the command: its "
                 "options become the command's defaults; flags given with it override them")
      ->check(settingsFileCheck);
  app.config_formatter(std::make_shared<SettingsFile>(&app));
}

report::Settings commandSettings(const CLI::App& sub) {
  report::Settings settings;
  settings.objscan_version = OBJSCAN_VERSION;
  settings.command = sub.get_name();
  for (const CLI::Option* opt : sub.get_options()) {
    if (opt == sub.get_help_ptr() || opt == sub.get_config_ptr()) continue;
    report::OptionSetting o;
    o.name = opt->get_lnames().empty() ? opt->get_name() : opt->get_lnames().front();
    o.flag = opt->get_expected_min() == 0;
    o.list = !o.flag && opt->get_expected_max() > 1;
    if (o.flag) {
      o.values = {opt->count() > 0 ? "true" : "false"};
    } else if (opt->count() > 0) {
      o.values = opt->results();
      if (namesPaths(o.name)) {
        for (std::string& value : o.values) value = absolutePath(value);
      }
    } else if (!opt->get_default_str().empty()) {
      o.values = {opt->get_default_str()};
    }
    settings.options.push_back(std::move(o));
  }
  return settings;
}

CLI::Validator wholeNumberFrom(std::uint64_t min) {
  const std::string wanted = "must be a whole number of at least " + std::to_string(min);
  return CLI::Validator(
      [min, wanted](std::string& text) -> std::string {
        std::uint64_t value = 0;
        const char* end = text.data() + text.size();
        const auto [ptr, error] = std::from_chars(text.data(), end, value);
        // Counts of frames, splits or vertices never come near 2^53; larger is a typo.
        if (error != std::errc() || ptr != end || value > (std::uint64_t{1} << 53) || value < min) {
          return wanted + " (got '" + text + "')";
        }
        return {};
      },
      "", "whole number");
}

CLI::Validator positiveNumber() {
  return CLI::Validator(
      [](std::string& text) -> std::string {
        char* end = nullptr;
        const double value = std::strtod(text.c_str(), &end);
        if (text.empty() || end != text.c_str() + text.size() || !std::isfinite(value) ||
            !(value > 0.0)) {
          return "must be a number above 0 (got '" + text + "')";
        }
        return {};
      },
      "", "positive number");
}

void addObjectFormat(CLI::App* sub, std::string& format) {
  sub->add_option("--object-format", format,
                  "File format of each object in objects/: ply (colours, normals), obj "
                  "(MeshLab, Blender), stl (geometry only) or glb (glTF: browsers, Blender)")
      ->check(CLI::IsMember({"ply", "obj", "stl", "glb"}))
      ->capture_default_str();
}

void addFusionOptions(CLI::App* sub, pipeline::FuseOptions& o) {
  sub->add_option("--voxel-size", o.config.volume.voxel_size_m,
                  "Voxel edge in metres (default 5.86 mm: 3 m / 512, the paper's density)")
      ->default_str(exactText(o.config.volume.voxel_size_m));
  sub->add_option("--truncation", o.config.volume.truncation_m,
                  "Truncation distance in metres (default: 0.03, or 3 voxels if larger)");
  CLI::Option* behind = sub->add_option(
      "--behind", o.config.volume.behind_m,
      "Update the volume only this far behind each reading, metres, 2 voxels to the truncation "
      "(default: the truncation)");
  sub->add_flag("--behind-noise", o.config.volume.behind_follows_noise,
                "Update the volume behind each reading as deep as three sigmas of a Kinect-type "
                "sensor's noise at its depth (2 voxels to the truncation)")
      ->excludes(behind);
  bool& carve = o.config.volume.carve_free_space;
  CLI::Option* no_carve = sub->add_flag_callback(
      "--no-carve", [&carve] { carve = false; },
      "Average every reading as KinectFusion does, instead of letting free space a reading sees "
      "beat solid guessed from deep behind another surface (the default, which keeps "
      "thin-walled hollows hollow; see docs/fusion.md, Thin walls)");
  sub->add_flag_callback(
         "--carve", [&carve] { carve = true; },
         "Carve (the default; named by settings files written when it was not)")
      ->excludes(no_carve);
  sub->add_option("--min-depth", o.config.preprocess.min_depth_m,
                  "Ignore depth nearer than this (m)")
      ->default_str(exactText(o.config.preprocess.min_depth_m));
  sub->add_option("--max-depth", o.config.preprocess.max_depth_m,
                  "Ignore depth farther than this (m)")
      ->default_str(exactText(o.config.preprocess.max_depth_m));
  sub->add_option("--poses", o.poses,
                  "Integrate at given poses instead of tracking: a TUM trajectory file, or "
                  "'groundtruth' for the source's own");
  sub->add_option("--start", o.start, "First frame (0-based)")
      ->check(wholeNumberFrom(0))
      ->capture_default_str();
  sub->add_option("--end", o.end, "Stop before this frame")->check(wholeNumberFrom(1));
  sub->add_option("--every", o.every, "Use every n-th frame")
      ->check(wholeNumberFrom(1))
      ->capture_default_str();
  sub->add_option("--intrinsics", o.intrinsics,
                  "intrinsics.json (fx, fy, cx, cy, width, height) replacing the source's");
  sub->add_flag("--no-color", o.no_color, "Fuse depth only (mesh without colours)");
}

void addDiscoveryOptions(CLI::App* sub, discovery::DiscoveryConfig& config) {
  sub->add_option("--min-size", config.min_size,
                  "Smallest segment, in vertices at the paper's density (scaled with the "
                  "mesh's; the paper's m_size)")
      ->check(wholeNumberFrom(1))
      ->capture_default_str();
  sub->add_flag_callback(
      "--paper-segmentation",
      [&config] {
        config.supports.enabled = false;
        config.convexity.enabled = false;
      },
      "Segment as the paper does, without first cutting objects from the planes they stand on "
      "(objscan's support surfaces; see the README)");
  sub->add_flag_callback(
      "--color-cuts", [&config] { config.convexity.colour_limits = {20.0f}; },
      "Also split touching objects where two plain colours meet (a lid on a jar): more "
      "candidates, off by default as the cut is fragile (see docs/discovery.md, Colour cuts)");
  sub->add_flag_callback(
      "--no-object-set", [&config] { config.objects.enabled = false; },
      "Rank every hypothesis by its score alone, overlapping ones included, as the paper does "
      "(default: the object set first, whose hypotheses never overlap; see docs/discovery.md)");
  sub->add_option("--max-iou", config.max_iou,
                  "Non-maximum suppression: drop a hypothesis whose vertices overlap a better one's "
                  "by more than this intersection over union (the paper's 0.7; 1 keeps all)")
      ->check(CLI::Range(0.01, 1.0))
      ->capture_default_str();
}

void addLabelledScenes(CLI::App* sub, std::vector<std::filesystem::path>& scenes,
                       std::optional<std::filesystem::path>& catalog) {
  sub->add_option("scenes", scenes,
                  "Labelled scenes: folders with scene_gt.ply and fused/mesh.ply "
                  "(scripts/make_discovery_scenes), meshes whose vertices carry object_id, or "
                  "PCD clouds with a label field")
      ->required();
  sub->add_option("--catalog", catalog, "Catalog to reuse and extend (default: none)");
}

void addSceneReading(CLI::App* sub, discovery::SceneReading& reading) {
  sub->add_option_function<std::string>(
      "--intrinsics",
      [&reading](const std::string& file) {
        reading.intrinsics = readIntrinsicsJson(file);
        reading.intrinsics_origin = file;
      },
      "intrinsics.json of the camera: of unorganized PCD scenes (default: the pinhole that fits "
      "their points), or replacing the source's with --frame");
  sub->add_option_function<std::string>(
         "--up",
         [&reading](const std::string& text) {
           float x = 0, y = 0, z = 0;
           char extra = 0;
           if (std::sscanf(text.c_str(), "%f,%f,%f%c", &x, &y, &z, &extra) != 3) {
             throw CLI::ValidationError("--up", "expected three numbers X,Y,Z, e.g. 0,0,1");
           }
           const Eigen::Vector3f up(x, y, z);
           if (!up.allFinite() || !(up.norm() > 0.0f)) {
             throw CLI::ValidationError("--up", "the direction must be finite and not zero");
           }
           reading.view_up = up.normalized();
         },
         "Which way is up in the scenes' frame, X,Y,Z (default: a PCD's camera -y, or the camera "
         "path objscan writes beside a mesh, trajectory.txt); supports that do not face it hold "
         "nothing up (docs/discovery.md)")
      ->type_name("X,Y,Z");
}

void addPictureOptions(CLI::App* sub, pipeline::PictureOptions& o) {
  sub->add_option("--top", o.top, "Hypotheses to paint and show in close-up")
      ->check(CLI::Range(1, 100))
      ->capture_default_str();
  sub->add_option_function<std::string>(
         "--size",
         [&o](const std::string& size) {
           int w = 0, h = 0;
           char x = 0, extra = 0;
           if (std::sscanf(size.c_str(), "%d%c%d%c", &w, &x, &h, &extra) != 3 || x != 'x') {
             throw CLI::ValidationError("--size", "expected WIDTHxHEIGHT, e.g. 1280x960");
           }
           o.width = w;
           o.height = h;
         },
         "Overview size in pixels, WIDTHxHEIGHT (close-ups are 3/8 of it)")
      ->default_str("1280x960");
  sub->add_option_function<std::string>(
         "--view", [&o](const std::string& v) { o.view = objscan::render::parseViewKind(v); },
         "Overview camera: auto (the capture's trajectory, else three-quarter), trajectory, "
         "three-quarter or top")
      ->check(CLI::IsMember({"auto", "trajectory", "three-quarter", "top"}))
      ->default_str("auto");
  sub->add_flag("--ranks-image", o.ranks_image,
                "Also write renders/overview_ranks.png: 16-bit, the rank painted at each pixel");
}

}  // namespace objscan::app
