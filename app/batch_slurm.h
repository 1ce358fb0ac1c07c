#pragma once

#include <cstddef>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

namespace objscan::app {

/// --slurm and its options: where and how the scans of a batch run on a Slurm cluster.
struct SlurmOptions {
  bool enabled = false;
  std::string partition;                ///< --partition; empty: the cluster's default
  std::optional<unsigned> max_running;  ///< --max-running: array tasks at a time (%K)
  std::string time;                     ///< --time, as sbatch takes it; empty: the partition's
  std::string mem;                      ///< --mem per task; empty: from the memory guard's estimate
};

/// A batch checked and ready to run: its folder, its recordings (name, source), the indices of
/// those to scan, and the options after --.
struct BatchPlan {
  std::filesystem::path out;
  std::vector<std::pair<std::string, std::string>> named;
  std::vector<std::size_t> pending;
  std::vector<std::string> scan_args;
  bool no_catalog = false;
};

/// Throws std::invalid_argument when an option value cannot go into an sbatch script (a space
/// or a control character in --partition, --time, --mem; a control character in the folder's
/// or objscan's path, a backslash in the folder's).
void checkSlurmOptions(const SlurmOptions& options, const std::filesystem::path& out);
/// Throws std::invalid_argument for a source that cannot go into the task list (a tab, a line
/// break, any control character).
void checkSlurmSource(const std::string& source);
/// Throws std::runtime_error when jobs of an earlier Slurm submission into `out` (its
/// slurm/jobs.json) are still queued or running. Nothing when there was none, or when squeue
/// cannot say (a warning then).
void requireNoQueuedJobs(const std::filesystem::path& out);

/// Writes DIR/slurm/ (recordings-STAMP.txt, scan.sbatch, merge.sbatch, submit.sh) and runs
/// submit.sh: one job array of the pending recordings, and the merge (`objscan batch --finish DIR`)
/// after it (afterok, or afternotok: once either way). Prints the job ids and how to follow them;
/// records them in DIR/slurm/jobs.json. Returns the exit code. Throws std::runtime_error when
/// sbatch fails (its own message).
int submitToSlurm(const BatchPlan& plan, const SlurmOptions& options);

/// `objscan batch --status DIR`: each recording done, running, queued, failed or not started,
/// from the folders and logs, and from squeue when the batch went to Slurm; and the merge job.
int printBatchStatus(const std::filesystem::path& dir);

}  // namespace objscan::app
