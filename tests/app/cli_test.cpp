// Runs the real objscan binary and checks what users see: exit codes, one error line, output.

#include <gtest/gtest.h>

#include <filesystem>
#include <regex>
#include <set>
#include <string>

#include "cli_expect.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/ply_io.h"
#include "test_support.h"

namespace objscan {
namespace {

namespace fs = std::filesystem;
using testing::expectOneErrorLine;
using testing::ProcessResult;
using testing::TempDir;
using testing::writeBytes;

using testing::objscan;

/// Bad input: exit code 2, nothing on stdout, exactly one line on stderr naming the path.
void expectOneLineError(const ProcessResult& r, const std::string& path,
                        const std::string& needle) {
  EXPECT_EQ(r.exit_code, 2) << r.err;
  EXPECT_EQ(r.out, "");
  const auto ls = testing::lines(r.err);
  ASSERT_EQ(ls.size(), 1u) << r.err;
  EXPECT_EQ(ls[0].rfind("objscan: error: " + path + ": ", 0), 0u) << ls[0];
  EXPECT_NE(ls[0].find(needle), std::string::npos) << ls[0];
}

/// The source files of a folder of the source tree (.cpp and .h), by name.
std::vector<fs::path> sourcesIn(const std::string& folder) {
  std::vector<fs::path> out;
  for (const auto& e : fs::recursive_directory_iterator(fs::path(OBJSCAN_SOURCE_DIR) / folder)) {
    const std::string ext = e.path().extension().string();
    if (e.is_regular_file() && (ext == ".cpp" || ext == ".h")) out.push_back(e.path());
  }
  return out;
}

TEST(Architecture, TheCodeKeepsWhatDocsArchitectureSays) {
  // civetweb is included by the server module's HTTP layer only (http_server, http_query), not
  // by its routes, and by nothing else.
  std::set<std::string> civetweb;
  for (const char* folder : {"core", "render", "capture", "fusion", "discovery", "report",
                             "pipeline", "server", "app"}) {
    for (const fs::path& f : sourcesIn(folder)) {
      if (readWholeFile(f).find("#include <civetweb.h>") != std::string::npos) {
        civetweb.insert(fs::relative(f, OBJSCAN_SOURCE_DIR).string());
      }
    }
  }
  EXPECT_EQ(civetweb,
            (std::set<std::string>{"server/src/http_query.cpp", "server/src/http_server.cpp"}));
  const std::string page = readWholeFile(fs::path(OBJSCAN_SOURCE_DIR) / "docs/architecture.md");
  EXPECT_NE(page.find("civetweb is included by these two .cpp files only"), std::string::npos);
  // The library prints only through core's log and progress bar; app prints and exits.
  const std::regex prints(
      R"((^|[^A-Za-z_0-9:])(std::)?(printf|fprintf|puts|fputs|exit)\s*\(|std::(cout|cerr)\b)");
  for (const char* module :
       {"core", "render", "capture", "fusion", "discovery", "report", "pipeline", "server"}) {
    for (const fs::path& f : sourcesIn(std::string(module) + "/src")) {
      if (f.filename() == "log.cpp" || f.filename() == "progress.cpp") continue;
      EXPECT_FALSE(std::regex_search(readWholeFile(f), prints)) << f;
    }
  }
  // app includes every module itself, as the diagram says.
  std::string app;
  for (const fs::path& f : sourcesIn("app")) app += readWholeFile(f);
  for (const char* module :
       {"core", "render", "capture", "fusion", "discovery", "report", "pipeline", "server"}) {
    EXPECT_NE(app.find(std::string("#include \"objscan/") + module + "/"), std::string::npos)
        << module;
  }
  EXPECT_NE(page.find("includes every module below itself"), std::string::npos);
}

TEST(Docs, NameFeaturesNotInternalMilestones) {
  // "Step H" means nothing to a reader; the docs name the feature instead.
  const std::regex step(R"(\bStep [A-Z]\b)");
  std::vector<fs::path> pages = {fs::path(OBJSCAN_SOURCE_DIR) / "README.md"};
  for (const auto& e : fs::directory_iterator(fs::path(OBJSCAN_SOURCE_DIR) / "docs")) {
    if (e.path().extension() == ".md") pages.push_back(e.path());
  }
  for (const fs::path& page : pages) {
    const std::string text = readWholeFile(page);
    std::smatch m;
    EXPECT_FALSE(std::regex_search(text, m, step)) << page << ": " << m.str();
  }
}

TEST(Cli, HelpForEveryCommandExitsZero) {
  for (const char* cmd : {"info", "devices", "record", "fuse", "discover", "render", "scan",
                          "synth", "eval", "train"}) {
    const ProcessResult r = objscan({cmd, "--help"});
    EXPECT_EQ(r.exit_code, 0) << cmd;
    EXPECT_NE(r.out.find("Usage: objscan " + std::string(cmd)), std::string::npos) << r.out;
  }
  const ProcessResult top = objscan({"--help"});
  EXPECT_EQ(top.exit_code, 0);
  EXPECT_NE(top.out.find("Exit codes: 0 success, 1 runtime failure, 2 bad usage or bad input, 3 no "
                         "sensor attached,\n130 interrupted"),
            std::string::npos)
      << top.out;
}

TEST(Cli, StartsWithoutTheLibrariesThatMadeEveryStartSlow) {
  // The dynamic loader's own list of what a start maps (LD_TRACE_LOADED_OBJECTS, as ldd asks).
  // OSMesa (with LLVM) is loaded by the first renderer, and OpenCV's imgcodecs (with GDAL and
  // a hundred more) is not used: together they took 0.18 s of every start.
  testing::ProcessOptions options;
  options.env = {"LD_TRACE_LOADED_OBJECTS=1"};
  const ProcessResult r = testing::runProcess({OBJSCAN_EXE}, options);
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("libspng"), std::string::npos) << r.out;  // the list is a real one
  for (const char* heavy : {"libOSMesa", "libLLVM", "libopencv_imgcodecs", "libgdal"}) {
    EXPECT_EQ(r.out.find(heavy), std::string::npos) << heavy << " in\n" << r.out;
  }
}

TEST(Cli, CompletionAndManPageComeFromTheOptionsThemselves) {
  // Issue 18: shell completion and a man page, generated from the same help text.
  TempDir dir;
  const ProcessResult completion = objscan({"--completion", "bash"});
  ASSERT_EQ(completion.exit_code, 0) << completion.err;
  testing::writeBytes(dir / "objscan.bash", completion.out);
  // Bash itself completes with it: a command from its start, a command's option from its start.
  const ProcessResult words = testing::runProcess(
      {"/bin/bash", "-c",
       "source " + (dir / "objscan.bash").string() +
           "; COMP_WORDS=(objscan fu); COMP_CWORD=1; _objscan; echo \"${COMPREPLY[*]}\";"
           " COMP_WORDS=(objscan discover --object-f); COMP_CWORD=2; _objscan;"
           " echo \"${COMPREPLY[*]}\""},
      {});
  ASSERT_EQ(words.exit_code, 0) << words.err;
  EXPECT_EQ(words.out, "fuse\n--object-format\n");
  // An option of a few values completes to them, not to file names; a <source> also to the
  // sources that are not files. In an empty folder, so that no file name joins in.
  fs::create_directories(dir / "empty");
  testing::ProcessOptions in_empty;
  in_empty.cwd = dir / "empty";
  const auto complete = [&](const std::string& words_line, int cword) {
    const ProcessResult r = testing::runProcess(
        {"/bin/bash", "-c",
         "source " + (dir / "objscan.bash").string() + "; COMP_WORDS=(" + words_line +
             "); COMP_CWORD=" + std::to_string(cword) + "; _objscan; echo \"${COMPREPLY[*]}\""},
        in_empty);
    EXPECT_EQ(r.exit_code, 0) << r.err;
    return r.out;
  };
  EXPECT_EQ(complete("objscan discover --object-format ''", 3), "ply obj stl glb\n");
  EXPECT_EQ(complete("objscan scan x --object-format g", 4), "glb\n");
  EXPECT_EQ(complete("objscan render out --view t", 4), "trajectory three-quarter top\n");
  EXPECT_EQ(complete("objscan train --kind r", 3), "rbf_svm\n");
  EXPECT_EQ(complete("objscan scan ''", 2), "synth: live freenect virtual:\n");
  EXPECT_EQ(complete("objscan fuse v", 2), "virtual:\n");
  EXPECT_EQ(complete("objscan discover ''", 2), "\n");  // meshes: files only

  const ProcessResult man = objscan({"--man"});
  ASSERT_EQ(man.exit_code, 0) << man.err;
  testing::writeBytes(dir / "objscan.1", man.out);
  // groff formats it without a warning; every command and its examples are there.
  const ProcessResult page = testing::runProcess(
      {"/usr/bin/groff", "-man", "-Tascii", "-ww", "-P-cbou", (dir / "objscan.1").string()}, {});
  ASSERT_EQ(page.exit_code, 0) << page.err;
  EXPECT_EQ(page.err, "");
  for (const char* text :
       {"NAME", "COMMANDS", "EXIT STATUS", "ENVIRONMENT", "OBJSCAN_MEMORY_LIMIT",
        "OBJSCAN_CATALOG", "OBJSCAN_LABELLER", "OBJSCAN_VIRTUAL_SENSOR", "XDG_DATA_HOME", "TMPDIR",
        "fuse", "discover",
        "--object-format", "objscan scan recordings/tum_fr2_desk.oni"}) {
    EXPECT_NE(page.out.find(text), std::string::npos) << text;
  }
  EXPECT_EQ(objscan({"--completion", "tcsh"}).exit_code, 2);
}

TEST(Cli, ConfigMessagesSayWhatIsWrongWithTheFileGiven) {
  // Issue 32: a folder was "not readable (missing?)", /proc/self/mem printed libstdc++'s
  // "basic_filebuf::underflow" with no file name, and render --config blamed the file.
  TempDir dir;
  expectOneErrorLine(objscan({"scan", "synth:1", "--out", (dir / "o").string(), "--config",
                              dir.path().string()}),
                     2, dir.path().string() + " is a folder: give the settings.json in it");
  expectOneErrorLine(
      objscan({"scan", "synth:1", "--out", (dir / "o").string(), "--config", "/proc/self/mem"}), 2,
      "/proc/self/mem: cannot determine the file size");
  writeBytes(dir / "settings.json", "{}");
  expectOneErrorLine(objscan({"render", (dir / "o").string(), "--config",
                              (dir / "settings.json").string()}),
                     2, "objscan render takes no --config");
  EXPECT_FALSE(fs::exists(dir / "o"));
}

TEST(Cli, UsageErrorsPointToTheCommandsOwnHelpAndSayWhatIsWanted) {
  // Issue 18's paper cuts and defect 8, one by one.
  TempDir dir;
  const ProcessResult help = objscan({"help", "fuse"});
  EXPECT_EQ(help.exit_code, 0) << help.err;
  EXPECT_NE(help.out.find("Usage: objscan fuse [OPTIONS] source"), std::string::npos) << help.out;
  EXPECT_NE(help.out.find("Examples:"), std::string::npos) << help.out;
  expectOneErrorLine(objscan({"help", "fusion"}), 2, "help: no command 'fusion'");
  expectOneErrorLine(objscan({"fuse"}), 2, "source is required (run 'objscan fuse --help')");
  const std::string out = (dir / "out").string();
  expectOneErrorLine(objscan({"fuse", "synth:1", "--out", out, "--start", "-1"}), 2,
                     "--start: must be a whole number of at least 0 (got '-1')");
  expectOneErrorLine(objscan({"fuse", "synth:1", "--out", out, "--start", "99999999999999999999"}),
                     2, "--start: must be a whole number of at least 0");
  expectOneErrorLine(objscan({"scan", "synth:1", "--out", out, "--seconds", "-3"}), 2,
                     "--seconds: must be a number above 0 (got '-3')");
  // A symbolic link loop is bad input named in one line, not the library's text and exit 1.
  fs::create_symlink(dir / "b", dir / "a");
  fs::create_symlink(dir / "a", dir / "b");
  for (const char* command : {"discover", "info"}) {
    std::vector<std::string> args = {command, (dir / "a").string()};
    if (std::string(command) == "discover") args.insert(args.end(), {"--out", out});
    const ProcessResult r = objscan(args);
    expectOneErrorLine(r, 2, (dir / "a").string() + ": cannot access: Too many levels of symbolic "
                             "links");
    EXPECT_EQ(r.err.find("filesystem error"), std::string::npos) << r.err;
  }
  EXPECT_FALSE(fs::exists(out));
}

TEST(Cli, SynthWritesARecordingThatInfoReads) {
  TempDir dir;
  const std::string out = (dir / "scene").string();
  ProcessResult r = objscan({"synth", "--out", out, "--frames", "4", "--objects", "6", "--seed",
                             "9", "--preset", "counter"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("scene         counter, 6 objects, seed 9, noise on"), std::string::npos)
      << r.out;
  // --quiet: errors only, on either stream (issue 18: the stdout summary stayed).
  r = objscan({"--quiet", "synth", "--out", (dir / "quiet").string(), "--frames", "4", "--objects",
               "6", "--seed", "9", "--preset", "counter"});
  ASSERT_EQ(r.exit_code, 0) << r.err;
  EXPECT_EQ(r.err, "");
  EXPECT_EQ(r.out, "");
  r = objscan({"info", out});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("frames        4 (paired by associations.txt)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("fx 570.3 fy 570.3 cx 319.5 cy 239.5, 640x480 px (intrinsics.json)"),
            std::string::npos)
      << r.out;
  r = objscan({"info", out + "/scene_gt.ply"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("objects       6 object ids"), std::string::npos) << r.out;
}

TEST(Cli, SynthBadOptionsExitTwoWithOneLine) {
  TempDir dir;
  const std::string out = (dir / "s").string();
  for (const std::vector<std::string>& args :
       {std::vector<std::string>{"synth"},
        {"synth", "--out", out, "--preset", "garage"},
        {"synth", "--out", out, "--noise", "maybe"},
        {"synth", "--out", out, "--objects", "0"},
        {"synth", "--out", out, "--frames", "-3"},
        {"synth", "--out", out, "--object-dir", (dir / "missing").string()},
        {"synth", "--out", out, "--intrinsics", (dir / "missing.json").string()}}) {
    const ProcessResult r = objscan(args);
    EXPECT_EQ(r.exit_code, 2) << args.back() << ": " << r.err;
    EXPECT_EQ(testing::lines(r.err).size(), 1u) << r.err;
    EXPECT_FALSE(std::filesystem::exists(out)) << "nothing written for bad options";
  }
  std::filesystem::create_directories(dir / "full");
  writeBytes(dir / "full" / "keep.txt", "precious");
  const ProcessResult r = objscan({"synth", "--out", (dir / "full").string(), "--frames", "2"});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_NE(r.err.find("already exists and is not an empty folder"), std::string::npos) << r.err;
  EXPECT_EQ(testing::readBytes(dir / "full" / "keep.txt"), "precious");
}

TEST(Cli, BadUsageExitsTwoWithOneLine) {
  for (const std::vector<std::string>& args : {std::vector<std::string>{},
                                               {"frobnicate"},
                                               {"info"},
                                               {"info", "--bogus", "x"},
                                               {"-q", "-v", "info", "x"}}) {
    const ProcessResult r = objscan(args);
    EXPECT_EQ(r.exit_code, 2) << r.err;
    EXPECT_EQ(testing::lines(r.err).size(), 1u) << r.err;
  }
}

TEST(Cli, InfoOnMeshPrintsCountsBoundsAndFormat) {
  TempDir dir;
  TriangleMesh cube = testing::makeCube(0.5f);
  cube.normals.assign(8, Eigen::Vector3f::UnitZ());
  cube.labels = {0, 0, 3, 3, 0, 7, 7, 7};
  cube.weights = {1.0f, 2.0f, 3.5f, 3.5f, 64.0f, 128.0f, 1.0f, 2.0f};
  cube.ignore = {0, 1, 1, 0, 0, 0, 0, 1};
  writePly(dir / "cube.ply", cube);
  const ProcessResult r = objscan({"info", (dir / "cube.ply").string()});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("mesh (PLY binary_little_endian"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("vertices      8 (normals: yes, colours: no)"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("faces         12 triangles"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("objects       2 object ids on 5 vertices (object_id;"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("weights       1 .. 128 (quality"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("not scored    3 vertices"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("extent        0.5000 x 0.5000 x 0.5000 m"), std::string::npos) << r.out;
  EXPECT_NE(r.out.find("area          1.5000 m^2"), std::string::npos) << r.out;
}

TEST(Cli, InfoOnShippedRecordingAndTrajectory) {
  const std::string rec = std::string(OBJSCAN_SOURCE_DIR) + "/recordings/tum_fr2_desk_10";
  ProcessResult r = objscan({"info", rec});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("frames        10 (paired by associations.txt)"), std::string::npos)
      << r.out;
  EXPECT_NE(r.out.find("all 10 frames decoded, 10 with colour"), std::string::npos) << r.out;
  // stderr is a pipe here, so the progress bar prints plain lines, never carriage returns.
  EXPECT_NE(r.err.find("reading frames: 100% (10/10) in "), std::string::npos) << r.err;
  EXPECT_EQ(r.err.find('\r'), std::string::npos);

  r = objscan({"--quiet", "info", rec});
  EXPECT_EQ(r.exit_code, 0);
  EXPECT_EQ(r.err, "") << "--quiet silences progress";

  r = objscan({"info", rec + "/groundtruth.txt"});
  EXPECT_EQ(r.exit_code, 0) << r.err;
  EXPECT_NE(r.out.find("poses         10"), std::string::npos) << r.out;
}

TEST(Cli, InfoOnRecordingWithBadImageGivesOneErrorLineAndNoReport) {
  TempDir dir;
  const std::filesystem::path shipped =
      std::filesystem::path(OBJSCAN_SOURCE_DIR) / "recordings" / "tum_fr2_desk_10";
  std::filesystem::copy(shipped, dir / "rec", std::filesystem::copy_options::recursive);
  // Cut the 6th depth image in half: five frames decode, then the error.
  const std::string sixth = testing::lines(testing::readBytes(dir / "rec" / "associations.txt"))[5];
  const std::string depth_rel = sixth.substr(sixth.rfind(' ') + 1);
  const auto depth = dir / "rec" / depth_rel;
  writeBytes(depth, testing::readBytes(depth).substr(0, 5000));

  const ProcessResult r = objscan({"info", (dir / "rec").string()});
  EXPECT_EQ(r.exit_code, 2);
  EXPECT_EQ(r.out, "") << "no half report on stdout";
  EXPECT_EQ(r.err.find("libpng"), std::string::npos) << r.err;
  const auto ls = testing::lines(r.err);
  ASSERT_FALSE(ls.empty());
  // Progress lines may come first; the error is the last line and the only one of its kind.
  EXPECT_EQ(ls.back(), "objscan: error: " + depth.string() +
                           ": the PNG file is truncated (it has no IEND end chunk)");
  std::size_t errors = 0;
  for (const auto& l : ls) errors += l.rfind("objscan: error: ", 0) == 0 ? 1 : 0;
  EXPECT_EQ(errors, 1u);
  EXPECT_EQ(r.err.find(" in 0."), std::string::npos) << "no completion line for a failed stage";
}

TEST(Cli, UnwritableStandardOutputIsARuntimeFailure) {
  const std::string cmd = std::string(OBJSCAN_EXE) + " info '" + OBJSCAN_SOURCE_DIR +
                          "/recordings/tum_fr2_desk_10/groundtruth.txt' > /dev/full";
  const ProcessResult r = testing::runProcess({"/bin/sh", "-c", cmd});
  EXPECT_EQ(r.exit_code, 1);
  EXPECT_EQ(r.err, "objscan: error: cannot write to standard output\n");
}

TEST(Cli, InfoOnBadInputGivesOneLineAndExitTwo) {
  TempDir dir;
  const TriangleMesh mesh = testing::makeRandomMesh(2, 10, 8);
  writePly(dir / "good.ply", mesh);
  const std::string good = testing::readBytes(dir / "good.ply");

  expectOneLineError(objscan({"info", (dir / "absent.ply").string()}),
                     (dir / "absent.ply").string(), "no such file");
  expectOneLineError(objscan({"info", dir.path().string()}), dir.path().string(), "is a directory");
  writeBytes(dir / "empty.ply", "");
  expectOneLineError(objscan({"info", (dir / "empty.ply").string()}), (dir / "empty.ply").string(),
                     "empty");
  for (const std::size_t cut :
       {std::size_t{3}, std::size_t{150}, good.size() / 2, good.size() - 1}) {
    writeBytes(dir / "cut.ply", good.substr(0, cut));
    expectOneLineError(objscan({"info", (dir / "cut.ply").string()}), (dir / "cut.ply").string(),
                       "");
  }
  const std::string header =
      "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float "
      "z\n"
      "element face 1\nproperty list uchar int vertex_indices\nend_header\n";
  writeBytes(dir / "oor.ply", header + "0 0 0\n1 0 0\n0 1 0\n3 0 1 7\n");
  expectOneLineError(objscan({"info", (dir / "oor.ply").string()}), (dir / "oor.ply").string(),
                     "refers to vertex 7");
  writeBytes(dir / "nan.ply", header + "0 0 0\nnan 0 0\n0 1 0\n3 0 1 2\n");
  expectOneLineError(objscan({"info", (dir / "nan.ply").string()}), (dir / "nan.ply").string(),
                     "non-finite position");
  writeBytes(dir / "scene.fbx", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  expectOneLineError(objscan({"info", (dir / "scene.fbx").string()}), (dir / "scene.fbx").string(),
                     "unknown format");
  // The object formats objscan writes are described, and a damaged one is said to be.
  writeBytes(dir / "scene.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
  const ProcessResult obj = objscan({"info", (dir / "scene.obj").string()});
  EXPECT_EQ(obj.exit_code, 0) << obj.err;
  EXPECT_NE(obj.out.find("vertices      3 (normals: no, colours: no)\nfaces         1 triangle\n"),
            std::string::npos)
      << obj.out;
  writeBytes(dir / "noise.glb", std::string(100, 'x'));
  expectOneLineError(objscan({"info", (dir / "noise.glb").string()}), (dir / "noise.glb").string(),
                     "no 'glTF' magic");
  writeBytes(dir / "cut.stl", std::string(84, '\0').replace(80, 1, "\x05"));
  expectOneLineError(objscan({"info", (dir / "cut.stl").string()}), (dir / "cut.stl").string(),
                     "header says 5 triangles");
  writeBytes(dir / "noise.ply", std::string("\x89PNG\r\n\x1a\n", 8) + std::string(100, 'x'));
  expectOneLineError(objscan({"info", (dir / "noise.ply").string()}), (dir / "noise.ply").string(),
                     "not a PLY file");
  writeBytes(dir / "zero.ply",
             "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n"
             "property float z\nend_header\n");
  expectOneLineError(objscan({"info", (dir / "zero.ply").string()}), (dir / "zero.ply").string(),
                     "empty mesh");
}

}  // namespace
}  // namespace objscan
