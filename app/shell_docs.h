#pragma once

#include <string>

// CLI11 is included by the sources that build the command line: it takes seconds to compile
// at -O3, and most sources that include this header do not use it.
namespace CLI {
class App;
}  // namespace CLI

/// The bash completion script and the man page, both generated from the command line's own
/// definition (names, options, help text, examples), so they never disagree with --help.
namespace objscan::app {

/// A bash completion script for `objscan` (complete -F): commands, then each command's options,
/// then file names.
std::string bashCompletion(const CLI::App& app);

/// objscan(1) in roff (man -l objscan.1): synopsis, each command with its options and examples,
/// exit status, environment.
std::string manPage(const CLI::App& app, const std::string& version);

}  // namespace objscan::app
