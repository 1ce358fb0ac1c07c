#pragma once

#include <filesystem>

#include "objscan/report/results.h"

namespace objscan::report {

/// Writes DIR/report.html from the results of a scan (or discover + render) into DIR and returns
/// its path. The page is made from the values, not from the files: nothing is read back. It is
/// self-contained (opened from disk, no network): CSS and a small script inline, every picture
/// embedded as a `data:image/png;base64,` URI. It holds, each part only when the results have it:
/// a title with the source and the date of DIR/hypotheses.json; a summary and stage timings (with
/// a notice when the scan was interrupted); the overview and the contact sheet; the ranked table
/// of hypotheses (at most 50 rows) with their close-ups and links to objects/; and, with an
/// evaluation, a precision-recall curve and each hypothesis's ground-truth match.
///
/// The page's script sets `data-images="<loaded>/<total>"` and `data-errors="<count>"` on <body>
/// once loaded, so a headless browser can check that every picture decoded.
///
/// Throws InputError naming DIR/hypotheses.json when the results hold no hypotheses; OutputError
/// when report.html cannot be written (written atomically: a failure leaves any earlier report as
/// it was).
///
/// It also embeds the scene in 3-D (mesh_view.h: three.js and the mesh inline, decimated to at
/// most 100,000 triangles) and names `objscan view DIR`. `scene_mesh` is the mesh hypotheses.json's
/// first scene was cut from, when the caller has it in memory; results.mesh when null; without
/// either the page has no 3-D view.
std::filesystem::path writeReport(const ScanResults& results, const std::filesystem::path& dir,
                                  const TriangleMesh* scene_mesh = nullptr);

}  // namespace objscan::report
