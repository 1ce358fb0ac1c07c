#include "batch_command.h"

#include <fcntl.h>
#include <sched.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cctype>
#include <cerrno>
#include <chrono>
#include <csignal>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <map>
#include <memory>
#include <set>
#include <stdexcept>
#include <thread>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "commands.h"
#include "discover_command.h"
#include "exit_codes.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/clock.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"
#include "objscan/core/memory.h"
#include "objscan/core/output_folder.h"
#include "objscan/core/progress.h"
#include "objscan/discovery/catalog.h"
#include "objscan/pipeline/collection.h"
#include "objscan/pipeline/sources.h"
#include "objscan/report/results_io.h"
#include "options.h"
#include "scan_command.h"
#include "stop_signals.h"

extern char** environ;

namespace objscan::app {
namespace {

namespace fs = std::filesystem;

/// What one scan of a batch may take at most, for --jobs' default: the peak resident memory of
/// `objscan scan` on a 300-frame table top (docs/batch.md), with room to spare.
constexpr std::uint64_t kMemoryPerScan = 1536ull << 20;  // 1.5 GiB

/// Scan options a batch sets itself, or that make no sense for a recording.
const char* const kBatchOwned[] = {"--out", "--catalog", "--serve", "--serve-wait", "--record",
                                   "--config"};

std::string sanitized(std::string text) {
  for (char& c : text) {
    const unsigned char u = static_cast<unsigned char>(c);
    if (!(std::isalnum(u) || c == '-' || c == '.' || c == '_')) c = '_';
  }
  return text;
}

unsigned defaultJobs() {
  cpu_set_t set;
  const int cores = sched_getaffinity(0, sizeof set, &set) == 0
                        ? CPU_COUNT(&set)
                        : static_cast<int>(std::thread::hardware_concurrency());
  const std::uint64_t most = static_cast<std::uint64_t>(std::max(1, cores));
  const std::optional<std::uint64_t> memory = availableMemoryBytes();
  if (!memory) return static_cast<unsigned>(most);
  return static_cast<unsigned>(std::clamp<std::uint64_t>(*memory / kMemoryPerScan, 1, most));
}

/// The scan options, parsed as `objscan scan` parses them, before any scan starts.
ScanCommandOptions checkScanArgs(const std::vector<std::string>& args, const std::string& source) {
  for (const std::string& a : args) {
    for (const char* owned : kBatchOwned) {
      if (a == owned || a.rfind(std::string(owned) + "=", 0) == 0) {
        throw std::invalid_argument(std::string("after --: ") + owned +
                                    " is not a scan option a batch takes (it sets the results "
                                    "folders and catalogs itself)");
      }
    }
  }
  std::vector<std::string> argv = {"--out", "unused"};
  argv.insert(argv.end(), args.begin(), args.end());
  argv.insert(argv.end(), {"--", source});
  try {
    ScanCommandOptions scan = parseScanOptions(argv);
    // What scan checks before it opens its source: settings, pictures, the model, a given
    // ground truth.
    scan.fuse.config.validate();
    scan.pictures.validate();
    sceneDiscoveryOptions(scan.discover);
    if (!scan.ground_truth.empty()) requireGroundTruthFile(scan.ground_truth);
    return scan;
  } catch (const CLI::CallForHelp&) {
    throw std::invalid_argument("after --: run 'objscan scan --help' for the scan options");
  } catch (const CLI::ParseError& e) {
    throw std::invalid_argument(std::string("after --: ") + e.what() +
                                " (run 'objscan scan --help' for the scan options)");
  }
}

/// Opens each source as scan would (a missing, unreadable or damaged recording is an error now,
/// not after an hour of the others) and gives each a results folder name of its own.
std::vector<std::pair<std::string, std::string>> checkedSources(
    const std::vector<std::string>& sources) {
  std::vector<std::pair<std::string, std::string>> named;  // name, source
  std::map<std::string, std::string> by_name;
  for (const std::string& source : sources) {
    const std::string name = batchName(source);
    if (const auto [it, fresh] = by_name.emplace(name, source); !fresh) {
      throw std::invalid_argument(source + ": its results folder would be " + name +
                                  ", as that of " + it->second +
                                  " (rename one, or give it from another folder name)");
    }
    named.emplace_back(name, source);
  }
  ProgressBar progress("checking sources", sources.size());
  for (const std::string& source : sources) {
    if (source.rfind("synth:", 0) != 0) {
      const fs::path path(source);
      if (!fs::exists(path)) throw InputError(path, "missing");
    }
    pipeline::openFrameSource(source, {});
    progress.advance();
  }
  return named;
}

/// Starts `objscan scan` in a process group of its own (a Ctrl-C at the terminal reaches the
/// batch, which passes it on), its output appended to `log`, no input, no other open file.
pid_t spawnScan(const std::vector<std::string>& args, const fs::path& log) {
  posix_spawn_file_actions_t files;
  posix_spawn_file_actions_init(&files);
  posix_spawn_file_actions_addopen(&files, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_addopen(&files, STDOUT_FILENO, log.c_str(),
                                   O_WRONLY | O_CREAT | O_APPEND, 0644);
  posix_spawn_file_actions_adddup2(&files, STDOUT_FILENO, STDERR_FILENO);
  posix_spawn_file_actions_addclosefrom_np(&files, 3);
  posix_spawnattr_t attributes;
  posix_spawnattr_init(&attributes);
  posix_spawnattr_setflags(&attributes, POSIX_SPAWN_SETPGROUP);
  posix_spawnattr_setpgroup(&attributes, 0);
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = -1;
  // The running binary itself, even if its file was replaced since (a rebuild mid-batch).
  const int error = posix_spawn(&pid, "/proc/self/exe", &files, &attributes, argv.data(), environ);
  posix_spawn_file_actions_destroy(&files);
  posix_spawnattr_destroy(&attributes);
  if (error != 0) throw std::runtime_error(std::string("cannot start it: ") + std::strerror(error));
  return pid;
}

}  // namespace

/// The line a run's part of a log begins with.
constexpr std::string_view kLogHeader = "---- objscan batch: ";

/// The last error line of the latest run in a scan's log, for the batch's summary.
BatchFile readBatchFile(const fs::path& dir) {
  const fs::path file = dir / "batch.json";
  nlohmann::json batch;
  try {
    batch = nlohmann::json::parse(readWholeFile(file));
  } catch (const InputError&) {
    throw InputError(file, "missing or unreadable: not the folder of a batch");
  } catch (const std::exception&) {
    throw InputError(file, "damaged");
  }
  BatchFile out;
  try {
    for (const nlohmann::json& r : batch.at("recordings")) {
      out.named.emplace_back(r.at("name").get<std::string>(), r.at("source").get<std::string>());
    }
    out.scan_args = batch.at("scan_options").get<std::vector<std::string>>();
  } catch (const std::exception&) {
    throw InputError(file, "damaged: no recordings or scan options");
  }
  if (out.named.empty()) throw InputError(file, "lists no recording");
  return out;
}

std::string lastErrorLine(const fs::path& log) {
  std::ifstream in(log);
  std::string line, error;
  while (std::getline(in, line)) {
    if (line.rfind(kLogHeader, 0) == 0) error.clear();
    if (line.rfind("objscan: error: ", 0) == 0) error = line.substr(16);
  }
  return error.empty() ? "see " + log.string() : error;
}

std::string batchName(const std::string& source) {
  if (pipeline::isLiveSource(source)) {
    throw std::invalid_argument(source +
                                ": a batch scans recordings; a sensor is scanned with objscan scan");
  }
  std::string name;
  if (source.rfind("synth:", 0) == 0) {
    name = "synth_" + sanitized(source.substr(6));
  } else {
    // "." and "dir/" name the folder they are.
    std::error_code ec;
    fs::path path = fs::weakly_canonical(fs::path(source), ec);
    if (ec) path = fs::path(source).lexically_normal();
    while (!path.empty() && !path.has_filename() && path != path.root_path()) {
      path = path.parent_path();
    }
    name = sanitized(path.extension() == ".oni" ? path.stem().string() : path.filename().string());
  }
  if (name.empty() || name == "." || name == ".." || name == "catalogs" || name == "logs" ||
      name == "batch.json" || name == "collection" || name == "slurm" || name == "index.html" ||
      name.rfind("catalog.", 0) == 0) {
    throw std::invalid_argument(source + ": gives no results folder name of its own (" +
                                (name.empty() ? std::string("none") : name) + ")");
  }
  return name;
}

std::vector<std::string> readSourceList(const fs::path& file) {
  std::ifstream in(file);
  if (!fs::is_regular_file(file) || !in) {
    throw InputError(file, fs::exists(file) ? "cannot be read as a list of sources" : "missing");
  }
  std::vector<std::string> sources;
  std::string line;
  while (std::getline(in, line)) {
    const auto first = line.find_first_not_of(" \t\r");
    if (first == std::string::npos || line[first] == '#') continue;
    const auto last = line.find_last_not_of(" \t\r");
    sources.push_back(line.substr(first, last - first + 1));
  }
  return sources;
}

namespace {

/// A source as a results folder's settings.json names it, without a trailing slash.
std::string recordedForm(std::string source) {
  source = absolutePath(source);
  while (source.size() > 1 && source.back() == '/') source.pop_back();
  return source;
}

/// The source whose results DIR holds (its settings.json), or nothing.
std::optional<std::string> resultsSource(const fs::path& dir) {
  try {
    for (const report::OptionSetting& o :
         report::readSettings(dir / report::kSettingsFile).options) {
      if (o.name == "source" && o.values.size() == 1) return recordedForm(o.values[0]);
    }
  } catch (const std::exception&) {
  }
  return std::nullopt;
}

}  // namespace

bool scanComplete(const fs::path& dir, const std::string& source) {
  try {
    if (!fs::is_regular_file(dir / report::kReportFile)) return false;
    const report::Timings timings = report::readTimings(dir / report::kTimingsFile);
    if (timings.interrupted || !timings.sensor_lost.empty()) return false;
    report::readHypotheses(dir / report::kHypothesesFile);
    // Of this source, not of another that gave the same name in an earlier batch.
    return resultsSource(dir) == recordedForm(source);
  } catch (const std::exception&) {
    return false;  // missing or damaged: scanned again
  }
}

namespace {

/// The scans a batch runs, and what became of them.
class Scans {
 public:
  Scans(const BatchCommandOptions& options,
        const std::vector<std::pair<std::string, std::string>>& named, bool no_catalog)
      : options_(options), named_(named), no_catalog_(no_catalog) {}
  ~Scans() { abandon(); }
  Scans(const Scans&) = delete;
  Scans& operator=(const Scans&) = delete;

