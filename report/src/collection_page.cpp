#include "objscan/report/collection_page.h"

#include <cmath>
#include <string>

#include "objscan/core/atomic_file.h"
#include "html.h"

namespace objscan::report {
namespace {

using html::escape;
using html::fixed;
using html::urlPath;

constexpr std::string_view kCollectionStyle = R"css(
.scene { margin: 0 0 1.5rem; }
.scene h3 { font-size: 1.05rem; margin: 0 0 .2rem; }
.row { display: flex; flex-wrap: wrap; gap: .6rem; align-items: flex-start; }
.item { width: 168px; font-size: .8rem; color: #57606a; overflow-wrap: anywhere; }
.item img { display: block; width: 168px; height: auto; background: #fff; border: 1px solid #d8dee4; }
.item.query { width: 216px; }
.item.query img { width: 216px; border: 2px solid #0969da; }
.missing { width: 166px; height: 166px; border: 1px dashed #d8dee4; display: flex;
  align-items: center; justify-content: center; }
.group { margin: 0 0 1.75rem; padding-bottom: 1rem; border-bottom: 1px solid #eaeef2; }
)css";

std::string sizeText(const Eigen::Vector3f& e) {
  return fixed(1000.0 * e[0], 0) + " &times; " + fixed(1000.0 * e[1], 0) + " &times; " +
         fixed(1000.0 * e[2], 0) + " mm";
}

/// The viewer's link to an item: its scene, and its rank or its segment.
std::string viewerLink(const CollectionPage& page, const CollectionItem& item) {
  std::string target = page.viewer_url + "#scene=" + std::to_string(item.scene_index);
  if (item.rank) {
    target += "&rank=" + std::to_string(*item.rank);
  } else if (item.segment) {
    target += "&segment=" + std::to_string(*item.segment);
  }
  return target;
}

/// One picture with its caption; `scene_name` adds the scene's name to the caption.
std::string itemHtml(const CollectionPage& page, const CollectionItem& item, const char* css_class,
                     bool scene_name) {
  std::string out = "<figure class=\"item " + std::string(css_class) + "\" data-scene=\"" +
                    escape(item.scene) + "\"";
  if (item.rank) out += " data-rank=\"" + std::to_string(*item.rank) + "\"";
  if (item.segment) out += " data-segment=\"" + std::to_string(*item.segment) + "\"";
  if (item.distance) out += " data-distance=\"" + fixed(*item.distance, 4) + "\"";
  out += "><a href=\"" + escape(viewerLink(page, item)) + "\">";
  const std::string alt = item.rank ? "hypothesis " + std::to_string(*item.rank)
                                    : "segment " + std::to_string(item.segment.value_or(0));
  if (item.picture.empty()) {
    out += "<div class=\"missing\">no picture</div>";
  } else {
    out += "<img src=\"" + escape(urlPath(item.picture)) + "\" alt=\"" + escape(alt) +
           "\">";
  }
  out += "</a><figcaption>";
  if (scene_name) out += "<strong>" + escape(item.scene) + "</strong><br>";
  if (item.rank) out += "#" + std::to_string(*item.rank) + " ";
  if (item.score && std::isfinite(*item.score)) out += "score " + fixed(*item.score, 3) + " ";
  if (item.distance) out += "distance " + fixed(*item.distance, 2);
  out += "<br>" + sizeText(item.extents) + "</figcaption></figure>\n";
  return out;
}

}  // namespace

std::filesystem::path writeCollectionPage(const CollectionPage& page,
                                          const std::filesystem::path& file) {
  std::string out =
      "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
      "<meta name=\"viewport\" content=\"width=device-width, initial-scale=1\">\n<title>objscan "
      "collection &ndash; " +
      escape(page.title) + "</title>\n<style>" + std::string(html::kStyle) +
      std::string(kCollectionStyle) + "</style>\n<script>" + std::string(html::kScript) +
      "</script>\n</head>\n<body data-scenes=\"" + std::to_string(page.scenes.size()) +
      "\" data-groups=\"" + std::to_string(page.groups.size()) + "\">\n";
  out += "<h1>Collection: " + escape(page.title) + "</h1>\n<p class=\"meta\">" +
         std::to_string(page.scenes.size()) + " scenes ranked together";
  if (page.failed > 0) {
    out += "; " + std::to_string(page.failed) + " recordings without complete results (not shown)";
  }
  out += ".</p>\n<p class=\"note\">A picture opens the object in the 3-D viewer: run <code>" +
         escape(page.view_command) + "</code> first (it serves <code>" +
         escape(page.viewer_url) + "</code>).</p>\n";
  out +=
      "<nav><a href=\"#scenes\">Scenes</a><a href=\"#across\">Objects across scenes</a></nav>\n";

  out += "<h2 id=\"scenes\">Scenes</h2>\n";
  for (const CollectionSceneEntry& s : page.scenes) {
    out += "<section class=\"scene\" data-name=\"" + escape(s.name) + "\">\n<h3>";
    if (s.report.empty()) {
      out += escape(s.name);
    } else {
      out += "<a href=\"" + escape(urlPath(s.report)) + "\">" + escape(s.name) + "</a>";
    }
    out += "</h3>\n<p class=\"meta\"><code>" + escape(s.source) + "</code>, " +
           std::to_string(s.hypotheses) + " hypotheses in the collection's ranking</p>\n";
    out += "<div class=\"row\">\n";
    for (const CollectionItem& item : s.objects) out += itemHtml(page, item, "object", false);
    if (s.objects.empty()) out += "<p class=\"note\">No object found in this scene.</p>\n";
    out += "</div>\n</section>\n";
  }

  out += "<h2 id=\"across\">Objects across scenes</h2>\n";
  if (page.groups.empty()) {
    out += "<p class=\"note\">" + escape(page.groups_missing) + "</p>\n";
  } else {
    out +=
        "<p class=\"note\">Each of the collection's best objects (left, framed) and the segments "
        "of other scenes most like it, nearest first: of similar size (within 25 % along each "
        "principal direction) and nearest in the five shape measures, the neighbours recurrence "
        "is measured over.</p>\n";
  }
  for (const CollectionGroup& g : page.groups) {
    out += "<section class=\"group\"><div class=\"row\">\n";
    out += itemHtml(page, g.query, "query", true);
    for (const CollectionItem& n : g.neighbours) out += itemHtml(page, n, "neighbour", true);
    if (g.neighbours.empty()) {
      out += "<p class=\"note\">No segment of another scene is of a similar size.</p>\n";
    }
    out += "</div></section>\n";
  }
  out += "<footer>Written by objscan batch.</footer>\n</body>\n</html>\n";
  writeFileAtomically(file, out);
  return file;
}

}  // namespace objscan::report
