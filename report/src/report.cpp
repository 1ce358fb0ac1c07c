#include "objscan/report/report.h"

#include "objscan/report/mesh_view.h"

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <ctime>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <system_error>
#include <utility>
#include <vector>

#include "objscan/core/atomic_file.h"
#include "objscan/core/error.h"
#include "objscan/core/palette.h"
#include "objscan/discovery/shape_measures.h"
#include "objscan/report/results_io.h"
#include "html.h"

namespace objscan::report {
namespace {

namespace fs = std::filesystem;
using html::base64;
using html::escape;
using html::fixed;
using html::kScript;
using html::kStyle;
using html::urlPath;

/// The ranked table shows at most this many rows; the rest are counted below it.
constexpr std::size_t kMaxRows = 50;

// ---------------------------------------------------------------------------------------------
// What the page shows, from the results model: unknown values as std::nullopt

struct HypothesisRow {
  std::int64_t rank = 0;
  std::optional<double> score;
  std::optional<double> object_score;  ///< in the object set's order; none for an alternative
  std::optional<std::string> footing;  ///< how it stands (discovery::Footing's name)
  std::array<std::optional<double>, discovery::kMeasureCount> measures;  ///< kMeasureNames order
  std::optional<std::int64_t> vertex_count;
  std::optional<std::array<double, 3>> extents_m;
  std::optional<std::string> file;   ///< relative to the results folder
  std::optional<std::string> scene;  ///< the scene mesh it was cut from
};

struct SceneInfo {
  std::optional<std::string> mesh;
  std::optional<std::int64_t> vertices;
  std::optional<std::int64_t> faces;
};

struct HypothesesView {
  std::vector<HypothesisRow> rows;  ///< by rank
  std::vector<SceneInfo> scenes;
  std::optional<std::string> scoring;
};

struct Stage {
  std::string name;
  double seconds = 0.0;
};

struct TimingsView {
  std::optional<std::string> source;
  bool interrupted = false;
  std::vector<std::string> not_produced;
  std::vector<Stage> stages;
  std::optional<double> total_s;
  std::optional<std::int64_t> frames_read, frames_fused, frames_lost;
  std::optional<std::int64_t> mesh_vertices, mesh_faces;
  std::optional<std::int64_t> hypotheses;
};

struct CurvePoint {
  double recall = 0.0;
  double precision = 0.0;
};

struct Match {
  std::optional<std::int64_t> object_id;
  std::optional<std::string> object;
  std::optional<double> iou;
  std::optional<bool> found;  ///< this rank found the object (not a better rank before it)
};

struct EvaluationView {
  std::optional<std::string> ground_truth;
  std::optional<std::int64_t> objects, found;
  std::optional<double> min_iou, ap;
  std::vector<CurvePoint> curve;
  std::map<std::int64_t, Match> by_rank;
};

using Png = Picture;

std::optional<std::int64_t> known(const std::optional<std::size_t>& v) {
  if (!v) return std::nullopt;
  return static_cast<std::int64_t>(*v);
}

std::optional<double> finite(double v) {
  if (!std::isfinite(v)) return std::nullopt;
  return v;
}

std::optional<std::string> nonEmpty(const std::string& s) {
  if (s.empty()) return std::nullopt;
  return s;
}

HypothesesView viewOf(const Hypotheses& h) {
  HypothesesView out;
  for (const HypothesisRecord& r : h.hypotheses) {
    HypothesisRow row;
    row.rank = static_cast<std::int64_t>(r.rank);
    row.score = r.score;
    row.object_score = r.objectScoreIfObject();
    row.footing = nonEmpty(r.footing);
    const auto values = discovery::measureValues(r.measures);
    for (std::size_t k = 0; k < values.size(); ++k) row.measures[k] = finite(values[k]);
    row.vertex_count = known(r.vertex_count);
    if (r.box) {
      row.extents_m =
          std::array<double, 3>{r.box->extents.x(), r.box->extents.y(), r.box->extents.z()};
    }
    row.file = nonEmpty(r.file);
    row.scene = nonEmpty(r.scene);
    out.rows.push_back(std::move(row));
  }
  for (const SceneRecord& s : h.scenes) {
    out.scenes.push_back({nonEmpty(s.mesh), known(s.vertices), known(s.faces)});
  }
  if (h.scoring) out.scoring = nonEmpty(h.scoring->kind);
  return out;
}

TimingsView viewOf(const Timings& t) {
  TimingsView out;
  out.source = nonEmpty(t.source);
  out.interrupted = t.interrupted;
  out.not_produced = t.not_produced;
  for (const StageTime& s : t.stages) out.stages.push_back({s.name, s.seconds});
  out.total_s = t.total_s;
  if (t.frames) {
    out.frames_read = known(t.frames->read);
    out.frames_fused = known(t.frames->fused);
    out.frames_lost = known(t.frames->lost);
  }
  out.mesh_vertices = known(t.mesh_vertices);
  out.mesh_faces = known(t.mesh_faces);
  out.hypotheses = known(t.hypotheses);
  return out;
}

EvaluationView viewOf(const Evaluation& e) {
  EvaluationView out;
  out.ground_truth = nonEmpty(e.ground_truth);
  out.objects = known(e.objects);
  out.found = known(e.found);
  out.min_iou = finite(e.min_iou);
  out.ap = finite(e.ap);
  for (const EvaluatedRank& r : e.ranks) {
    if (std::isfinite(r.recall) && std::isfinite(r.precision)) {
      out.curve.push_back({r.recall, r.precision});
    }
    out.by_rank[static_cast<std::int64_t>(r.rank)] = {r.object_id, nonEmpty(r.object),
                                                      finite(r.iou), r.found};
  }
  return out;
}

// ---------------------------------------------------------------------------------------------
// Writing HTML





/// Three significant digits: the measures span orders of magnitude (global convexity is often
/// below 0.001, where a fixed two decimals would show 0.00).
std::string measureText(double v) {
  char text[32];
  std::snprintf(text, sizeof text, "%.3g", v);
  return text;
}

std::string integerText(std::int64_t v) { return std::to_string(v); }

constexpr std::string_view kUnknown = "\u2013";  // en dash: unknown or not applicable

std::string orUnknown(const std::optional<double>& v, int decimals) {
  return v ? fixed(*v, decimals) : std::string(kUnknown);
}

std::string joined(const std::vector<std::string>& parts, std::string_view separator) {
  std::string out;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    if (i > 0) out += separator;
    out += parts[i];
  }
  return out;
}

/// "<label> 50 read, 49 fused" with the known counts; "" when none is known.
std::string countsText(
    const std::string& label,
    const std::vector<std::pair<std::optional<std::int64_t>, const char*>>& counts) {
  std::vector<std::string> parts;
  for (const auto& [count, what] : counts) {
    if (count) parts.push_back(integerText(*count) + " " + what);
  }
  return parts.empty() ? "" : label + " " + joined(parts, ", ");
}

/// The sum of a count over all scenes; unknown when unknown for one of them (or no scenes).
std::optional<std::int64_t> sceneTotal(const std::vector<SceneInfo>& scenes,
                                       std::optional<std::int64_t> SceneInfo::*count) {
  if (scenes.empty()) return std::nullopt;
  std::int64_t total = 0;
  for (const SceneInfo& s : scenes) {
    if (!(s.*count)) return std::nullopt;
    total += *(s.*count);
  }
  return total;
}

std::string rgb(const std::array<std::uint8_t, 3>& c) {
  return "rgb(" + std::to_string(c[0]) + "," + std::to_string(c[1]) + "," + std::to_string(c[2]) +
         ")";
}

std::string imgTag(const Png& png, const std::string& alt, const std::string& css_class) {
  return "<img class=\"" + css_class + "\" src=\"data:image/png;base64," + base64(png.png) +
         "\" width=\"" + std::to_string(png.width) + "\" height=\"" + std::to_string(png.height) +
         "\" alt=\"" + escape(alt) + "\">";
}

/// "2024-05-01 14:03 UTC", when `path` was last written; "" when unknown.
std::string modifiedUtc(const fs::path& path) {
  std::error_code ec;
  const fs::file_time_type written = fs::last_write_time(path, ec);
  if (ec) return "";
  const std::time_t t = std::chrono::system_clock::to_time_t(
      std::chrono::time_point_cast<std::chrono::system_clock::duration>(
          fs::file_time_type::clock::to_sys(written)));
  std::tm utc{};
  if (::gmtime_r(&t, &utc) == nullptr) return "";
  char text[64];
  return std::strftime(text, sizeof text, "%Y-%m-%d %H:%M UTC", &utc) > 0 ? text : "";
}



/// The inline 3-D view: started once the page has loaded; a browser without WebGL gets a line
/// saying so instead (the rest of the page does not need it). Served by objscan view (under
/// /results/), it links the viewer.
constexpr std::string_view kView3dScript = R"js(
(function () {
  'use strict';
  var box = document.getElementById('mesh-view');
  try {
    var data = document.getElementById('mesh-data').textContent;
    var mesh = ObjscanMeshView.decode(ObjscanMeshView.base64ToBuffer(data.trim()));
    var camera = JSON.parse(document.getElementById('mesh-camera').textContent);
    var view = new ObjscanMeshView.MeshView(box, mesh, camera);
    // The best few in their colours, as the pictures paint them; the rest on demand.
    view.setPaintTop(Number(box.getAttribute('data-paint-top')));
    var all = document.getElementById('mesh-all');
    all.addEventListener('change', function () { view.setPaintAll(all.checked); });
    box.meshView = view;
    box.setAttribute('data-state', 'ready');
  } catch (e) {
    box.textContent = 'The 3-D view could not start here (' + e.message + ').';
    box.setAttribute('data-state', 'unavailable');
    box.style.height = 'auto';
  }
  if (/^https?:$/.test(location.protocol) && location.pathname.indexOf('/results/') === 0) {
    var a = document.createElement('a');
    a.href = '/';
    a.textContent = ' (open it)';
    document.getElementById('viewer-link').appendChild(a);
  }
})();
)js";

