#include "batch_slurm.h"

#include <fcntl.h>
#include <poll.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>
#include <map>
#include <set>
#include <sstream>
#include <stdexcept>
#include <string>
#include <system_error>

#include <nlohmann/json.hpp>

#include "batch_command.h"
#include "exit_codes.h"
#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/log.h"

extern char** environ;

namespace objscan::app {
namespace {

namespace fs = std::filesystem;

/// Memory asked per task when --mem is not given: the memory guard's allowance per scan.
constexpr const char* kDefaultMemory = "1536M";
/// Memory asked for the merge when --mem is not given: it reads every scene's mesh at once and
/// renders the collection page.
constexpr const char* kMergeMemory = "4G";
/// CPUs per task: one scan keeps about 1.6 cores busy (docs/batch.md).
constexpr int kCpusPerTask = 2;

/// `text` as one word for bash: in single quotes, each ' written '\''.
std::string shellWord(const std::string& text) {
  std::string out = "'";
  for (const char c : text) {
    if (c == '\'') {
      out += "'\\''";
    } else {
      out += c;
    }
  }
  return out + "'";
}

struct ToolResult {
  int status = -1;  ///< the exit status; -1 when it did not end normally
  std::string out, err;
};

/// Runs a program found on PATH with no input, and returns its exit status and what it printed.
ToolResult runTool(const std::vector<std::string>& args) {
  int out_pipe[2], err_pipe[2];
  if (pipe2(out_pipe, O_CLOEXEC) != 0) throw std::system_error(errno, std::generic_category());
  if (pipe2(err_pipe, O_CLOEXEC) != 0) {
    ::close(out_pipe[0]);
    ::close(out_pipe[1]);
    throw std::system_error(errno, std::generic_category());
  }
  posix_spawn_file_actions_t files;
  posix_spawn_file_actions_init(&files);
  posix_spawn_file_actions_addopen(&files, STDIN_FILENO, "/dev/null", O_RDONLY, 0);
  posix_spawn_file_actions_adddup2(&files, out_pipe[1], STDOUT_FILENO);
  posix_spawn_file_actions_adddup2(&files, err_pipe[1], STDERR_FILENO);
  std::vector<char*> argv;
  for (const std::string& a : args) argv.push_back(const_cast<char*>(a.c_str()));
  argv.push_back(nullptr);
  pid_t pid = -1;
  const int error = posix_spawnp(&pid, argv[0], &files, nullptr, argv.data(), environ);
  posix_spawn_file_actions_destroy(&files);
  ::close(out_pipe[1]);
  ::close(err_pipe[1]);
  ToolResult result;
  if (error == 0) {
    pollfd fds[2] = {{out_pipe[0], POLLIN, 0}, {err_pipe[0], POLLIN, 0}};
    std::string* into[2] = {&result.out, &result.err};
    int open = 2;
    while (open > 0) {
      if (::poll(fds, 2, -1) < 0) {
        if (errno == EINTR) continue;
        break;
      }
      for (int i = 0; i < 2; ++i) {
        if (fds[i].fd < 0 || fds[i].revents == 0) continue;
        char buffer[4096];
        const ssize_t n = ::read(fds[i].fd, buffer, sizeof buffer);
        if (n > 0) {
          into[i]->append(buffer, static_cast<std::size_t>(n));
        } else if (n == 0 || errno != EINTR) {
          fds[i].fd = -1;
          --open;
        }
      }
    }
    int status = 0;
    pid_t waited = -1;
    while ((waited = ::waitpid(pid, &status, 0)) < 0 && errno == EINTR) {
    }
    result.status = waited == pid && WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  }
  ::close(out_pipe[0]);
  ::close(err_pipe[0]);
  if (error != 0) {
    throw std::runtime_error(args[0] + " cannot be run: " + std::strerror(error) +
                             (error == ENOENT ? " (is Slurm's client installed, and on PATH?)" : ""));
  }
  return result;
}

/// The last non-empty line of `text`.
std::string lastLine(const std::string& text) {
  std::string line, last;
  std::istringstream in(text);
  while (std::getline(in, line)) {
    if (line.find_first_not_of(" \t\r") != std::string::npos) last = line;
  }
  return last;
}

/// The #SBATCH lines every job of the batch shares (the output file goes on sbatch's command
/// line, quoted: the folder's path may hold spaces).
std::string sbatchOptions(const SlurmOptions& options, const std::string& name,
                          const std::string& memory) {
  std::string s = "#SBATCH --job-name=" + name + "\n";
  if (!options.partition.empty()) s += "#SBATCH --partition=" + options.partition + "\n";
  if (!options.time.empty()) s += "#SBATCH --time=" + options.time + "\n";
  s += "#SBATCH --mem=" + memory + "\n";
  return s;
}

bool hasControl(const std::string& text) {
  for (const char c : text) {
    if (static_cast<unsigned char>(c) < 0x20 || c == 0x7f) return true;
  }
  return false;
}

/// An #SBATCH value objscan writes into a script: one word of printable characters.
void checkSbatchValue(const std::string& flag, const std::string& value) {
  if (hasControl(value) || value.find(' ') != std::string::npos) {
    throw std::invalid_argument(flag + " takes one word without spaces or control characters");
  }
}

/// A path in sbatch's --output: '%' starts a pattern there, "%%" is a '%'.
std::string outputPattern(const fs::path& folder, const std::string& file) {
  std::string out;
  for (const char c : folder.string()) {
    out += c;
    if (c == '%') out += '%';
  }
  return out + "/" + file;
}

/// Job ids in DIR/slurm/jobs.json.
nlohmann::json readJobs(const fs::path& dir) {
  try {
    nlohmann::json j = nlohmann::json::parse(readWholeFile(dir / "slurm" / "jobs.json"));
    // The shape the readers rely on; anything else is as good as no file.
    j.at("array").get<std::string>();
    j.at("merge").get<std::vector<std::string>>();
    j.at("recordings").get<std::vector<std::string>>();
    return j;
  } catch (const std::exception&) {
    return nullptr;
  }
}

/// The running objscan binary's path, which the scripts run.
fs::path objscanBinary() {
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (ec) throw std::runtime_error("cannot find the objscan binary: " + ec.message());
  return exe;
}

/// squeue's lines (`-o FORMAT`, array tasks one a line) for the jobs of DIR's jobs.json (the
/// array and the merge jobs) still queued or running; none when squeue cannot be asked (its
/// message in `error`).
std::vector<std::string> queueLines(const nlohmann::json& jobs, const char* format,
                                    std::string* error) {
  std::string ids = jobs.at("array").get<std::string>();
  for (const nlohmann::json& m : jobs.at("merge")) {
    ids += ',';
    ids += m.get<std::string>();
  }
  std::vector<std::string> lines;
  try {
    const ToolResult r = runTool({"squeue", "-h", "-r", "-o", format, "-j", ids});
    // Jobs Slurm has forgotten (past MinJobAge): squeue says so for a single id.
    if (r.status != 0 && r.err.find("Invalid job id") != std::string::npos) return lines;
    if (r.status != 0) {
      *error = "squeue failed: " + lastLine(r.err);
      return lines;
    }
    std::istringstream in(r.out);
    std::string line;
    while (std::getline(in, line)) {
      if (!line.empty()) lines.push_back(line);
    }
  } catch (const std::exception& e) {
    *error = e.what();
  }
  return lines;
}

}  // namespace

void checkSlurmOptions(const SlurmOptions& options, const fs::path& out) {
  checkSbatchValue("--partition", options.partition);
  checkSbatchValue("--time", options.time);
  checkSbatchValue("--mem", options.mem);
  const std::string folder = fs::absolute(out).string();
  if (hasControl(folder) || hasControl(objscanBinary().string())) {
    throw std::invalid_argument(
        "--slurm: the folder's path, or objscan's, holds a control character, which cannot go "
        "into an sbatch script");
  }
  if (folder.find('\\') != std::string::npos) {
    throw std::invalid_argument(
        "--slurm: the folder's path holds a backslash, which sbatch's "
        "--output reads as 'do not expand'");
  }
}

void checkSlurmSource(const std::string& source) {
  if (hasControl(source)) {
    throw std::invalid_argument(source +
                                ": a source with a control character (a tab, a line break) "
                                "cannot go into the Slurm task list");
  }
}

void requireNoQueuedJobs(const fs::path& out) {
  const nlohmann::json jobs = readJobs(out);
  if (!jobs.is_object()) return;
  std::string error;
  const std::vector<std::string> queued = queueLines(jobs, "%i", &error);
  if (!error.empty()) {
    log::warning("cannot ask Slurm whether the jobs of the earlier submission into this folder "
                 "have ended (" + error + ")");
  }
  if (!queued.empty()) {
    std::string list;
    for (const std::string& id : queued) {
      if (!list.empty()) list += ", ";
      list += id;
    }
    throw std::runtime_error(out.string() + ": jobs of an earlier Slurm submission into it are "
                             "still queued or running (" + list +
                             "): wait for them (objscan batch --status), or scancel them");
  }
}

int submitToSlurm(const BatchPlan& plan, const SlurmOptions& options) {
  const fs::path out = fs::absolute(plan.out).lexically_normal();
  if (plan.pending.empty()) {
    std::printf("slurm         nothing to submit: every recording has complete results\n");
    return kExitSuccess;
  }
  const fs::path slurm = out / "slurm";
  fs::create_directories(slurm / "logs");
  const fs::path exe = objscanBinary();
  const std::string memory = options.mem.empty() ? std::string(kDefaultMemory) : options.mem;
  const std::string merge_memory = options.mem.empty() ? std::string(kMergeMemory) : options.mem;

  // The recordings of this submission, one a line: array task i scans line i + 1.
  std::string list;
  for (const std::size_t i : plan.pending) list += plan.named[i].first + "\t" + plan.named[i].second + "\n";
  // A list of its own for each submission: a task still queued from an earlier one (submit.sh
  // run again by hand) reads its own.
  const std::string list_name = "recordings-" + std::to_string(std::time(nullptr)) + "-" +
                                std::to_string(::getpid()) + ".txt";
  writeFileAtomically(slurm / list_name, list);

  std::string scan_args;
  for (const std::string& a : plan.scan_args) scan_args += " " + shellWord(a);
  const std::string dir = shellWord(out.string());
  std::string scan =
      "#!/bin/bash\n"
      "# objscan batch --slurm: array task i scans line i + 1 of the list given as $1 (name, tab,\n"
      "# source) into DIR/<name>/,\n"
      "# with its own catalog DIR/catalogs/<name>.sqlite, its output appended to\n"
      "# DIR/logs/<name>.log. Submitted by submit.sh beside it.\n" +
      sbatchOptions(options, "objscan-scan", memory) +
      "#SBATCH --cpus-per-task=" + std::to_string(kCpusPerTask) +
      "\nset -u\n"
      "dir=" +
      dir + "\n" +
      "line=$(sed -n \"$((SLURM_ARRAY_TASK_ID + 1))p\" \"$1\")\n"
      "name=${line%%$'\\t'*}\n"
      "source=${line#*$'\\t'}\n"
      "[[ -n $name && $name != \"$line\" ]] || { echo \"no recording $SLURM_ARRAY_TASK_ID\" >&2; "
      "exit 2; }\n"
      "log=\"$dir/logs/$name.log\"\n";
  if (!plan.no_catalog) {
    scan +=
        "# The scan's catalog holds that scan alone: an earlier attempt's scene goes with it.\n"
        "catalog=\"$dir/catalogs/$name.sqlite\"\n"
        "rm -f \"$catalog\" \"$catalog-journal\" \"$catalog-wal\" \"$catalog-shm\"\n";
  }
  scan +=
      "echo \"---- objscan batch: Slurm job ${SLURM_ARRAY_JOB_ID}_${SLURM_ARRAY_TASK_ID} on "
      "$(hostname) at $(date +%s) (seconds since 1970): scan $source\" >> \"$log\"\n"
      "exec " +
      shellWord(exe.string()) + " scan --out \"$dir/$name\"" +
      (plan.no_catalog ? std::string() : std::string(" --catalog \"$catalog\"")) + scan_args +
      " -- \"$source\" < /dev/null >> \"$log\" 2>&1\n";
  writeFileAtomically(slurm / "scan.sbatch", scan);

  const std::string merge =
      "#!/bin/bash\n"
      "# objscan batch --slurm: after the scans, merges their catalogs, ranks the collection and\n"
      "# writes index.html (objscan batch --finish). Submitted by submit.sh beside it.\n" +
      sbatchOptions(options, "objscan-merge", merge_memory) +
      "exec " + shellWord(exe.string()) + " batch --finish " + dir + " < /dev/null\n";
  writeFileAtomically(slurm / "merge.sbatch", merge);

  const std::size_t n = plan.pending.size();
  std::string array = "0-" + std::to_string(n - 1);
  if (options.max_running) array += "%" + std::to_string(*options.max_running);
  const std::string submit =
      "#!/bin/bash\n"
      "# What objscan batch --slurm ran to submit this batch: the scans as one job array, then "
      "the\n"
      "# merge once they have all ended, whichever way (afterok, or afternotok; the other of the\n"
      "# two is dropped by Slurm). Prints the three job ids. Run it again to submit it again.\n"
      "set -euo pipefail\n"
      "dir=" +
      dir + "\n" + "array=$(sbatch --parsable --array=" + array +
      " --output=" + shellWord(outputPattern(slurm / "logs", "scan-%A_%a.out")) +
      " \"$dir/slurm/scan.sbatch\" \"$dir/slurm/" + list_name +
      "\")\n"
      "array=${array%%;*}\n"
      "echo \"$array\"\n"
      "for after in afterok afternotok; do\n"
      "  sbatch --parsable --dependency=$after:$array --kill-on-invalid-dep=yes --output=" +
      shellWord(outputPattern(slurm / "logs", "merge-%j.out")) +
      " \"$dir/slurm/merge.sbatch\"\n"
      "done\n";
  writeFileAtomically(slurm / "submit.sh", submit);
  std::error_code perms_error;  // not executable: `bash submit.sh` still runs it
  fs::permissions(slurm / "submit.sh", fs::perms::owner_exec | fs::perms::group_exec,
                  fs::perm_options::add, perms_error);

  nlohmann::json pending_names = nlohmann::json::array();
  for (const std::size_t i : plan.pending) pending_names.push_back(plan.named[i].first);
  const ToolResult r = runTool({"bash", (slurm / "submit.sh").string()});
  std::vector<std::string> ids;
  {
    std::istringstream in(r.out);
    std::string line;
    while (std::getline(in, line)) {
      if (!line.empty()) ids.push_back(line.substr(0, line.find(';')));
    }
  }
  if (r.status != 0 || ids.size() != 3) {
    const std::string why = lastLine(r.err);
    std::string submitted;
    for (const std::string& id : ids) {
      if (!submitted.empty()) submitted += ", ";
      submitted += id;
    }
    if (!ids.empty()) {
      writeFileAtomically(
          slurm / "jobs.json",
          nlohmann::json({{"array", ids[0]},
                          {"merge", std::vector<std::string>(ids.begin() + 1, ids.end())},
                          {"recordings", pending_names}})
                  .dump(2) +
              "\n");
    }
    throw std::runtime_error("sbatch failed" + (why.empty() ? std::string() : ": " + why) +
                             (ids.empty() ? std::string()
                                          : " (submitted before it: job " + submitted +
                                                "; scancel them, then submit again)"));
  }
  nlohmann::json jobs = {{"array", ids[0]},
                         {"merge", {ids[1], ids[2]}},
                         {"submitted", static_cast<std::int64_t>(std::time(nullptr))},
                         {"recordings", nlohmann::json::array()}};
  jobs["recordings"] = pending_names;
  writeFileAtomically(slurm / "jobs.json", jobs.dump(2) + "\n");
  std::printf("slurm         job array %s: %zu recordings%s; merge job %s (or %s if a scan fails)\n",
              ids[0].c_str(), n,
              options.max_running
                  ? (", " + std::to_string(*options.max_running) + " at a time").c_str()
                  : "",
              ids[1].c_str(), ids[2].c_str());
  std::printf("follow        objscan batch --status %s\n", plan.out.c_str());
  return kExitSuccess;
}

int printBatchStatus(const fs::path& dir) {
  const std::vector<std::pair<std::string, std::string>> named = readBatchFile(dir).named;

  // From Slurm: the array tasks queued or running, by recording, and the merge job's state.
  std::map<std::string, std::string> queue;  // name -> RUNNING, PENDING, ...
  std::string merge_state, slurm_note;
  const nlohmann::json jobs = readJobs(dir);
  if (jobs.is_object()) {
    const auto submitted = jobs.at("recordings").get<std::vector<std::string>>();
    const std::string array = jobs.at("array").get<std::string>();
    for (const std::string& line : queueLines(jobs, "%i|%T", &slurm_note)) {
      const std::size_t bar = line.find('|');
      if (bar == std::string::npos) continue;
      const std::string id = line.substr(0, bar), state = line.substr(bar + 1);
      if (id.rfind(array + "_", 0) == 0) {
        try {
          const std::size_t task = std::stoul(id.substr(array.size() + 1));
          if (task < submitted.size()) queue[submitted[task]] = state;
        } catch (const std::exception&) {
        }
      } else {
        merge_state = state;
      }
    }
  }

  std::size_t done = 0, running = 0, queued = 0, failed = 0, unstarted = 0, unknown = 0;
  for (const auto& [name, source] : named) {
    std::string state, detail;
    const fs::path log = dir / "logs" / (name + ".log");
    if (const auto q = queue.find(name); q != queue.end()) {
      state = q->second == "PENDING" ? "queued" : "running";
      (state == "queued" ? queued : running) += 1;
      if (q->second != "PENDING" && q->second != "RUNNING") detail = q->second;
    } else if (scanComplete(dir / name, source)) {
      state = "done";
      ++done;
    } else if (!slurm_note.empty()) {
      state = "unknown";  // perhaps queued or running: Slurm could not be asked
      ++unknown;
    } else if (fs::exists(log)) {
      state = "failed";
      detail = lastErrorLine(log);
      ++failed;
    } else {
      state = "not started";
      ++unstarted;
    }
    std::printf("%-13s %s%s%s\n", state.c_str(), name.c_str(), detail.empty() ? "" : ": ",
                detail.c_str());
  }
  std::printf("batch         %zu done, %zu running, %zu queued, %zu failed, %zu not started\n", done,
              running, queued, failed, unstarted);
  if (unknown > 0) std::printf("unknown       %zu (not complete; Slurm could not say)\n", unknown);
  if (jobs.is_object()) {
    std::printf("merge         %s\n",
                !slurm_note.empty()  ? "unknown"
                : !merge_state.empty() ? merge_state.c_str()
                : fs::exists(dir / "index.html")
                    ? "ended (index.html written)"
                    : "not in the queue, and no index.html (cancelled, or failed: see slurm/logs/)");
  }
  if (!slurm_note.empty()) {
    log::error("cannot ask Slurm where the batch's jobs stand: " + slurm_note);
    return kExitRuntimeFailure;
  }
  return kExitSuccess;
}

}  // namespace objscan::app
