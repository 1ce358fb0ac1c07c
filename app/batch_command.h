#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "batch_slurm.h"

namespace objscan::app {

struct BatchCommandOptions {
  std::vector<std::string> sources;  ///< as scan takes them: recordings, folders, synth:<seed>
  std::filesystem::path list;        ///< --list FILE: one source a line (# comments)
  std::filesystem::path out;
  std::optional<unsigned> jobs;        ///< --jobs; nothing: what the machine allows
  std::vector<std::string> scan_args;  ///< after --: options for every scan
  SlurmOptions slurm;                  ///< --slurm and its options
  std::filesystem::path status;        ///< --status DIR: say where a batch stands
  std::filesystem::path finish;        ///< --finish DIR: the end of a batch (its merge job)
};

/// A recording's results folder name in a batch: a file's name without .oni, a folder's name,
/// synth_<seed>[_options] for synth:<seed>[,options]. Throws std::invalid_argument for a source
/// a batch cannot take (a live sensor) or one that gives no name.
std::string batchName(const std::string& source);

/// The sources of a --list file: one a line, blank lines and lines starting with # skipped,
/// spaces around a source trimmed. Throws InputError naming the file when it cannot be read.
std::vector<std::string> readSourceList(const std::filesystem::path& file);

/// Whether DIR holds the complete results of a scan of `source` (its settings.json names it)
/// that was not cut short: hypotheses.json, report.html and timings.json, read back by the
/// results model, with no interruption and no sensor lost. A batch run again skips those.
bool scanComplete(const std::filesystem::path& dir, const std::string& source);

/// DIR/batch.json, as a batch wrote it: its recordings (name, source) and the options after --.
struct BatchFile {
  std::vector<std::pair<std::string, std::string>> named;
  std::vector<std::string> scan_args;
};
/// Throws InputError naming DIR/batch.json when it is missing ("not the folder of a batch"),
/// damaged, or lists no recording.
BatchFile readBatchFile(const std::filesystem::path& dir);

/// The last error line of the latest run in a scan's log ("see LOG" when it has none).
std::string lastErrorLine(const std::filesystem::path& log);

/// `objscan batch`: one `objscan scan` per source into OUT/<name>/, --jobs at a time, each with
/// its own catalog (OUT/catalogs/<name>.sqlite) and log (OUT/logs/<name>.log); a line per
/// recording as it ends and a bar over all. Everything is checked before the first scan starts.
/// Returns 0 when every recording has complete results, 1 when one failed (the others are still
/// scanned), 130 when stopped by Ctrl-C / SIGTERM (passed on to the scans, which keep what they
/// wrote). With --slurm, submits the scans and the end of the batch to Slurm instead
/// (batch_slurm.h); --status and --finish act on the folder of an earlier batch.
int runBatch(const BatchCommandOptions& options);

}  // namespace objscan::app