/// The largest mesh the report inlines as it is; a larger one is inlined decimated to this.
constexpr std::size_t kInlineTriangles = 100000;

/// The precision-recall curve as an inline SVG: recall on x, precision on y, both 0..1.
std::string precisionRecallSvg(const EvaluationView& e) {
  constexpr double kLeft = 52, kTop = 16, kWidth = 300, kHeight = 240;
  auto x = [&](double r) { return fixed(kLeft + std::clamp(r, 0.0, 1.0) * kWidth, 1); };
  auto y = [&](double p) { return fixed(kTop + (1.0 - std::clamp(p, 0.0, 1.0)) * kHeight, 1); };
  std::string s =
      "<svg class=\"pr\" xmlns=\"http://www.w3.org/2000/svg\" width=\"380\" height=\"310\" "
      "viewBox=\"0 0 380 310\" role=\"img\" aria-labelledby=\"pr-title\">"
      "<title id=\"pr-title\">Precision-recall curve over the ranked hypotheses</title>";
  for (int i = 0; i <= 5; ++i) {
    const double v = i / 5.0;
    // Grid lines, ticks and labels on both axes.
    s += "<line x1=\"" + x(v) + "\" y1=\"" + y(0) + "\" x2=\"" + x(v) + "\" y2=\"" + y(1) +
         "\" stroke=\"#eaeef2\"/>";
    s += "<line x1=\"" + x(0) + "\" y1=\"" + y(v) + "\" x2=\"" + x(1) + "\" y2=\"" + y(v) +
         "\" stroke=\"#eaeef2\"/>";
    s += "<line x1=\"" + x(v) + "\" y1=\"" + y(0) + "\" x2=\"" + x(v) + "\" y2=\"" +
         fixed(kTop + kHeight + 5, 1) + "\" stroke=\"#57606a\"/>";
    s += "<line x1=\"" + fixed(kLeft - 5, 1) + "\" y1=\"" + y(v) + "\" x2=\"" + x(0) + "\" y2=\"" +
         y(v) + "\" stroke=\"#57606a\"/>";
    s += "<text x=\"" + x(v) + "\" y=\"" + fixed(kTop + kHeight + 19, 1) +
         "\" text-anchor=\"middle\">" + fixed(v, 1) + "</text>";
    s += "<text x=\"" + fixed(kLeft - 8, 1) + "\" y=\"" + fixed(kTop + (1.0 - v) * kHeight + 4, 1) +
         "\" text-anchor=\"end\">" + fixed(v, 1) + "</text>";
  }
  s += "<rect x=\"" + x(0) + "\" y=\"" + y(1) + "\" width=\"" + fixed(kWidth, 1) + "\" height=\"" +
       fixed(kHeight, 1) + "\" fill=\"none\" stroke=\"#57606a\"/>";
  s += "<text x=\"" + x(0.5) + "\" y=\"" + fixed(kTop + kHeight + 38, 1) +
       "\" text-anchor=\"middle\">recall</text>";
  s += "<text transform=\"translate(14 " + y(0.5) +
       ") rotate(-90)\" text-anchor=\"middle\">precision</text>";
  if (!e.curve.empty()) {
    s += "<polyline fill=\"none\" stroke=\"#0969da\" stroke-width=\"2\" "
         "stroke-linejoin=\"round\" points=\"";
    for (std::size_t i = 0; i < e.curve.size(); ++i) {
      s += (i ? " " : "") + x(e.curve[i].recall) + "," + y(e.curve[i].precision);
    }
    s += "\"/>";
  }
  // Legend, top right inside the plot.
  const double lx = kLeft + kWidth - 118, ly = kTop + 10;
  s += "<rect x=\"" + fixed(lx, 1) + "\" y=\"" + fixed(ly, 1) +
       "\" width=\"108\" height=\"24\" fill=\"#fff\" stroke=\"#d8dee4\"/>";
  s += "<line x1=\"" + fixed(lx + 8, 1) + "\" y1=\"" + fixed(ly + 12, 1) + "\" x2=\"" +
       fixed(lx + 30, 1) + "\" y2=\"" + fixed(ly + 12, 1) +
       "\" stroke=\"#0969da\" stroke-width=\"2\"/>";
  s += "<text x=\"" + fixed(lx + 36, 1) + "\" y=\"" + fixed(ly + 16, 1) +
       "\">AP = " + orUnknown(e.ap, 3) + "</text>";
  s += "</svg>";
  return s;
}

