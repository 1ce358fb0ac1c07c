// The flags of objscan's analysis commands: discover, eval, train, render, scan.

#include <memory>
#include <string>

#include <CLI/CLI.hpp>

#include "commands.h"
#include "discover_command.h"
#include "eval_command.h"
#include "exit_codes.h"
#include "objscan/capture/openni.h"
#include "options.h"
#include "render_command.h"
#include "scan_command.h"

namespace objscan::app {

Command addDiscoverCommand(CLI::App& app) {
  auto options = std::make_shared<DiscoverCommandOptions>();
  DiscoverCommandOptions& discover_options = *options;
  CLI::App* discover = app.add_subcommand(
      "discover", "Segment scene meshes, measure and rank object hypotheses into DIR");
  discover->footer(
      "Examples:\n"
      "  objscan discover out/desk/mesh.ply --out out/desk-objects\n"
      "  objscan discover view.pcd --out out/view --no-catalog   (one camera view, ranked alone)\n"
      "  objscan discover session.oni --frame 30 --out out/frame30");
  discover
      ->add_option("meshes", discover_options.meshes,
                   "Scenes: meshes (.ply, e.g. objscan fuse's mesh.ply), folders holding one, or a "
                   "camera's point clouds (.pcd); with --frame, <source>s as fuse takes them")
      ->required();
  discover->add_option("--frame", discover_options.frame,
                       "Discover objects in this one frame (0-based) of each <source> (a "
                       "recording, a dataset folder, synth:<seed>, live, freenect, virtual:...)");
  discover->add_option("--out", discover_options.out, "Folder for hypotheses.json and objects/")
      ->required();
  auto* catalog_option =
      discover->add_option("--catalog", discover_options.catalog,
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
  addObjectFormat(discover, discover_options.object_format);
  addDiscoveryOptions(discover, discover_options.config);
  addSceneReading(discover, discover_options.reading);
  return {discover, [options, discover] {
            options->settings = commandSettings(*discover);
            return runDiscover(*options);
          }};
}

Command addEvalCommand(CLI::App& app) {
  auto options = std::make_shared<EvalCommandOptions>();
  EvalCommandOptions& eval_options = *options;
  CLI::App* eval = app.add_subcommand(
      "eval", "The paper's evaluation on labelled scenes: AP, precision-recall, ablation, recall");
  eval->footer(
      "Example:\n"
      "  objscan eval scenes/learn*.pcd --out out/eval --no-classifiers --category "
      "'boxes=learn[0-9]\\.pcd'");
  addLabelledScenes(eval, eval_options.scenes, eval_options.catalog);
  eval->add_option("--out", eval_options.out, "Folder for the CSV files and plots")->required();
  eval->add_option("--model", eval_options.model,
                   "Rank with a classifier from objscan train in the per-scene figures and object "
                   "recall, as discover --model does (default: the average of the normalised "
                   "measures); the classifier protocol trains its own");
  addDiscoveryOptions(eval, eval_options.config);
  addSceneReading(eval, eval_options.reading);
  eval->add_flag("--align-truth", eval_options.reading.align_truth,
                 "Lay the fused mesh of each scene folder onto its scene_gt.ply (rigid ICP) "
                 "before the labels move onto it: a fusion's drift and its sensor's depth bias "
                 "displace the map from the truth by as much as a small object is wide "
                 "(docs/discovery.md)");
  eval->add_option("--splits", eval_options.splits, "Random train/test halvings")
      ->check(wholeNumberFrom(1))
      ->capture_default_str();
  eval->add_option("--seed", eval_options.seed, "Seed of the splits and folds")
      ->capture_default_str();
  eval->add_flag_callback(
      "--no-ablation", [&eval_options] { eval_options.ablation = false; },
      "Skip the RBF SVM without each measure");
  eval->add_flag_callback(
      "--no-classifiers", [&eval_options] { eval_options.classifiers = false; },
      "Skip the classifier protocol: object recall and per-scene figures only");
  eval->add_option("--category", eval_options.categories,
                   "NAME=REGEX: scenes whose whole file name matches REGEX (POSIX extended) form "
                   "category NAME in the "
                   "per-scene figures (the first that matches; repeatable)");

  return {eval, [options, eval] {
            options->settings = commandSettings(*eval);
            return runEval(*options);
          }};
}

Command addTrainCommand(CLI::App& app) {
  auto options = std::make_shared<TrainCommandOptions>();
  TrainCommandOptions& train_options = *options;
  CLI::App* train = app.add_subcommand(
      "train", "Fit a classifier that scores hypotheses (for objscan discover --model)");
  train->footer(
      "Examples:\n"
      "  objscan train scenes/learn*.pcd --model out/model.json   (ground truth of the scenes)\n"
      "  objscan train --catalog C --model out/model.json   (the labels given in objscan view)");
  addLabelledScenes(train, train_options.scenes, train_options.catalog);
  // Without scenes, train uses the catalog's labels (people's, from objscan view).
  train->get_option("scenes")->required(false)->description(
      "Labelled scenes: folders with scene_gt.ply and fused/mesh.ply "
      "(scripts/make_discovery_scenes), meshes whose vertices carry object_id, or PCD clouds with "
      "a label field; none: the labels given in objscan view to the segments of --catalog");
  train->get_option("--catalog")
      ->description(
          "Catalog to reuse and extend (default: none); without scenes, the catalog whose labels "
          "(given in objscan view) to train on");
  train->add_option("--model", train_options.model, "Model file to write (JSON)")->required();
  train
      ->add_option("--kind", train_options.kind,
                   "naive_bayes, linear_svm, rbf_svm or nearest_neighbour")
      ->type_name("{naive_bayes,linear_svm,rbf_svm,nearest_neighbour}")
      ->capture_default_str();
  train
      ->add_option("--min-iou", train_options.min_iou,
                   "A segment is an object at this IoU with a ground-truth object")
      ->check(CLI::Range(0.01, 1.0))
      ->capture_default_str();
  addDiscoveryOptions(train, train_options.config);
  addSceneReading(train, train_options.reading);
  train->add_option("--seed", train_options.seed, "Seed of the cross-validation folds")
      ->capture_default_str();

  return {train, [options] { return runTrain(*options); }};
}

Command addRenderCommand(CLI::App& app) {
  auto options = std::make_shared<RenderCommandOptions>();
  RenderCommandOptions& render_options = *options;
  CLI::App* render = app.add_subcommand(
      "render",
      "Render the top hypotheses of a results folder into DIR/renders/ and DIR/report.html");
  render->footer("Example:\n  objscan render out/desk --top 8 --view top --size 1920x1440");
  render
      ->add_option("dir", render_options.dir,
                   "A results folder of objscan scan (or discover): hypotheses.json, mesh.ply, "
                   "trajectory.txt")
      ->required();
  addPictureOptions(render, render_options.pictures);

  return {render, [options, render] {
            options->settings = commandSettings(*render);
            return runRender(*options);
          }};
}

namespace {

/// scan's flags that become its options only once parsed.
struct ScanFlags {
  ScanCommandOptions options;
  std::filesystem::path record;
  bool compress_color = false;
};

/// scan's subcommand and its options, bound to `state`.
CLI::App* addScanOptions(CLI::App& app, const std::shared_ptr<ScanFlags>& state) {
  ScanCommandOptions& scan_options = state->options;
  CLI::App* scan = app.add_subcommand(
      "scan", "Capture (or replay) to ranked objects in one go: fuse, discover, render, report");
  scan->footer(
      "Examples:\n"
      "  objscan scan recordings/tum_fr2_desk.oni --out out/demo\n"
      "  objscan scan --out out/live --record out/live.oni --seconds 20   (the first sensor)\n"
      "  objscan scan --config out/demo/settings.json --out out/again      (repeat a run)");
  scan->add_option("source", scan_options.source,
                   "X.oni, a TUM or 7-Scenes folder, synth:<seed>, virtual:<source>, live[:uri] or "
                   "freenect[:i]; "
                   "default: the first live sensor");
  scan->add_option("--out", scan_options.out,
                   "Folder for mesh.ply, trajectory.txt, hypotheses.json, objects/, renders/, "
                   "report.html, timings.json")
      ->required();
  auto* scan_frames = scan->add_option("--frames", scan_options.limits.max_frames,
                                       "Stop capture after this many frames")
                          ->check(wholeNumberFrom(1));
  scan->add_option("--seconds", scan_options.limits.max_seconds, "Stop capture after this long")
      ->check(positiveNumber())
      ->excludes(scan_frames);
  addFusionOptions(scan, scan_options.fuse);
  addServeOptions(scan, scan_options.serve);
  scan->add_option("--record", state->record,
                   "Save the live sensor's raw stream to this .oni while scanning (depth "
                   "lossless; replayable however capture ends)");
  scan->add_flag("--compress-color", state->compress_color,
                 "With --record: store colour as JPEG (lossy, about 10x smaller)");
  auto* scan_catalog_option =
      scan->add_option("--catalog", scan_options.discover.catalog,
                       "Catalog of scenes seen so far (default $OBJSCAN_CATALOG or "
                       "~/.local/share/objscan/catalog.sqlite)");
  scan->add_flag("--no-catalog", scan_options.discover.no_catalog, "Use no catalog")
      ->excludes(scan_catalog_option);
  scan->add_option("--model", scan_options.discover.model,
                   "Score with a classifier from objscan train (default: the average)");
  addDiscoveryOptions(scan, scan_options.discover.config);
  addObjectFormat(scan, scan_options.discover.object_format);
  addPictureOptions(scan, scan_options.pictures);
  auto* truth_option = scan->add_option(
      "--ground-truth", scan_options.ground_truth,
      "Scene mesh with per-vertex object_id (objscan synth's scene_gt.ply) to score the "
      "hypotheses against (default: X.scene_gt.ply beside X.oni, scene_gt.ply in a folder)");
  scan->add_flag("--no-ground-truth", scan_options.no_ground_truth,
                 "Do not look for ground truth beside the source")
      ->excludes(truth_option);

  return scan;
}

}  // namespace

ScanCommandOptions parseScanOptions(const std::vector<std::string>& args) {
  CLI::App parser{"objscan", "objscan"};
  auto state = std::make_shared<ScanFlags>();
  addScanOptions(parser, state);
  std::vector<std::string> argv = {"objscan", "scan"};
  argv.insert(argv.end(), args.begin(), args.end());
  std::vector<const char*> raw;
  for (const std::string& a : argv) raw.push_back(a.c_str());
  parser.parse(static_cast<int>(raw.size()), raw.data());
  return state->options;
}

Command addScanCommand(CLI::App& app) {
  auto state = std::make_shared<ScanFlags>();
  CLI::App* scan = addScanOptions(app, state);
  return {scan, [state, scan] {
            state->options.settings = commandSettings(*scan);
            if (!state->record.empty()) {
              capture::LiveRecording live_record;
              live_record.out = state->record;
              live_record.compress_color = state->compress_color;
              state->options.fuse.record = live_record;
            } else if (state->compress_color) {
              throw std::invalid_argument(
                  "--compress-color needs --record (run 'objscan scan --help')");
            }
            return runScan(state->options);
          }};
}

}  // namespace objscan::app
