// objscan: the command line. Parses flags, calls the library, prints, chooses the exit code
// (README, "Exit codes"). Nothing else lives here.

#include <CLI/CLI.hpp>
#include <algorithm>
#include <cstdio>
#include <optional>
#include <stdexcept>
#include <string>
#include <vector>

#include "discover_command.h"
#include "eval_command.h"
#include "exit_codes.h"
#include "fuse_command.h"
#include "info_command.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "record_command.h"
#include "render_command.h"
#include "scan_command.h"
#include "stop_signals.h"
#include "synth_command.h"

namespace {

using namespace objscan::app;

constexpr const char* kVersion = "0.1.0";

/// One line on stderr, whatever the message holds.
void printError(const std::string& message) {
  std::string line = message;
  for (char& c : line) {
    if (c == '\n' || c == '\r') c = ' ';
  }
  std::fprintf(stderr, "objscan: error: %s\n", line.c_str());
}

int run(int argc, char** argv) {
  CLI::App app{
      "objscan: turn an RGB-D capture into a fused mesh and a ranked list of the objects in it.",
      "objscan"};
  bool version = false;
  app.add_flag("--version", version, "Print the version and exit");
  app.require_subcommand(0, 1);
  app.fallthrough();
  bool verbose = false;
  bool quiet = false;
  auto* verbose_flag = app.add_flag("-v,--verbose", verbose, "Log details to stderr");
  app.add_flag("-q,--quiet", quiet, "Log only errors to stderr (no progress)")
      ->excludes(verbose_flag);
  app.footer(
      "Exit codes: 0 success, 1 runtime failure, 2 bad usage or bad input, 3 no sensor attached,\n"
      "130 interrupted (Ctrl-C; what was written is complete).\n"
      "Run 'objscan <command> --help' for a command's options.\n");

  std::string info_path;
  CLI::App* info = app.add_subcommand(
      "info", "Print what a mesh (.ply), trajectory (TUM .txt) or recording holds");
  info->add_option("path", info_path,
                   "A .ply mesh, a TUM trajectory .txt, or a TUM-format recording folder")
      ->required();

  SynthOptions synth_options;
  CLI::App* synth = app.add_subcommand(
      "synth", "Generate a synthetic scene with exact ground truth, rendered as a TUM recording");
  synth->add_option("--out", synth_options.out, "Folder to create (must not exist, or be empty)")
      ->required();
  synth->add_option("--preset", synth_options.preset, "Scene: desk, shelf or counter")
      ->capture_default_str();
  synth->add_option("--objects", synth_options.objects, "How many objects to place (1-30)")
      ->capture_default_str();
  synth->add_option("--object-dir", synth_options.object_dir,
                    "Folder of .ply meshes (metres, z up) added to the built-in shapes");
  synth->add_option("--frames", synth_options.frames, "Frames along the hand-held path (30 Hz)")
      ->capture_default_str();
  synth->add_option("--seed", synth_options.seed, "Seed: same seed, same files")
      ->check(CLI::Validator(
          [](std::string& s) {
            return s.starts_with('-') ? std::string("must be 0 or more") : std::string();
          },
          "NONNEGATIVE"))
      ->capture_default_str();
  synth->add_option("--noise", synth_options.noise, "Depth-sensor noise model: on or off")
      ->capture_default_str();
  synth->add_option("--intrinsics", synth_options.intrinsics,
                    "intrinsics.json (fx, fy, cx, cy, width, height); default: Xtion 640x480");

  CLI::App* devices =
      app.add_subcommand("devices", "List connected OpenNI2 sensors (Asus Xtion, Kinect v1, ...)");

  RecordCommandOptions record_options;
  CLI::App* record = app.add_subcommand(
      "record", "Record a sensor session to an .oni file (depth lossless); Ctrl-C stops cleanly");
  record->add_option("--out", record_options.out, "The .oni file to write")->required();
  record->add_option("--device", record_options.device,
                     "Sensor URI (objscan devices lists them); default: the first one. "
                     "virtual:<folder> or virtual:synth:<seed> streams a dataset or a synthetic "
                     "scene through objscan's virtual OpenNI2 sensor");
  auto* frames_option =
      record->add_option("--frames", record_options.frames, "Stop after this many frames")
          ->check(CLI::PositiveNumber);
  record->add_option("--seconds", record_options.seconds, "Stop after this many seconds")
      ->check(CLI::PositiveNumber)
      ->excludes(frames_option);
  record->add_flag("--compress-color", record_options.compress_color,
                   "Store colour as JPEG (lossy, about 10x smaller); depth stays lossless");
  record->add_option("--intrinsics", record_options.intrinsics,
                     "intrinsics.json stored with the recording (X.oni.json) instead of what the "
                     "sensor reports; replay uses it");

  FuseCommandOptions fuse_options;
  std::optional<float> truncation_m;
  CLI::App* fuse = app.add_subcommand(
      "fuse", "Fuse a recording into DIR/mesh.ply and DIR/trajectory.txt (TSDF + ICP tracking)");
  fuse->add_option("source", fuse_options.source,
                   "X.oni, a TUM or 7-Scenes folder, synth:<seed>, live[:uri] or virtual:<source>")
      ->required();
  fuse->add_option("--out", fuse_options.out, "Folder for mesh.ply and trajectory.txt")->required();
  const auto addFusionOptions = [](CLI::App* sub, FuseCommandOptions& o,
                                   std::optional<float>& truncation) {
    sub->add_option("--voxel-size", o.config.volume.voxel_size_m,
                    "Voxel edge in metres (default: 3 m / 512, the paper's density)")
        ->capture_default_str();
    sub->add_option("--truncation", truncation,
                    "Truncation distance in metres (default: 0.03, or 3 voxels if larger)");
    sub->add_option("--min-depth", o.config.preprocess.min_depth_m,
                    "Ignore depth nearer than this (m)")
        ->capture_default_str();
    sub->add_option("--max-depth", o.config.preprocess.max_depth_m,
                    "Ignore depth farther than this (m)")
        ->capture_default_str();
    sub->add_option("--poses", o.poses,
                    "Integrate at given poses instead of tracking: a TUM trajectory file, or "
                    "'groundtruth' for the source's own");
    sub->add_option("--start", o.start, "First frame (0-based)")->check(CLI::NonNegativeNumber);
    sub->add_option("--end", o.end, "Stop before this frame")->check(CLI::PositiveNumber);
    sub->add_option("--every", o.every, "Use every n-th frame")->check(CLI::PositiveNumber);
    sub->add_option("--intrinsics", o.intrinsics,
                    "intrinsics.json (fx, fy, cx, cy, width, height) replacing the source's");
    sub->add_flag("--no-color", o.no_color, "Fuse depth only (mesh without colours)");
  };
  addFusionOptions(fuse, fuse_options, truncation_m);

  DiscoverCommandOptions discover_options;
  std::filesystem::path discover_catalog;
  CLI::App* discover = app.add_subcommand(
      "discover", "Segment scene meshes, measure and rank object hypotheses into DIR");
  discover
      ->add_option("meshes", discover_options.meshes,
                   "Scene meshes (.ply, e.g. objscan fuse's mesh.ply), or folders holding one")
      ->required();
  discover->add_option("--out", discover_options.out, "Folder for hypotheses.json and objects/")
      ->required();
  auto* catalog_option =
      discover->add_option("--catalog", discover_catalog,
                           "Catalog of scenes seen so far (SQLite; default $OBJSCAN_CATALOG or "
                           "~/.local/share/objscan/catalog.sqlite)");
  discover
      ->add_flag("--no-catalog", discover_options.no_catalog,
                 "Use no catalog: recurrence only among the scenes given")
      ->excludes(catalog_option);
  discover->add_option("--model", discover_options.model,
                       "Score with a classifier from objscan train (default: the average of the "
                       "normalised measures)");
  discover->add_flag("--timings", discover_options.timings, "Print each stage's time");
  const auto addDiscoveryOptions = [](CLI::App* sub, objscan::discovery::DiscoveryConfig& config) {
    sub->add_option("--min-size", config.min_size,
                    "Smallest segment, in vertices at the paper's density (scaled with the "
                    "mesh's; the paper's m_size)")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    sub->add_flag_callback(
        "--paper-segmentation", [&config] { config.supports.enabled = false; },
        "Segment as the paper does, without first cutting objects from the planes they stand on "
        "(objscan's support surfaces; see the README)");
  };
  addDiscoveryOptions(discover, discover_options.config);

  const auto addLabelledScenes = [](CLI::App* sub, std::vector<std::filesystem::path>& scenes,
                                    std::optional<std::filesystem::path>& catalog) {
    sub->add_option("scenes", scenes,
                    "Labelled scenes: folders with scene_gt.ply and fused/mesh.ply "
                    "(scripts/make_discovery_scenes), or meshes whose vertices carry object_id")
        ->required();
    sub->add_option("--catalog", catalog, "Catalog to reuse and extend (default: none)");
  };
  EvalCommandOptions eval_options;
  CLI::App* eval = app.add_subcommand(
      "eval", "The paper's evaluation on labelled scenes: AP, precision-recall, ablation, recall");
  addLabelledScenes(eval, eval_options.scenes, eval_options.catalog);
  eval->add_option("--out", eval_options.out, "Folder for the CSV files and plots")->required();
  addDiscoveryOptions(eval, eval_options.config);
  eval->add_option("--splits", eval_options.splits, "Random train/test halvings")
      ->check(CLI::PositiveNumber)
      ->capture_default_str();
  eval->add_option("--seed", eval_options.seed, "Seed of the splits and folds")
      ->capture_default_str();
  bool no_ablation = false;
  eval->add_flag("--no-ablation", no_ablation, "Skip the RBF SVM without each measure");

  TrainCommandOptions train_options;
  CLI::App* train = app.add_subcommand(
      "train", "Fit a classifier that scores hypotheses (for objscan discover --model)");
  addLabelledScenes(train, train_options.scenes, train_options.catalog);
  train->add_option("--model", train_options.model, "Model file to write (YAML)")->required();
  train
      ->add_option("--kind", train_options.kind,
                   "naive_bayes, linear_svm, rbf_svm or nearest_neighbour")
      ->capture_default_str();
  train
      ->add_option("--min-iou", train_options.min_iou,
                   "A segment is an object at this IoU with a ground-truth object")
      ->check(CLI::Range(0.01, 1.0))
      ->capture_default_str();
  addDiscoveryOptions(train, train_options.config);
  train->add_option("--seed", train_options.seed, "Seed of the cross-validation folds")
      ->capture_default_str();

  const auto addRenderOptions = [](CLI::App* sub, RenderCommandOptions& o) {
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
  };

  RenderCommandOptions render_options;
  CLI::App* render = app.add_subcommand(
      "render",
      "Render the top hypotheses of a results folder into DIR/renders/ and DIR/report.html");
  render
      ->add_option("dir", render_options.dir,
                   "A results folder of objscan scan (or discover): hypotheses.json, mesh.ply, "
                   "trajectory.txt")
      ->required();
  addRenderOptions(render, render_options);

  ScanCommandOptions scan_options;
  std::optional<float> scan_truncation_m;
  std::filesystem::path scan_catalog;
  bool scan_compress_color = false;
  CLI::App* scan = app.add_subcommand(
      "scan", "Capture (or replay) to ranked objects in one go: fuse, discover, render, report");
  scan->add_option(
      "source", scan_options.source,
      "X.oni, a TUM or 7-Scenes folder, synth:<seed>, virtual:<source>, or live[:uri]; "
      "default: the first live sensor");
  scan->add_option("--out", scan_options.out,
                   "Folder for mesh.ply, trajectory.txt, hypotheses.json, objects/, renders/, "
                   "report.html, timings.json")
      ->required();
  auto* scan_frames = scan->add_option("--frames", scan_options.limits.max_frames,
                                       "Stop capture after this many frames")
                          ->check(CLI::PositiveNumber);
  scan->add_option("--seconds", scan_options.limits.max_seconds, "Stop capture after this long")
      ->check(CLI::PositiveNumber)
      ->excludes(scan_frames);
  addFusionOptions(scan, scan_options.fuse, scan_truncation_m);
  std::filesystem::path scan_record;
  scan->add_option("--record", scan_record,
                   "Save the live sensor's raw stream to this .oni while scanning (depth "
                   "lossless; replayable however capture ends)");
  scan->add_flag("--compress-color", scan_compress_color,
                 "With --record: store colour as JPEG (lossy, about 10x smaller)");
  auto* scan_catalog_option =
      scan->add_option("--catalog", scan_catalog,
                       "Catalog of scenes seen so far (default $OBJSCAN_CATALOG or "
                       "~/.local/share/objscan/catalog.sqlite)");
  scan->add_flag("--no-catalog", scan_options.discover.no_catalog, "Use no catalog")
      ->excludes(scan_catalog_option);
  scan->add_option("--model", scan_options.discover.model,
                   "Score with a classifier from objscan train (default: the average)");
  addDiscoveryOptions(scan, scan_options.discover.config);
  addRenderOptions(scan, scan_options.render);
  auto* truth_option = scan->add_option(
      "--ground-truth", scan_options.ground_truth,
      "Scene mesh with per-vertex object_id (objscan synth's scene_gt.ply) to score the "
      "hypotheses against (default: X.scene_gt.ply beside X.oni, scene_gt.ply in a folder)");
  scan->add_flag("--no-ground-truth", scan_options.no_ground_truth,
                 "Do not look for ground truth beside the source")
      ->excludes(truth_option);

  try {
    app.parse(argc, argv);
  } catch (const CLI::CallForHelp& e) {
    return app.exit(e);
  } catch (const CLI::CallForAllHelp& e) {
    return app.exit(e);
  } catch (const CLI::ParseError& e) {
    printError(std::string(e.what()) + " (run 'objscan --help')");
    return kExitBadInput;
  }

  if (version) {
    std::printf("objscan %s\n", kVersion);
    return kExitSuccess;
  }
  if (app.get_subcommands().empty()) {
    printError("a command is required (run 'objscan --help')");
    return kExitBadInput;
  }

  objscan::log::setLevel(quiet     ? objscan::log::Level::kError
                         : verbose ? objscan::log::Level::kDebug
                                   : objscan::log::Level::kInfo);

  if (info->parsed()) runInfo(info_path);
  if (devices->parsed()) runDevices();
  if (record->parsed()) return runRecord(record_options);
  if (fuse->parsed()) {
    auto& volume = fuse_options.config.volume;
    volume.truncation_m = truncation_m.value_or(std::max(0.03f, 3.0f * volume.voxel_size_m));
    return runFuse(fuse_options);
  }
  if (synth->parsed()) runSynth(synth_options);
  if (discover->parsed()) {
    if (!discover_catalog.empty()) discover_options.catalog = discover_catalog;
    return runDiscover(discover_options);
  }
  if (eval->parsed()) {
    eval_options.ablation = !no_ablation;
    return runEval(eval_options);
  }
  if (train->parsed()) return runTrain(train_options);
  if (render->parsed()) return runRender(render_options);
  if (scan->parsed()) {
    auto& volume = scan_options.fuse.config.volume;
    volume.truncation_m = scan_truncation_m.value_or(std::max(0.03f, 3.0f * volume.voxel_size_m));
    if (!scan_catalog.empty()) scan_options.discover.catalog = scan_catalog;
    if (!scan_record.empty()) {
      objscan::capture::LiveRecording live_record;
      live_record.out = scan_record;
      live_record.compress_color = scan_compress_color;
      scan_options.fuse.record = live_record;
    } else if (scan_compress_color) {
      printError("--compress-color needs --record (run 'objscan scan --help')");
      return kExitBadInput;
    }
    return runScan(scan_options);
  }
  return kExitSuccess;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    const int code = run(argc, argv);
    // Output piped to a full disk or a closed pipe must not look like success.
    if (std::fflush(stdout) != 0 || std::ferror(stdout)) {
      printError("cannot write to standard output");
      return kExitRuntimeFailure;
    }
    return code;
  } catch (const objscan::app::Interrupted& e) {
    printError(e.what());
    return kExitInterrupted;
  } catch (const objscan::InputError& e) {
    printError(e.what());
    return kExitBadInput;
  } catch (const std::invalid_argument& e) {
    printError(e.what());
    return kExitBadInput;
  } catch (const objscan::NoSensorError& e) {
    printError(e.what());
    return kExitNoSensor;
  } catch (const std::exception& e) {
    printError(e.what());
    return kExitRuntimeFailure;
  }
}