  /// Runs the scans of `pending` (indices into the named sources), `jobs` at a time. Returns
  /// false when stopped (Ctrl-C / SIGTERM).
  bool run(const std::vector<std::size_t>& pending, unsigned jobs) {
    ProgressBar progress(pending.empty() ? "" : "batch", pending.size(),  // "": no bar
                         ProgressBar::Style::kLines);
    std::size_t next = 0;
    while ((stops_ == 0 && next < pending.size()) || !running_.empty()) {
      if (StopSignals::stopRequested()) {
        // The first stop asks the scans to stop as scan does (they keep what they wrote); a
        // second one ends them.
        StopSignals::clear();
        for (const Job& job : running_) ::kill(job.pid, stops_ == 0 ? SIGINT : SIGKILL);
        ++stops_;
      }
      while (stops_ == 0 && !StopSignals::stopRequested() && next < pending.size() &&
             running_.size() < jobs) {
        start(pending[next++]);
      }
      if (!reap()) std::this_thread::sleep_for(std::chrono::milliseconds(50));
      progress.advance(ended_ - progress.done());
    }
    progress.finish();
    return stops_ == 0;
  }

  std::size_t done() const { return done_; }
  std::size_t failed() const { return failed_; }

 private:
  struct Job {
    pid_t pid = -1;
    std::size_t index = 0;
    SteadyClock::time_point start;
  };