std::string groundTruthCell(const EvaluationView& e, std::int64_t rank) {
  const auto it = e.by_rank.find(rank);
  if (it == e.by_rank.end() || (!it->second.object && !it->second.object_id)) {
    return "<td class=\"text gt unknown\">" + std::string(kUnknown) + "</td>";
  }
  const Match& m = it->second;
  const std::string name = m.object ? escape(*m.object) : "object " + integerText(*m.object_id);
  // A rank that matched an object a better rank had found already counts as a miss.
  const bool hit = m.found ? *m.found : (m.iou && e.min_iou && *m.iou >= *e.min_iou);
  return std::string("<td class=\"text gt ") + (hit ? "hit" : "miss") + "\">" + name +
         (m.iou ? " (IoU " + fixed(*m.iou, 2) + ")" : "") + "</td>";
}

/// Everything the page is made from.
struct Inputs {
  fs::path dir;
  HypothesesView hypotheses;
  std::optional<TimingsView> timings;
  std::optional<EvaluationView> evaluation;
  std::optional<Png> overview;
  std::optional<Png> contact_sheet;
  std::vector<std::optional<Png>> closeups;  ///< of the rows shown: hypotheses.rows[i]'s
  bool has_settings = false;
};

Inputs inputsOf(const ScanResults& results, const fs::path& dir) {
  if (!results.hypotheses) {
    throw InputError(dir / kHypothesesFile,
                     "missing: run `objscan discover` or `objscan scan` into this folder first");
  }
  Inputs in;
  in.dir = dir;
  in.hypotheses = viewOf(*results.hypotheses);
  in.has_settings = results.settings.has_value();
  if (results.timings) in.timings = viewOf(*results.timings);
  if (results.evaluation) in.evaluation = viewOf(*results.evaluation);
  if (results.pictures) {
    in.overview = results.pictures->overview;
    in.contact_sheet = results.pictures->contact_sheet;
  }
  const std::size_t shown = std::min(in.hypotheses.rows.size(), kMaxRows);
  for (std::size_t i = 0; i < shown; ++i) {
    std::optional<Png> closeup;
    if (results.pictures) {
      const auto it =
          results.pictures->closeups.find(static_cast<std::size_t>(in.hypotheses.rows[i].rank));
      if (it != results.pictures->closeups.end()) closeup = it->second;
    }
    in.closeups.push_back(std::move(closeup));
  }
  return in;
}

