// The catalog (SQLite): a fuzzed file opened as discovery::Catalog and queried the ways discover,
// train and view do: scenes, segments with their vertices, recurrence entries, labels and their
// history, and training's set.
#include "fuzz_input.h"
#include "objscan/discovery/catalog.h"
#include "objscan/discovery/scenes.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::filesystem::path& file = objscan::fuzz::writeInput(data, size, ".sqlite");
  // SQLite's journal of a previous input must not be taken for this one's.
  std::error_code ec;
  std::filesystem::remove(file.string() + "-journal", ec);
  return objscan::fuzz::expectingRefusals([&] {
    objscan::discovery::Catalog catalog(file);
    for (const objscan::discovery::CatalogScene& s : catalog.scenes()) {
      (void)catalog.segments(s.id, true);
      (void)catalog.labelCounts(s.id);
      (void)catalog.labelEvents(s.id);
    }
    (void)catalog.recurrenceEntries();
    (void)catalog.segmentCount();
    (void)objscan::discovery::catalogTrainingSet(file, objscan::discovery::DiscoveryConfig{});
  });
}