  fs::path logOf(const std::string& name) const { return options_.out / "logs" / (name + ".log"); }

  void start(std::size_t index) {
    const auto& [name, source] = named_[index];
    std::vector<std::string> args = {"objscan", "scan", "--out", (options_.out / name).string()};
    if (!no_catalog_) {
      args.insert(args.end(),
                  {"--catalog", (options_.out / "catalogs" / (name + ".sqlite")).string()});
    }
    args.insert(args.end(), options_.scan_args.begin(), options_.scan_args.end());
    args.insert(args.end(), {"--", source});  // a source that starts with '-' is still one
    // The scan's catalog holds that scan alone: an earlier attempt's scene goes with it.
    for (const char* suffix : {"", "-journal", "-wal", "-shm"}) {
      std::error_code ec;
      fs::remove(options_.out / "catalogs" / (name + ".sqlite" + suffix), ec);
    }
    const fs::path log = logOf(name);
    {
      std::ofstream header(log, std::ios::app);
      header << kLogHeader << std::time(nullptr) << " (seconds since 1970):";
      for (const std::string& a : args) header << ' ' << a;
      header << '\n';
    }
    log::info("started       " + name);
    try {
      running_.push_back({spawnScan(args, log), index, SteadyClock::now()});
    } catch (const std::exception& e) {
      ended(index, 0.0, std::string("not started: ") + e.what());
    }
  }