std::vector<std::string> sceneMeshes(const HypothesesView& hyp) {
  std::vector<std::string> meshes;
  for (const SceneInfo& s : hyp.scenes) {
    if (s.mesh) meshes.push_back(*s.mesh);
  }
  return meshes;
}

/// <!DOCTYPE> up to and including <body>.
std::string pageHead(const Inputs& in) {
  const std::vector<std::string> meshes = sceneMeshes(in.hypotheses);
  std::string title = "objscan report";
  if (in.timings && in.timings->source) {
    title += " \u2013 " + *in.timings->source;
  } else if (meshes.size() == 1) {
    title += " \u2013 " + fs::path(meshes[0]).filename().string();
  }
  return "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
         "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>" +
         escape(title) + "</title>\n<style>" + std::string(kStyle) + "</style>\n<script>" +
         std::string(kScript) + "</script>\n</head>\n<body data-errors=\"0\">\n";
}

/// Title, what the scan started from and when, a one-line summary, links to the sections.
std::string header(const Inputs& in) {
  const std::optional<TimingsView>& timings = in.timings;
  std::vector<std::string> meta;
  if (timings && timings->source) {
    meta.push_back("source <code>" + escape(*timings->source) + "</code>");
  }
  for (const std::string& m : sceneMeshes(in.hypotheses)) {
    meta.push_back("scene mesh <code>" + escape(m) + "</code>");
  }
  if (const std::string date = modifiedUtc(in.dir / "hypotheses.json"); !date.empty()) {
    meta.push_back("written " + date);
  }
  if (in.hypotheses.scoring) meta.push_back("scored by " + escape(*in.hypotheses.scoring));

  std::vector<std::string> summary;
  if (timings) {
    const std::string frames = countsText("frames:", {{timings->frames_read, "read"},
                                                      {timings->frames_fused, "fused"},
                                                      {timings->frames_lost, "lost"}});
    if (!frames.empty()) summary.push_back(frames);
  }
  // Mesh size: timings.json's, else the scene meshes' from hypotheses.json.
  const std::vector<SceneInfo>& scenes = in.hypotheses.scenes;
  const char* mesh_label = scenes.size() > 1 ? "meshes:" : "mesh:";
  std::string mesh = timings ? countsText(mesh_label, {{timings->mesh_vertices, "vertices"},
                                                       {timings->mesh_faces, "faces"}})
                             : "";
  if (mesh.empty()) {
    mesh = countsText(mesh_label, {{sceneTotal(scenes, &SceneInfo::vertices), "vertices"},
                                   {sceneTotal(scenes, &SceneInfo::faces), "faces"}});
  }
  if (!mesh.empty()) summary.push_back(mesh);
  const std::int64_t count = timings && timings->hypotheses
                                 ? *timings->hypotheses
                                 : static_cast<std::int64_t>(in.hypotheses.rows.size());
  summary.push_back(integerText(count) + (count == 1 ? " hypothesis" : " hypotheses"));
  if (timings && timings->total_s) summary.push_back(fixed(*timings->total_s, 1) + " s");

  std::string nav;
  auto link = [&nav](bool present, const char* id, const char* text) {
    if (present) nav += std::string("<a href=\"#") + id + "\">" + text + "</a>";
  };
  link(in.overview.has_value(), "overview", "Overview");
  link(in.contact_sheet.has_value(), "contact-sheet", "Contact sheet");
  link(true, "view3d", "3-D view");
  link(true, "hypotheses", "Hypotheses");
  link(in.evaluation.has_value(), "evaluation", "Evaluation");
  link(timings.has_value(), "timings", "Timings");
  link(in.has_settings, "settings", "Settings");

  return "<header>\n<h1>objscan report</h1>\n" +
         (meta.empty() ? "" : "<p class=\"meta\">" + joined(meta, " &middot; ") + "</p>\n") +
         "<p class=\"summary\">" + joined(summary, " &middot; ") + "</p>\n<nav>" + nav +
         "</nav>\n</header>\n";
}

