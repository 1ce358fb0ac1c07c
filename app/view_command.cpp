#include "view_command.h"

#include <cstdio>
#include <cstdlib>
#include <memory>
#include <stdexcept>

#include <CLI/CLI.hpp>

#include "exit_codes.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/discovery/catalog.h"
#include "objscan/server/view_server.h"
#include "options.h"
#include "stop_signals.h"

namespace objscan::app {
namespace {

namespace fs = std::filesystem;

/// The port view listens on when --serve is not given: one a user can bookmark.
constexpr int kDefaultPort = 8090;

/// Who labels: --labeller, else $OBJSCAN_LABELLER, $USER or $LOGNAME (the first set and not
/// empty), else "unknown". Throws std::invalid_argument (exit 2) naming where a name that is not
/// one came from, without printing it (it may hold what a terminal obeys).
std::string labellerOf(const std::string& given) {
  std::string name = "unknown";
  std::string from;
  if (!given.empty()) {
    name = given;
    from = "--labeller";
  } else {
    for (const char* variable : {"OBJSCAN_LABELLER", "USER", "LOGNAME"}) {
      if (const char* v = std::getenv(variable); v && *v) {
        name = v;
        from = std::string("$") + variable;
        break;
      }
    }
  }
  if (const std::string problem = discovery::labellerNameProblem(name); !problem.empty()) {
    throw std::invalid_argument(from + ": not a labeller's name: " + problem);
  }
  return name;
}

}  // namespace

Command addViewCommand(CLI::App& app) {
  auto options = std::make_shared<ViewCommandOptions>();
  ViewCommandOptions& o = *options;
  CLI::App* view = app.add_subcommand(
      "view",
      "Show a results folder in 3-D in a browser: turn it around, click objects, label segments "
      "(object / not / unsure) into the catalog for objscan train");
  view->footer(
      "Keys in the page: y object, n not an object, u unsure, j / k next / previous, space next "
      "unlabelled, z undo.\n"
      "Example:\n  objscan view out/desk            (then open http://127.0.0.1:8090/)\n"
      "  objscan view out/desk --serve 0  (any free port)");
  view->add_option("dir", o.dir, "A results folder of objscan scan or discover (hypotheses.json)")
      ->required();
  view->add_option("--serve", o.address,
                   "Listen at [ADDR:]PORT (ADDR defaults to 127.0.0.1; PORT 0 takes any free "
                   "port; default 127.0.0.1:8090, or any free port when that is taken)");
  view->add_option("--catalog", o.catalog,
                   "Catalog the labels go to (default: the one the results were made with)");
  view->add_option("--labeller", o.labeller,
                   "Name stored with each label (default: $OBJSCAN_LABELLER, else $USER)");
  view->add_option("--serve-wait", o.wait_s, "Stop serving after this many seconds (default: at Ctrl-C)")
      ->check(CLI::NonNegativeNumber);
  view->add_option("--preview-triangles", o.max_preview_triangles,
                   "Show meshes with more triangles decimated to this many (default 1000000)")
      ->check(CLI::Range(std::size_t{1000}, std::size_t{50'000'000}));
  return {view, [options] { return runView(*options); }};
}

int runView(const ViewCommandOptions& options) {
  std::error_code ec;
  if (!fs::is_directory(options.dir, ec)) {
    throw InputError(options.dir, "is not a folder: give a results folder of objscan scan or discover");
  }
  // The address first: a bad one is a usage error before any file is read.
  std::optional<server::ServeAddress> address;
  if (options.address) address = server::parseServeAddress(*options.address);

  server::ViewSettings settings;
  settings.labeller = labellerOf(options.labeller);  // before any file is read
  settings.dir = options.dir;
  settings.catalog = options.catalog;
  settings.max_preview_triangles = options.max_preview_triangles;
  server::ViewData data(settings);
  // Ctrl-C from here on ends the viewer cleanly (exit 0), also while the meshes are read.
  StopSignals signals;

  // Listening before the meshes are read: a port in use is said at once, and the page can be
  // opened while they load (it waits for them).
  std::unique_ptr<server::ViewServer> viewer;
  if (address) {
    viewer = std::make_unique<server::ViewServer>(data, *address);
    if (address->host.rfind("127.", 0) != 0) {
      log::warning("--serve " + *options.address + ": the viewer and its labelling can be used " +
                   "by anyone who reaches this machine on that port (there is no password)");
    }
  } else {
    try {
      viewer = std::make_unique<server::ViewServer>(
          data, server::ServeAddress{"127.0.0.1", kDefaultPort});
    } catch (const std::invalid_argument&) {
      log::warning("port " + std::to_string(kDefaultPort) +
                   " is taken (another objscan view?): serving on a free one");
      viewer = std::make_unique<server::ViewServer>(data, server::ServeAddress{"127.0.0.1", 0});
    }
  }
  char how_long[64] = "until Ctrl-C";
  if (options.wait_s) std::snprintf(how_long, sizeof how_long, "for %g s", *options.wait_s);
  std::printf("viewer        %s (serving %s)\n", viewer->url().c_str(), how_long);
  std::fflush(stdout);

  data.loadScenes();
  std::size_t shown = 0, labellable = 0;
  const server::ViewScene* first_failure = nullptr;
  for (const server::ViewScene& s : data.scenes()) {
    shown += s.error.empty() ? 1 : 0;
    labellable += s.catalog_scene ? 1 : 0;
    if (!s.error.empty() && !first_failure) first_failure = &s;
  }
  if (shown == 0) {
    // Nothing to serve: one error line and exit 2, not an empty page and exit 0.
    const std::string reason = first_failure ? first_failure->error : "hypotheses.json lists none";
    throw InputError(options.dir, "no scene can be shown: " + reason +
                                      (data.scenes().size() > 1 ? " (and the others)" : ""));
  }
  for (const server::ViewScene& s : data.scenes()) {
    if (!s.error.empty()) log::warning("scene " + s.name + " cannot be shown: " + s.error);
  }
  // Scenes the catalog holds can be labelled; how many labels they have the page says.
  std::printf("scenes        %zu (%zu can be shown, %zu can be labelled), %zu hypotheses\n",
              data.scenes().size(), shown, labellable, data.hypotheses().hypotheses.size());
  if (labellable > 0) {
    std::printf("labels        into %s, as %s\n", data.catalogPath().c_str(),
                settings.labeller.c_str());
  }
  std::fflush(stdout);

  StopSignals::waitForStop(options.wait_s);
  return kExitSuccess;  // Ctrl-C is how a viewer ends
}

}  // namespace objscan::app