  /// Collects every scan that ended; false when none had.
  bool reap() {
    bool any = false;
    for (auto it = running_.begin(); it != running_.end();) {
      int status = 0;
      const pid_t pid = ::waitpid(it->pid, &status, WNOHANG);
      if (pid == 0 || (pid < 0 && errno == EINTR)) {
        ++it;
        continue;
      }
      any = true;
      const double seconds = secondsSince(it->start);
      const std::size_t index = it->index;
      it = running_.erase(it);
      if (pid < 0) {
        ended(index, seconds, std::string("lost track of it: ") + std::strerror(errno));
      } else if (WIFEXITED(status) && WEXITSTATUS(status) == kExitSuccess) {
        std::printf("done          %s in %.1f s\n", named_[index].first.c_str(), seconds);
        std::fflush(stdout);
        ++done_;
        ++ended_;
      } else if (stops_ > 0) {
        std::printf("stopped       %s after %.1f s (%s)\n", named_[index].first.c_str(), seconds,
                    exitText(status).c_str());
        std::fflush(stdout);
        ++ended_;
      } else {
        ended(index, seconds, exitText(status) + ": " + lastErrorLine(logOf(named_[index].first)));
      }
    }
    return any;
  }

  /// A scan that failed: said on stderr, so that it shows with --quiet too.
  void ended(std::size_t index, double seconds, const std::string& why) {
    char after[32];
    std::snprintf(after, sizeof after, "%.1f", seconds);
    log::error(named_[index].first + " (" + named_[index].second + ") failed after " + after +
               " s, " + why);
    ++failed_;
    ++ended_;
  }

  /// On an exception: the scans still running are ended, so none outlives the batch.
  void abandon() noexcept {
    for (const Job& job : running_) ::kill(job.pid, SIGKILL);
    for (const Job& job : running_) ::waitpid(job.pid, nullptr, 0);
    running_.clear();
  }

  static std::string exitText(int status) {
    if (WIFEXITED(status)) return "exit " + std::to_string(WEXITSTATUS(status));
    if (WIFSIGNALED(status)) return std::string("killed by signal ") + strsignal(WTERMSIG(status));
    return "ended";
  }