/// A notice listing what an interrupted scan did not produce; "" when it was not interrupted.
std::string interruptedNotice(const Inputs& in) {
  if (!in.timings || !in.timings->interrupted) return "";
  std::vector<std::string> names;
  for (const std::string& name : in.timings->not_produced) {
    names.push_back("<code>" + escape(name) + "</code>");
  }
  return "<div class=\"notice\" id=\"interrupted\" role=\"alert\"><strong>The scan was "
         "interrupted.</strong> What it finished is shown below" +
         (names.empty() ? std::string(".") : "; not produced: " + joined(names, ", ") + ".") +
         "</div>\n";
}

/// The overview and the contact sheet, those that exist.
std::string pictures(const Inputs& in) {
  std::string html;
  if (in.overview) {
    html += "<section id=\"overview\">\n<h2>Overview</h2>\n<figure>" +
            imgTag(*in.overview, "The scene with the top-ranked hypotheses in their colours",
                   "overview") +
            "<figcaption>The scene with the top-ranked hypotheses painted in their rank colours "
            "(the swatches in the table below).</figcaption></figure>\n</section>\n";
  }
  if (in.contact_sheet) {
    html += "<section id=\"contact-sheet\">\n<h2>Contact sheet</h2>\n<figure>" +
            imgTag(*in.contact_sheet, "Close-ups of the top-ranked hypotheses", "contact-sheet") +
            "</figure>\n</section>\n";
  }
  return html;
}

