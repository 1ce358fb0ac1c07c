#pragma once

#include <filesystem>
#include <optional>
#include <string>

#include "commands.h"

namespace objscan::app {

struct ViewCommandOptions {
  std::filesystem::path dir;
  /// --serve [ADDR:]PORT; nothing: 127.0.0.1:8090, or any free port when that one is taken.
  std::optional<std::string> address;
  std::optional<std::filesystem::path> catalog;  ///< --catalog: where labels go
  std::string labeller;                          ///< --labeller; empty: $USER
  std::optional<double> wait_s;                  ///< --serve-wait: stop after this many seconds
  std::size_t max_preview_triangles = 1'000'000;
};

/// `objscan view DIR`: serves the results folder to a browser until Ctrl-C. Returns the exit code.
int runView(const ViewCommandOptions& options);

}  // namespace objscan::app