  const BatchCommandOptions& options_;
  const std::vector<std::pair<std::string, std::string>>& named_;
  bool no_catalog_;
  std::vector<Job> running_;
  std::size_t done_ = 0, failed_ = 0, ended_ = 0;
  int stops_ = 0;
};

/// DIR/catalog.sqlite made again from the catalogs of the recordings whose results are complete
/// (`complete`: their names; under a temporary name, then renamed into place): the collection's
/// catalog, which only this writes. Returns its scene and segment counts.
std::pair<std::size_t, std::size_t> writeCollectionCatalog(
    const fs::path& out, const std::vector<std::string>& complete) {
  const fs::path temp = out / "catalog.sqlite.partial";
  for (const char* suffix : {"", "-journal", "-wal", "-shm"}) {
    fs::remove(temp.string() + suffix);  // what an interrupted batch left
  }
  std::pair<std::size_t, std::size_t> counts;
  {
    // One shard open at a time (a collection of thousands would run out of file descriptors).
    std::vector<fs::path> shards;
    std::set<std::pair<std::string, std::string>> current;  // (content hash, settings)
    for (const std::string& name : complete) {
      const fs::path shard = out / "catalogs" / (name + ".sqlite");
      if (!fs::is_regular_file(shard)) continue;
      for (const discovery::CatalogScene& s : discovery::Catalog(shard).scenes()) {
        current.emplace(s.content_hash, s.settings);
      }
      shards.push_back(shard);
    }
    discovery::Catalog collection(temp);
    // First the earlier collection's scenes that are still current, with the labels people gave
    // their segments in objscan view (the shards never have those); then the rest.
    const fs::path earlier = out / "catalog.sqlite";
    if (fs::exists(earlier)) {
      try {
        const discovery::Catalog before(earlier);
        discovery::mergeCatalog(collection, before, [&](const discovery::CatalogScene& s) {
          return current.count({s.content_hash, s.settings}) > 0;
        });
      } catch (const std::exception& e) {
        log::warning(std::string("the earlier collection catalog is not read, its labels are not "
                                 "carried over (it is kept as catalog.previous.sqlite): ") +
                     e.what());
      }
    }
    for (const fs::path& shard : shards) discovery::mergeCatalog(collection, discovery::Catalog(shard));
    counts = {collection.scenes().size(), collection.segmentCount()};
  }
  // The earlier catalog is kept beside it, with every label and its history, until the next
  // batch: the labels of a recording that is not complete this time are not in the new one.
  // A second name for it first, then the new one renamed over it: at no moment is there no
  // catalog.sqlite.
  std::error_code ec;
  if (fs::exists(out / "catalog.sqlite")) {
    fs::remove(out / "catalog.previous.sqlite", ec);
    fs::create_hard_link(out / "catalog.sqlite", out / "catalog.previous.sqlite", ec);
    if (ec) fs::copy_file(out / "catalog.sqlite", out / "catalog.previous.sqlite", ec);
    if (ec) {
      throw OutputError(out / "catalog.sqlite", "cannot keep it as catalog.previous.sqlite: " +
                                                    ec.message());
    }
  }
  fs::rename(temp, out / "catalog.sqlite", ec);
  if (ec)
    throw OutputError(out / "catalog.sqlite",
                      "cannot put the merged catalog in place: " + ec.message());
  return counts;
}

/// Every complete scene ranked again with the others, as `objscan discover` ranks several
/// scenes: recurrence across the whole collection (a scene scanned first saw no others), the
/// scans' discovery options, the collection's catalog (whose measures spare measuring again).
/// Into DIR/collection/.
void rankTheCollection(const fs::path& out, const std::vector<std::string>& complete,
                       DiscoverCommandOptions discover, bool no_catalog) {
  discover.meshes.clear();
  for (const std::string& name : complete)
    discover.meshes.push_back(out / name / report::kMeshFile);
  if (discover.meshes.empty()) return;
  discover.out = out / "collection";
  if (!no_catalog) discover.catalog = out / "catalog.sqlite";
  discover.settings.command = "batch";
  std::printf("collection    %zu scenes ranked together -> %s\n", discover.meshes.size(),
              discover.out.c_str());
  std::fflush(stdout);
  runDiscover(discover);
}

/// The end of a batch, after its scans (run here, or as Slurm's merge job): the collection's
/// catalog merged from the complete recordings' catalogs, the collection ranked together, and
/// index.html. Prints each; returns how many recordings lack complete results.
std::size_t endBatch(const fs::path& out, const std::vector<std::pair<std::string, std::string>>& named,
                     const ScanCommandOptions& scan_options) {
  const bool no_catalog = scan_options.discover.no_catalog;
  std::vector<std::string> complete;
  for (const auto& [name, source] : named) {
    if (scanComplete(out / name, source)) complete.push_back(name);
  }
  if (complete.empty()) {
    std::printf("collection    no recording has complete results: the collection is left as it "
                "was\n");
    return named.size();
  }
  if (!no_catalog) {
    const auto [scenes, segments] = writeCollectionCatalog(out, complete);
    std::printf("catalog       %s: %zu scenes, %zu segments (merged from %s)\n",
                (out / "catalog.sqlite").c_str(), scenes, segments, (out / "catalogs").c_str());
  }
  rankTheCollection(out, complete, scan_options.discover, no_catalog);
  std::vector<pipeline::CollectionRecording> recordings;
  for (const auto& [name, source] : named) recordings.push_back({name, source});
  const pipeline::CollectionPageOutcome page = pipeline::writeCollectionPage(out, recordings);
  std::printf("page          %s: %zu scenes, %zu objects across scenes, %zu pictures%s in %.1f s\n",
              page.page.c_str(), page.scenes, page.groups, page.pictures,
              page.pictures_failed > 0
                  ? (" (" + std::to_string(page.pictures_failed) + " failed)").c_str()
                  : "",
              page.seconds);
  return named.size() - complete.size();
}

/// `objscan batch --finish DIR`: the end of the batch DIR/batch.json describes (Slurm's merge
/// job runs it once the scans have ended). Every recording without complete results is an error
/// line; exit 1 then.
int finishBatch(const fs::path& out) {
  const auto [named, scan_args] = readBatchFile(out);
  const ScanCommandOptions scan_options = checkScanArgs(scan_args, named.front().second);
  const OutputFolderLock lock = prepareOutputFolder(out);
  for (const auto& [name, source] : named) {
    if (!scanComplete(out / name, source)) {
      log::error(name + " (" + source + "): no complete results: " +
                 lastErrorLine(out / "logs" / (name + ".log")));
    }
  }
  const std::size_t missing = endBatch(out, named, scan_options);
  std::printf("batch         %zu of %zu recordings complete\n", named.size() - missing,
              named.size());
  return missing == 0 ? kExitSuccess : kExitRuntimeFailure;
}

}  // namespace

int runBatch(const BatchCommandOptions& options) {
  // Ended child processes are collected by pid: not if SIGCHLD were ignored (that survives
  // exec), for the scans here as for sbatch and squeue.
  std::signal(SIGCHLD, SIG_DFL);
  const bool slurm_options = options.slurm.enabled || !options.slurm.partition.empty() ||
                             options.slurm.max_running || !options.slurm.time.empty() ||
                             !options.slurm.mem.empty();
  if (!options.status.empty() || !options.finish.empty()) {
    if (!options.status.empty() && !options.finish.empty()) {
      throw std::invalid_argument("--status and --finish: one at a time");
    }
    if (!options.sources.empty() || !options.list.empty() || !options.out.empty() ||
        slurm_options || options.jobs || !options.scan_args.empty()) {
      throw std::invalid_argument(
          std::string(options.status.empty() ? "--finish" : "--status") +
          " takes the batch's folder alone (its recordings and options are in its batch.json)");
    }
    return options.status.empty() ? finishBatch(options.finish) : printBatchStatus(options.status);
  }
  if (options.out.empty()) throw std::invalid_argument("--out is required");
  std::vector<std::string> sources = options.sources;
  if (!options.list.empty()) {
    const std::vector<std::string> listed = readSourceList(options.list);
    sources.insert(sources.end(), listed.begin(), listed.end());
  }
  if (sources.empty()) {
    throw std::invalid_argument("no sources: give recordings, folders or synth:<seed>, or --list");
  }
  if (!options.slurm.enabled && slurm_options) {
    throw std::invalid_argument("--partition, --max-running, --time and --mem go with --slurm");
  }
  if (options.slurm.enabled) {
    if (options.jobs) {
      throw std::invalid_argument("--jobs is for a batch on this machine; on Slurm, --max-running");
    }
    checkSlurmOptions(options.slurm, options.out);
  }
  const ScanCommandOptions scan_options = checkScanArgs(options.scan_args, sources.front());
  const bool no_catalog = scan_options.discover.no_catalog;
  std::vector<std::pair<std::string, std::string>> named = checkedSources(sources);
  // Sources as absolute paths: the batch's scripts, --status and --finish may run elsewhere.
  for (auto& [name, source] : named) source = recordedForm(source);
  if (options.slurm.enabled) {
    for (const auto& [name, source] : named) checkSlurmSource(source);
  }

  // A folder holding another source's results is not scanned over: they would be lost.
  for (const auto& [name, source] : named) {
    const std::optional<std::string> there = resultsSource(options.out / name);
    if (there && *there != recordedForm(source)) {
      throw InputError(options.out / name, "holds the results of " + *there + ", not of " + source +
                                               " (remove it, or give another --out)");
    }
  }
  try {
    const nlohmann::json earlier = nlohmann::json::parse(readWholeFile(options.out / "batch.json"));
    if (earlier.at("scan_options") != nlohmann::json(options.scan_args)) {
      log::warning(
          "the options after -- differ from the last batch into this folder: its complete "
          "results were made with those and are kept (remove DIR/<name> to scan one again)");
    }
  } catch (const std::exception&) {
    // no earlier batch here, or its batch.json is damaged: nothing to compare
  }

  std::optional<OutputFolderLock> lock = prepareOutputFolder(options.out);
  // Nothing of an earlier Slurm submission into DIR may still run: two scans of one recording
  // would write one folder.
  requireNoQueuedJobs(options.out);
  fs::create_directories(options.out / "logs");
  if (!no_catalog) fs::create_directories(options.out / "catalogs");
  nlohmann::json batch = {{"format", "objscan batch, version 1"},
                          {"scan_options", options.scan_args},
                          {"recordings", nlohmann::json::array()}};
  for (const auto& [name, source] : named) {
    batch["recordings"].push_back({{"name", name}, {"source", source}});
  }
  writeFileAtomically(options.out / "batch.json", batch.dump(2) + "\n");

  std::vector<std::size_t> pending;
  std::size_t skipped = 0;
  for (std::size_t i = 0; i < named.size(); ++i) {
    if (scanComplete(options.out / named[i].first, named[i].second)) {
      std::printf("complete      %s (an earlier run's results: skipped)\n", named[i].first.c_str());
      ++skipped;
    } else {
      pending.push_back(i);
    }
  }
  if (options.slurm.enabled) {
    // The scans and the merge are Slurm's now: the folder is not this process's to hold.
    lock.reset();
    return submitToSlurm({options.out, named, pending, options.scan_args, no_catalog},
                         options.slurm);
  }
  const unsigned jobs = std::max(1u, options.jobs.value_or(defaultJobs()));
  std::printf("batch         %zu recordings, %zu to scan, %u at a time -> %s\n", named.size(),
              pending.size(), jobs, options.out.c_str());
  std::fflush(stdout);

  StopSignals signals;
  const auto start = SteadyClock::now();
  Scans scans(options, named, no_catalog);
  const bool finished = scans.run(pending, jobs);
  std::printf("batch         %zu scanned, %zu failed, %zu complete before, in %.1f s; logs in %s\n",
              scans.done(), scans.failed(), skipped, secondsSince(start),
              (options.out / "logs").c_str());
  if (!finished) {
    std::printf("stopped by    Ctrl-C / SIGTERM: run the same batch again to scan the rest\n");
    return kExitInterrupted;
  }
  endBatch(options.out, named, scan_options);
  return scans.failed() == 0 ? kExitSuccess : kExitRuntimeFailure;
}

Command addBatchCommand(CLI::App& app, std::shared_ptr<const std::vector<std::string>> scan_args) {
  auto options = std::make_shared<BatchCommandOptions>();
  CLI::App* batch = app.add_subcommand(
      "batch", "Scan many recordings: one scan each into OUT/<name>/, several at a time");
  batch->footer(
      "Options after -- go to every scan (objscan scan's, but --out, --catalog, --serve, "
      "--record and --config).\n"
      "Examples:\n"
      "  objscan batch recordings/*.oni --out out/all\n"
      "  objscan batch --list scans.txt --out out/all --jobs 2 -- --frames 300 --top 8\n"
      "  objscan batch --list scans.txt --out /shared/all --slurm --max-running 20\n"
      "  objscan batch --status /shared/all\n"
      "Run it again after a failure or Ctrl-C: complete results are kept, the rest is scanned.");
  batch->add_option("sources", options->sources,
                    "Recordings (X.oni), TUM or 7-Scenes folders, synth:<seed>");
  batch->add_option("--list", options->list,
                    "A file of sources, one a line (blank lines and # comments skipped)");
  batch->add_option("--out", options->out,
                    "Folder for the results: OUT/<name>/ a recording, OUT/logs/, OUT/catalogs/, "
                    "OUT/batch.json, OUT/index.html");
  batch->add_option("--jobs", options->jobs,
                    "Scans at a time (default: the cores, fewer when memory is short)")
      ->check(wholeNumberFrom(1));
  batch->add_flag("--slurm", options->slurm.enabled,
                  "Submit to Slurm: one job array of the scans, then the merge (OUT/slurm/)");
  batch->add_option("--partition", options->slurm.partition, "With --slurm: the partition");
  batch->add_option("--max-running", options->slurm.max_running,
                    "With --slurm: scans at a time (the array's %K)")
      ->check(wholeNumberFrom(1));
  batch->add_option("--time", options->slurm.time,
                    "With --slurm: each job's time limit, as sbatch takes it (e.g. 2:00:00)");
  batch->add_option("--mem", options->slurm.mem,
                    "With --slurm: memory per job, as sbatch takes it (default 1536M)");
  batch->add_option("--status", options->status,
                    "Say where the batch in this folder stands: done, running, queued, failed");
  batch->add_option("--finish", options->finish,
                    "The end of the batch in this folder: merge, rank, index.html (Slurm's merge "
                    "job runs it)");
  return {batch, [options, scan_args] {
            options->scan_args = *scan_args;
            return runBatch(*options);
          }};
}

}  // namespace objscan::app