/// The ranked table: at most kMaxRows rows, the top-ranked ones (those with a close-up) marked
/// with their overview colour.
std::string hypothesesSection(const Inputs& in) {
  const std::vector<HypothesisRow>& rows = in.hypotheses.rows;
  std::string html = "<section id=\"hypotheses\">\n<h2>Ranked hypotheses</h2>\n";
  if (rows.empty()) {
    return html + "<p>No object hypotheses: no segment of the scene passed the filters.</p>\n" +
           "</section>\n";
  }
  std::vector<std::string> scenes_seen;
  for (const HypothesisRow& r : rows) {
    if (r.scene && std::find(scenes_seen.begin(), scenes_seen.end(), *r.scene) == scenes_seen.end())
      scenes_seen.push_back(*r.scene);
  }
  const bool scene_column = scenes_seen.size() > 1;
  const bool any_closeup = std::any_of(in.closeups.begin(), in.closeups.end(),
                                       [](const auto& c) { return c.has_value(); });
  // Files from before the object set, and --no-object-set runs, have no object scores.
  const bool object_set =
      std::any_of(rows.begin(), rows.end(), [](const HypothesisRow& r) { return r.object_score; });

  html +=
      std::string("<p class=\"note\">") +
      (any_closeup ? "Rows in bold with a colour swatch are the top-ranked hypotheses, "
                     "rendered in the overview and as close-ups. "
                   : "") +
      "The measures are the paper's, raw: &uarr; marks those where higher is more "
      "object-like, &darr; those where lower is; a dash means unknown." +
      (object_set ? " The objects come first, ranked by their object score (the score weighed by "
                    "how much evidence the segment has and how it stands), and never overlap; the "
                    "alternatives follow, ranked by score."
                  : "") +
      "</p>\n";
  html += "<div class=\"scroll\"><table>\n<thead><tr><th>rank</th>";
  if (object_set) html += "<th>object score</th><th class=\"text\">stands</th>";
  html += "<th>score</th>";
  // Which way each measure points, from discovery's own orientation of them.
  const auto oriented = discovery::orientedMeasures({1.0, 1.0, 1.0, 1.0, 1.0, 1.0});
  for (std::size_t k = 0; k < discovery::kMeasureCount; ++k) {
    std::string label = discovery::kMeasureNames[k];
    std::replace(label.begin(), label.end(), '_', ' ');
    html += "<th>" + label + (oriented[k] > 0.0 ? " &uarr;" : " &darr;") + "</th>";
  }
  html += "<th>vertices</th><th>box (mm)</th>";
  if (scene_column) html += "<th class=\"text\">scene</th>";
  html += "<th class=\"text\">mesh</th>";
  if (any_closeup) html += "<th>close-up</th>";
  if (in.evaluation) html += "<th class=\"text\">ground truth</th>";
  html += "</tr></thead>\n<tbody>\n";

  const std::string unknown_cell = "<td class=\"unknown\">" + std::string(kUnknown) + "</td>";
  for (std::size_t i = 0; i < in.closeups.size(); ++i) {
    const HypothesisRow& r = rows[i];
    const bool top = in.closeups[i].has_value();
    html += std::string("<tr class=\"") + (top ? "top" : "rest") + "\" id=\"rank-" +
            integerText(r.rank) + "\"><td class=\"rank\">";
    if (top) {  // the renderer's colour: ranks past the palette's ten reuse it in order
      const std::size_t colour = static_cast<std::size_t>(r.rank - 1) % kRankPalette.size();
      html +=
          "<span class=\"swatch\" style=\"background:" + rgb(kRankPalette[colour]) + "\"></span>";
    }
    html += integerText(r.rank) + "</td>";
    if (object_set) {
      html += r.object_score ? "<td>" + orUnknown(r.object_score, 3) + "</td>"
                             : "<td class=\"text\">alternative</td>";
      html += "<td class=\"text\">" + escape(r.footing.value_or(std::string(kUnknown))) + "</td>";
    }
    html += "<td>" + orUnknown(r.score, 3) + "</td>";
    for (const std::optional<double>& m : r.measures) {
      html += m ? "<td>" + measureText(*m) + "</td>" : unknown_cell;
    }
    html += r.vertex_count ? "<td>" + integerText(*r.vertex_count) + "</td>" : unknown_cell;
    html += r.extents_m ? "<td>" + fixed(1e3 * (*r.extents_m)[0], 0) + " &times; " +
                              fixed(1e3 * (*r.extents_m)[1], 0) + " &times; " +
                              fixed(1e3 * (*r.extents_m)[2], 0) + "</td>"
                        : unknown_cell;
    if (scene_column) {
      html += "<td class=\"text\"><code>" +
              (r.scene ? escape(fs::path(*r.scene).filename().string()) : std::string()) +
              "</code></td>";
    }
    std::error_code ec;
    if (r.file && fs::exists(in.dir / *r.file, ec)) {
      html += "<td class=\"text\"><a href=\"" + escape(urlPath(*r.file)) + "\">" +
              escape(fs::path(*r.file).filename().string()) + "</a></td>";
    } else if (r.file) {
      html += "<td class=\"text unknown\">" + escape(fs::path(*r.file).filename().string()) +
              " (missing)</td>";
    } else {
      html += "<td class=\"text unknown\">" + std::string(kUnknown) + "</td>";
    }
    if (any_closeup) {
      html +=
          top ? "<td>" +
                    imgTag(*in.closeups[i], "Close-up of rank " + integerText(r.rank), "thumb") +
                    "</td>"
              : std::string("<td></td>");
    }
    if (in.evaluation) html += groundTruthCell(*in.evaluation, r.rank);
    html += "</tr>\n";
  }
  html += "</tbody>\n</table></div>\n";
  if (rows.size() > in.closeups.size()) {
    html += "<p class=\"note\" id=\"more\">Showing the first " +
            std::to_string(in.closeups.size()) + " of " + std::to_string(rows.size()) +
            " hypotheses; " + std::to_string(rows.size() - in.closeups.size()) +
            " more are listed in <a href=\"hypotheses.json\">hypotheses.json</a>.</p>\n";
  }
  return html + "</section>\n";
}

