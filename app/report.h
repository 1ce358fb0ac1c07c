#pragma once

#include <filesystem>

namespace objscan::app {

/// Writes DIR/report.html from the files a scan left in DIR and returns its path. The page is
/// self-contained (opened from disk, no network): CSS and a small script inline, every picture
/// embedded as a `data:image/png;base64,` URI. It holds, each part only when its input exists:
/// a title with the source and the date of hypotheses.json; a summary and stage timings
/// (timings.json, with a notice when the scan was interrupted); renders/overview.png and
/// renders/contact_sheet.png; the ranked table of hypotheses.json (at most 50 rows) with the
/// close-ups renders/rank_NNN.png; and, with evaluation.json, a precision-recall curve and each
/// hypothesis's ground-truth match.
///
/// The page's script sets `data-images="<loaded>/<total>"` and `data-errors="<count>"` on <body>
/// once loaded, so a headless browser can check that every picture decoded.
///
/// Throws InputError naming DIR/hypotheses.json when it is missing or is not JSON of the expected
/// shape, naming another input file when it is present but unreadable, corrupt or of the wrong
/// shape (a .json that does not parse, a .png that is not a PNG); OutputError when report.html
/// cannot be written (written atomically: a failure leaves any earlier report as it was).
std::filesystem::path writeReport(const std::filesystem::path& dir);

}  // namespace objscan::app
