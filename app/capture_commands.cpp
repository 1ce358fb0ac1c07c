// The flags of objscan's capture-side commands: info, devices, synth, record, fuse.

#include <memory>
#include <string>

#include <CLI/CLI.hpp>

#include "commands.h"
#include "fuse_command.h"
#include "info_command.h"
#include "options.h"
#include "record_command.h"
#include "synth_command.h"

namespace objscan::app {

Command addInfoCommand(CLI::App& app) {
  auto info_path = std::make_shared<std::string>();
  CLI::App* info = app.add_subcommand(
      "info",
      "Print what a mesh, point cloud, trajectory, recording, catalog, model or results folder "
      "holds");
  info->footer(
      "Examples:\n  objscan info session.oni\n  objscan info out/desk/mesh.ply\n"
      "  objscan info out/desk\n  objscan info ~/.local/share/objscan/catalog.sqlite");
  info->add_option("path", *info_path,
                   "A mesh (.ply, .obj, .stl, .glb), a PCD view, a TUM trajectory .txt, an .oni "
                   "recording, a TUM or 7-Scenes recording folder, a catalog, a model (.json) or "
                   "a results folder")
      ->required();
  return {info, [info_path] {
            runInfo(*info_path);
            return 0;
          }};
}

Command addDevicesCommand(CLI::App& app) {
  CLI::App* devices =
      app.add_subcommand("devices", "List connected OpenNI2 sensors (Asus Xtion, Kinect v1, ...)");
  return {devices, [] {
            runDevices();
            return 0;
          }};
}

Command addSynthCommand(CLI::App& app) {
  auto options = std::make_shared<SynthOptions>();
  SynthOptions& synth_options = *options;
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
  synth
      ->add_option("--noise", synth_options.noise,
                   "Depth-sensor model: on (random noise, dropouts, shadows), full (also the "
                   "device's fixed depth distortion, which fusion does not average out) or off")
      ->capture_default_str();
  synth
      ->add_option("--clutter", synth_options.clutter,
                   "plain, or hard: small objects (1.6-4.3 cm), stacks, more touching pairs, "
                   "shared and two-tone colours, a potted plant and three cables")
      ->capture_default_str();
  synth->add_option("--intrinsics", synth_options.intrinsics,
                    "intrinsics.json (fx, fy, cx, cy, width, height); default: Xtion 640x480");
  synth
      ->add_option("--views", synth_options.views,
                   "Also write this many frames, evenly spread along the path, as labelled single "
                   "views (views/*.pcd, labels as mOSD's) for objscan eval and discover")
      ->check(CLI::NonNegativeNumber)
      ->capture_default_str();

  return {synth, [options] {
            runSynth(*options);
            return 0;
          }};
}

Command addRecordCommand(CLI::App& app) {
  auto options = std::make_shared<RecordCommandOptions>();
  RecordCommandOptions& record_options = *options;
  CLI::App* record = app.add_subcommand(
      "record", "Record a sensor session to an .oni file (depth lossless); Ctrl-C stops cleanly");
  record->footer(
      "Examples:\n"
      "  objscan record --out desk.oni --seconds 30\n"
      "  objscan record --device virtual:recordings/tum_fr2_desk_10 --out desk10.oni");
  record->add_option("--out", record_options.out, "The .oni file to write")->required();
  record->add_option("--device", record_options.device,
                     "Sensor URI (objscan devices lists them); default: the first one. "
                     "freenect[:<index>] records a Kinect v1 through libfreenect; "
                     "virtual:<folder> or virtual:synth:<seed> streams a dataset or a synthetic "
                     "scene through objscan's virtual OpenNI2 sensor");
  auto* frames_option =
      record->add_option("--frames", record_options.frames, "Stop after this many frames")
          ->check(wholeNumberFrom(1));
  record->add_option("--seconds", record_options.seconds, "Stop after this many seconds")
      ->check(positiveNumber())
      ->excludes(frames_option);
  record->add_flag("--compress-color", record_options.compress_color,
                   "Store colour as JPEG (lossy, about 10x smaller); depth stays lossless");
  record->add_option("--intrinsics", record_options.intrinsics,
                     "intrinsics.json stored with the recording (X.oni.json) instead of what the "
                     "sensor reports; replay uses it");

  return {record, [options] { return runRecord(*options); }};
}

Command addFuseCommand(CLI::App& app) {
  auto options = std::make_shared<FuseCommandOptions>();
  CLI::App* fuse = app.add_subcommand(
      "fuse", "Fuse a recording into DIR/mesh.ply and DIR/trajectory.txt (TSDF + ICP tracking)");
  fuse->footer(
      "Examples:\n"
      "  objscan fuse recordings/tum_fr2_desk.oni --out out/desk\n"
      "  objscan fuse ../data/rgbd_dataset_freiburg2_desk --out out/fr2 --voxel-size 0.004 "
      "--every 2");
  fuse->add_option("source", options->fuse.source,
                   "X.oni, a TUM or 7-Scenes folder, synth:<seed>, live[:uri], freenect[:i] (a "
                   "Kinect v1 through libfreenect) or virtual:<source>")
      ->required();
  fuse->add_option("--out", options->out, "Folder for mesh.ply and trajectory.txt")->required();
  addFusionOptions(fuse, options->fuse);
  addServeOptions(fuse, options->serve);
  return {fuse, [options, fuse] {
            options->settings = commandSettings(*fuse);
            return runFuse(*options);
          }};
}

}  // namespace objscan::app