/// The precision-recall curve and the numbers of evaluation.json.
std::string evaluationSection(const EvaluationView& e) {
  std::string html = "<section id=\"evaluation\">\n<h2>Evaluation against the ground truth</h2>\n";
  html += "<div class=\"evaluation\">" + precisionRecallSvg(e) + "<dl class=\"numbers\">";
  auto number = [&html](const char* term, const std::string& value) {
    html += std::string("<dt>") + term + "</dt><dd>" + value + "</dd>";
  };
  auto count = [](const std::optional<std::int64_t>& v) {
    return v ? integerText(*v) : std::string(kUnknown);
  };
  number("objects", count(e.objects));
  std::string found = count(e.found);
  if (e.found && e.objects && *e.objects > 0) {
    const double percent = 100.0 * static_cast<double>(*e.found) / static_cast<double>(*e.objects);
    found += " (" + fixed(percent, 0) + " %)";
  }
  number("found", found);
  number("average precision", orUnknown(e.ap, 3));
  number("min IoU", orUnknown(e.min_iou, 2));
  if (e.ground_truth) number("ground truth", "<code>" + escape(*e.ground_truth) + "</code>");
  return html +
         "</dl></div>\n<p class=\"note\">An object counts as found when a hypothesis overlaps it "
         "with at least the minimum IoU; the curve follows precision and recall down the "
         "ranking.</p>\n</section>\n";
}

/// The stages of timings.json with their seconds and share of the total.
std::string timingsSection(const TimingsView& t) {
  std::string html = "<section id=\"timings\">\n<h2>Timings</h2>\n";
  if (t.stages.empty() && !t.total_s) {
    return html + "<p class=\"note\">No stage timings were recorded.</p>\n</section>\n";
  }
  double sum = 0.0;
  for (const Stage& s : t.stages) sum += s.seconds;
  const double total = t.total_s.value_or(sum);
  html +=
      "<table>\n<thead><tr><th class=\"text\">stage</th><th>seconds</th><th "
      "class=\"text\">share</th></tr></thead>\n<tbody>\n";
  for (const Stage& s : t.stages) {
    const double share = total > 0.0 ? std::clamp(s.seconds / total, 0.0, 1.0) : 0.0;
    html += "<tr><td class=\"text\">" + escape(s.name) + "</td><td>" + fixed(s.seconds, 2) +
            "</td><td class=\"text barcell\"><div class=\"bar\" style=\"width:" +
            fixed(100.0 * share, 1) + "%\"></div></td></tr>\n";
  }
  return html + "</tbody>\n<tfoot><tr><td class=\"text\">total</td><td>" + fixed(total, 2) +
         "</td><td></td></tr></tfoot>\n</table>\n</section>\n";
}

/// How the results were made: objscan's version, the command and every option, the intrinsics
/// and the catalog (settings.json, which `--config` takes to repeat the run).
std::string settingsSection(const Settings& st) {
  std::string html = "<section id=\"settings\">\n<h2>Settings</h2>\n<dl class=\"numbers\">";
  auto term = [&html](const std::string& name, const std::string& value) {
    html += "<dt>" + escape(name) + "</dt><dd>" + value + "</dd>";
  };
  term("objscan", escape(st.objscan_version.empty() ? std::string(kUnknown) : st.objscan_version));
  term("command", "<code>objscan " + escape(st.command) + "</code>");
  auto values = [](const OptionSetting& o) {
    std::vector<std::string> escaped;
    for (const std::string& v : o.values) escaped.push_back(escape(v));
    return escaped.empty() ? std::string(kUnknown) : "<code>" + joined(escaped, " ") + "</code>";
  };
  for (const OptionSetting& o : st.options) term(o.name, values(o));
  for (const OptionSetting& o : st.resolved) term(o.name + " (used)", values(o));
  if (st.intrinsics) {
    const Intrinsics& in = *st.intrinsics;
    term("intrinsics",
         "fx " + fixed(in.fx_px, 2) + ", fy " + fixed(in.fy_px, 2) + ", cx " + fixed(in.cx_px, 2) +
             ", cy " + fixed(in.cy_px, 2) + ", " + integerText(in.width_px) + "&times;" +
             integerText(in.height_px) +
             (st.intrinsics_origin.empty() ? "" : " (" + escape(st.intrinsics_origin) + ")"));
  }
  term("catalog",
       st.catalog ? "<code>" + escape(st.catalog->path) + "</code>: " +
                        integerText(static_cast<std::int64_t>(st.catalog->scenes)) + " scenes, " +
                        integerText(static_cast<std::int64_t>(st.catalog->segments)) + " segments"
                  : std::string("none"));
  return html + "</dl>\n<p class=\"note\">Run <code>objscan " + escape(st.command) +
         " --config settings.json</code> in this folder to make these results again.</p>\n"
         "</section>\n";
}

/// The scene in 3-D, inline (three.js and the mesh, base64): turned with the mouse, hypotheses
/// in their rank colours, at most kInlineTriangles triangles (decimated past that). Always the
/// command that opens the full viewer, and a link to it when the page is served by it.
std::string view3dSection(const Hypotheses& hypotheses, const TriangleMesh* mesh,
                          const std::optional<OverviewCamera>& camera, const fs::path& dir,
                          std::size_t painted_top) {
  std::string html = "<section id=\"view3d\">\n<h2>3-D view</h2>\n";
  const std::string command = "<code>objscan view " + escape(dir.string()) + "</code>";
  std::string note;
  std::string scripts;
  std::optional<ViewMesh> made;
  if (mesh && !mesh->triangles.empty() && !hypotheses.scenes.empty()) {
    try {
      made = viewMesh(*mesh, hypotheses.hypotheses, hypotheses.scenes[0].mesh, kInlineTriangles);
    } catch (const std::invalid_argument& e) {  // hypotheses of another mesh: no view, a note
      note = std::string("No inline view: ") + e.what() + ". ";
    }
  }
  if (made) {
    const ViewMesh& view = *made;
    html += "<div id=\"mesh-view\" data-state=\"loading\" data-paint-top=\"" +
            std::to_string(painted_top) + "\"></div>\n<label><input type=\"checkbox\" " +
            "id=\"mesh-all\"> paint all " + std::to_string(hypotheses.hypotheses.size()) +
            " hypotheses</label>\n";
    note = "Drag to turn, right-drag to pan, wheel to zoom; the best " +
           std::to_string(painted_top) +
           " hypotheses in their rank colours, as in the pictures (the box above paints the "
           "rest too; ranks past ten reuse the colours)";
    if (view.preview.mesh.triangles.size() < mesh->triangles.size()) {
      note += "; shown with " + std::to_string(view.preview.mesh.triangles.size()) + " of its " +
              std::to_string(mesh->triangles.size()) + " triangles";
    }
    note += ". ";
    scripts = "<script>" + std::string(threeJs()) + "</script>\n<script>" +
              std::string(orbitControlsJs()) + "</script>\n<script>" +
              std::string(meshViewJs()) +
              "</script>\n<script type=\"application/octet-stream\" id=\"mesh-data\">" +
              base64(meshViewPayload(view)) +
              "</script>\n<script type=\"application/json\" id=\"mesh-camera\">" +
              (camera ? viewCameraJson(*camera) : std::string("null")) + "</script>\n<script>" +
              std::string(kView3dScript) + "</script>\n";
  } else if (note.empty()) {
    note = "No scene mesh was at hand for an inline view. ";
  }
  // The note before the scripts: the view's script fills its link.
  html += "<p class=\"note\">" + note + "The full viewer, with object details and labelling: " +
          command + "<span id=\"viewer-link\"></span>.</p>\n" + scripts + "</section>\n";
  return html;
}

}  // namespace

fs::path writeReport(const ScanResults& results, const fs::path& dir,
                     const TriangleMesh* scene_mesh) {
  const Inputs in = inputsOf(results, dir);
  std::string html = pageHead(in);
  html += header(in);
  html += interruptedNotice(in);
  html += pictures(in);
  if (!scene_mesh && results.mesh) scene_mesh = &*results.mesh;
  // As many as the pictures paint (their close-ups), as objscan view does.
  const std::size_t painted_top = paintedTop(dir);
  html += view3dSection(*results.hypotheses, scene_mesh,
                        results.pictures ? results.pictures->camera : std::nullopt, dir,
                        painted_top);
  html += hypothesesSection(in);
  if (in.evaluation) html += evaluationSection(*in.evaluation);
  if (in.timings) html += timingsSection(*in.timings);
  if (results.settings) html += settingsSection(*results.settings);
  html += "<footer>Written by objscan from the files in <code>" + escape(dir.string()) +
          "</code>.</footer>\n</body>\n</html>\n";
  const fs::path out = dir / kReportFile;
  writeFileAtomically(out, html);
  return out;
}

}  // namespace objscan::report
