// The HTML report (report/src/report.cpp) on a results folder written here and read back by the
// results model: what the page holds, that its pictures are the PNG files byte for byte, and, in
// headless Chromium, that every picture
// decodes and no script fails. Bad and missing inputs give the documented errors.

#include "objscan/report/report.h"

#include <gtest/gtest.h>

#include <unistd.h>

#include <cctype>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <iterator>
#include <optional>
#include <sstream>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "objscan/core/error.h"
#include "objscan/core/palette.h"
#include "objscan/report/results_io.h"
#include "browser.h"
#include "test_support.h"

namespace objscan {
namespace {

namespace fs = std::filesystem;

/// The report of a results folder, through the results model's one reader.
fs::path reportOf(const fs::path& dir) {
  return report::writeReport(report::readResults(dir), dir);
}
using Json = nlohmann::json;
using testing::readBytes;
using testing::TempDir;
using testing::writeBytes;

constexpr std::string_view kDataUri = "data:image/png;base64,";

/// A scene path with characters that HTML must escape.
const std::string kScene = "/scans/desk <1> & \"kitchen\".ply";
const std::string kSceneEscaped = "/scans/desk &lt;1&gt; &amp; &quot;kitchen&quot;.ply";
const std::string kSource = "synth:3,preset=<desk>&'x'";
const std::string kSourceEscaped = "synth:3,preset=&lt;desk&gt;&amp;&#39;x&#39;";

/// `count` hypotheses as `objscan discover` writes them (vertex lists included), with unknown
/// (null) measures: recurrence for all, symmetry for rank 3.
Json hypothesesJson(int count) {
  Json list = Json::array();
  for (int rank = 1; rank <= count; ++rank) {
    Json measures = {
        {"compactness", 0.5 + 0.01 * rank}, {"symmetry", 0.25},          {"smoothness", 0.875},
        {"local_convexity", 0.75},          {"global_convexity", 0.125}, {"recurrence", nullptr}};
    if (rank == 3) measures["symmetry"] = nullptr;
    char file[32];
    std::snprintf(file, sizeof file, "objects/rank_%03d.ply", rank);
    list.push_back({{"rank", rank},
                    {"score", 2.0 - 0.25 * rank},
                    {"scene", kScene},
                    {"measures", measures},
                    {"box",
                     {{"centre", {0.0, 0.1, 0.8}},
                      {"axes", {{1, 0, 0}, {0, 1, 0}, {0, 0, 1}}},
                      {"extents", {0.118, 0.0601 + 0.001 * rank, 0.0778}}}},
                    {"scale", 5.0},
                    {"vertex_count", 100 * rank},
                    {"vertices", {1, 2, 3}},
                    {"file", file}});
  }
  return {{"scoring", {{"kind", "average"}, {"model", nullptr}}},
          {"scenes",
           {{{"mesh", kScene}, {"vertices", 138825}, {"faces", 269590}, {"hypotheses", count}}}},
          {"hypotheses", list}};
}

Json timingsJson(bool interrupted) {
  Json t = {
      {"source", kSource},
      {"interrupted", interrupted},
      {"stages", {{{"name", "fuse"}, {"seconds", 1.25}}, {{"name", "discover"}, {"seconds", 0.5}}}},
      {"total_s", 2.0},
      {"frames", {{"read", 50}, {"fused", 49}, {"lost", 1}}},
      {"mesh", {{"vertices", 138825}, {"faces", 269590}}},
      {"hypotheses", 7}};
  if (interrupted) t["not_produced"] = {"renders/contact_sheet.png", "evaluation.json"};
  return t;
}

Json evaluationJson() {
  return {{"ground_truth", "/gt/scene_gt.json"},
          {"objects", 4},
          {"min_iou", 0.5},
          {"found", 2},
          {"ap", 0.4375},
          {"curve",
           {{{"rank", 1}, {"recall", 0.25}, {"precision", 1.0}},
            {{"rank", 2}, {"recall", 0.25}, {"precision", 0.5}},
            {{"rank", 3}, {"recall", 0.5}, {"precision", 0.667}}}},
          {"hypotheses",
           {{{"rank", 1}, {"object_id", 3}, {"object", "mug"}, {"iou", 0.81}},
            {{"rank", 2}, {"object_id", 5}, {"object", nullptr}, {"iou", 0.3}},
            {{"rank", 3}, {"object_id", 1}, {"iou", 0.62}}}}};
}

/// A solid-colour PNG of the given size.
void writePng(const fs::path& path, int width, int height, const cv::Scalar& bgr) {
  fs::create_directories(path.parent_path());
  ASSERT_TRUE(cv::imwrite(path.string(), cv::Mat(height, width, CV_8UC3, bgr))) << path;
}

/// The pictures of a full results folder, in the order the page shows them, each a different
/// size so that a browser that decoded them can be told apart from one that did not.
struct Picture {
  const char* name;
  int width, height;
};
constexpr Picture kPictures[] = {{"overview.png", 64, 48},
                                 {"contact_sheet.png", 80, 60},
                                 {"rank_001.png", 32, 24},
                                 {"rank_002.png", 40, 30},
                                 {"rank_003.png", 48, 36}};
constexpr std::size_t kPictureCount = std::size(kPictures);

/// A results folder as `objscan scan` leaves it: 7 hypotheses with close-ups of the top 3,
/// the overview, the contact sheet, timings and an evaluation.
void writeResults(const fs::path& dir, int hypotheses = 7, bool interrupted = false) {
  writeBytes(dir / "hypotheses.json", hypothesesJson(hypotheses).dump(1));
  writeBytes(dir / "timings.json", timingsJson(interrupted).dump(1));
  writeBytes(dir / "evaluation.json", evaluationJson().dump(1));
  for (std::size_t i = 0; i < kPictureCount; ++i) {
    writePng(dir / "renders" / kPictures[i].name, kPictures[i].width, kPictures[i].height,
             cv::Scalar(40.0 * i, 255 - 40.0 * i, 128));
  }
  fs::create_directories(dir / "objects");
  for (int rank = 1; rank <= 3; ++rank) {
    writeBytes(dir / "objects" / ("rank_00" + std::to_string(rank) + ".ply"), "ply\n");
  }
}

std::size_t countOf(std::string_view text, std::string_view needle) {
  std::size_t n = 0;
  for (std::size_t at = text.find(needle); at != std::string_view::npos;
       at = text.find(needle, at + needle.size())) {
    ++n;
  }
  return n;
}

/// RFC 4648 base64 decoding, written apart from the encoder under test; std::nullopt on a
/// character outside the alphabet or a length that is not a multiple of 4.
std::optional<std::string> decodeBase64(std::string_view text) {
  constexpr std::string_view kAlphabet =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  if (text.size() % 4 != 0) return std::nullopt;
  std::string out;
  unsigned bits = 0;
  int have = 0;
  for (std::size_t i = 0; i < text.size(); ++i) {
    if (text[i] == '=') {
      if (i + 2 < text.size()) return std::nullopt;  // padding only at the end
      break;
    }
    const std::size_t v = kAlphabet.find(text[i]);
    if (v == std::string_view::npos) return std::nullopt;
    bits = (bits << 6) | static_cast<unsigned>(v);
    have += 6;
    if (have >= 8) {
      have -= 8;
      out += static_cast<char>((bits >> have) & 0xFF);
    }
  }
  return out;
}

/// The payloads of the page's data URIs, in order.
std::vector<std::string> dataUriPayloads(const std::string& html) {
  std::vector<std::string> out;
  for (std::size_t at = html.find(kDataUri); at != std::string::npos;
       at = html.find(kDataUri, at + 1)) {
    const std::size_t begin = at + kDataUri.size();
    out.push_back(html.substr(begin, html.find('"', begin) - begin));
  }
  return out;
}

/// The values of every `attribute="..."` in `text`, in order. (Found by hand: GCC 12 warns inside
/// std::regex under the sanitizers' flags, and warnings are errors.)
std::vector<std::string> attributeValues(const std::string& text, const std::string& attribute) {
  std::vector<std::string> values;
  const std::string open = attribute + "=\"";
  for (std::size_t at = text.find(open); at != std::string::npos; at = text.find(open, at)) {
    at += open.size();
    const std::size_t end = text.find('"', at);
    if (end == std::string::npos) break;
    values.push_back(text.substr(at, end - at));
    at = end;
  }
  return values;
}

/// The value of attribute `name` on the page's <body> tag, or "(absent)".
std::string bodyAttribute(const std::string& html, const std::string& name) {
  const std::size_t body = html.find("<body");
  if (body == std::string::npos) return "(no <body>)";
  const std::string tag = html.substr(body, html.find('>', body) - body);
  const std::vector<std::string> values = attributeValues(tag, " " + name);
  return values.empty() ? "(absent)" : values.front();
}

/// The table row of `rank`, from its "<tr" up to its "</tr>" (excluded); "" when there is none.
std::string row(const std::string& html, int rank) {
  const std::size_t id = html.find("id=\"rank-" + std::to_string(rank) + "\"");
  if (id == std::string::npos) return "";
  const std::size_t begin = html.rfind("<tr", id);
  return html.substr(begin, html.find("</tr>", id) - begin);
}

// --- The page's content -----------------------------------------------------------------------

TEST(Report, EmbedsEveryPictureAsTheBytesOfItsPngFile) {
  TempDir dir;
  writeResults(dir.path());
  const fs::path page = reportOf(dir.path());
  EXPECT_EQ(page, dir.path() / "report.html");
  const std::string html = readBytes(page);

  const std::vector<std::string> payloads = dataUriPayloads(html);
  ASSERT_EQ(payloads.size(), kPictureCount);
  EXPECT_EQ(countOf(html, "<img "), kPictureCount);
  for (std::size_t i = 0; i < kPictureCount; ++i) {
    const std::optional<std::string> bytes = decodeBase64(payloads[i]);
    ASSERT_TRUE(bytes.has_value()) << kPictures[i].name << ": not base64";
    EXPECT_EQ(*bytes, readBytes(dir.path() / "renders" / kPictures[i].name)) << kPictures[i].name;
    const cv::Mat image = cv::imdecode(
        cv::Mat(1, static_cast<int>(bytes->size()), CV_8U, const_cast<char*>(bytes->data())),
        cv::IMREAD_UNCHANGED);
    EXPECT_EQ(image.cols, kPictures[i].width) << kPictures[i].name;
    EXPECT_EQ(image.rows, kPictures[i].height) << kPictures[i].name;
    // The <img> says the size the PNG has (the page's script checks the decoded size against it).
    const std::size_t img = html.rfind("<img ", html.find(payloads[i]));
    const std::string tag = html.substr(img, html.find('>', img) - img);
    EXPECT_NE(tag.find(" width=\"" + std::to_string(kPictures[i].width) + "\""), std::string::npos)
        << tag.substr(tag.size() - 80);
    EXPECT_NE(tag.find(" height=\"" + std::to_string(kPictures[i].height) + "\""),
              std::string::npos);
  }
}

TEST(Report, ReferencesNothingOutsideThePageButRelativeLinks) {
  TempDir dir;
  writeResults(dir.path());
  const std::string html = readBytes(reportOf(dir.path()));
  EXPECT_EQ(countOf(html, "src=\""), countOf(html, std::string("src=\"") + std::string(kDataUri)));
  for (const char* bad : {"src=\"http", "href=\"http", "file:", "<link", "@import", "url(",
                          "<script src", "//fonts."}) {
    EXPECT_EQ(html.find(bad), std::string::npos) << bad;
  }
  // Every link is relative to the results folder, or a jump inside the page.
  std::size_t links = 0;
  for (const std::string& target : attributeValues(html, "href")) {
    ++links;
    EXPECT_TRUE(target.starts_with("#") || target.starts_with("objects/") ||
                target == "hypotheses.json")
        << target;
  }
  EXPECT_GE(links, 3u);  // the three meshes at least
}

TEST(Report, EscapesThePathsItShows) {
  TempDir dir;
  writeResults(dir.path());
  const std::string html = readBytes(reportOf(dir.path()));
  EXPECT_NE(html.find(kSceneEscaped), std::string::npos);
  EXPECT_NE(html.find(kSourceEscaped), std::string::npos);
  EXPECT_EQ(html.find(kScene), std::string::npos);
  EXPECT_EQ(html.find(kSource), std::string::npos);
  EXPECT_EQ(html.find("<1>"), std::string::npos);
}

TEST(Report, RanksEveryHypothesisAndMarksTheTopOnesInTheirOverviewColours) {
  TempDir dir;
  writeResults(dir.path());
  const std::string html = readBytes(reportOf(dir.path()));
  for (const char* id : {"overview", "contact-sheet", "hypotheses", "evaluation", "timings"}) {
    EXPECT_NE(html.find(std::string("<section id=\"") + id + "\""), std::string::npos) << id;
  }
  EXPECT_EQ(html.find("id=\"interrupted\""), std::string::npos);
  EXPECT_EQ(html.find("id=\"more\""), std::string::npos);

  for (int rank = 1; rank <= 7; ++rank) {
    const std::string r = row(html, rank);
    ASSERT_FALSE(r.empty()) << "no row for rank " << rank;
    const bool top = rank <= 3;  // the ranks with a close-up
    EXPECT_EQ(r.starts_with("<tr class=\"top\""), top) << r;
    const auto& c = kRankPalette[static_cast<std::size_t>(rank - 1)];
    const std::string swatch = "background:rgb(" + std::to_string(c[0]) + "," +
                               std::to_string(c[1]) + "," + std::to_string(c[2]) + ")";
    EXPECT_EQ(r.find(swatch) != std::string::npos, top) << r;
    EXPECT_EQ(countOf(r, "<img "), top ? 1u : 0u);
    // Score, vertex count, box in mm (60.1 + rank mm wide), link.
    char score[16];
    std::snprintf(score, sizeof score, "<td>%.3f</td>", 2.0 - 0.25 * rank);
    EXPECT_NE(r.find(score), std::string::npos) << r;
    EXPECT_NE(r.find("<td>" + std::to_string(100 * rank) + "</td>"), std::string::npos);
    EXPECT_NE(r.find("<td>118 &times; " + std::to_string(60 + rank) + " &times; 78</td>"),
              std::string::npos)
        << r;
    // Unknown measures show a dash: recurrence everywhere, symmetry at rank 3.
    EXPECT_EQ(countOf(r, "<td class=\"unknown\">\u2013</td>"), rank == 3 ? 2u : 1u) << r;
    if (top) {
      EXPECT_NE(r.find("<a href=\"objects/rank_00" + std::to_string(rank) + ".ply\">"),
                std::string::npos);
    } else {
      EXPECT_NE(r.find("(missing)"), std::string::npos) << r;  // no such file was written
    }
  }
  EXPECT_EQ(countOf(html, "class=\"swatch\""), 3u);
  // Columns: the six measures by name, with the way they point (the paper's symmetry, hull
  // distance and recurrence are lower for objects); ground truth with the evaluation.
  for (const char* name :
       {"compactness &uarr;", "symmetry &darr;", "smoothness &uarr;", "local convexity &uarr;",
        "global convexity &darr;", "recurrence &darr;", "ground truth"}) {
    EXPECT_NE(html.find(std::string(">") + name + "</th>"), std::string::npos) << name;
  }
  EXPECT_NE(row(html, 1).find("mug (IoU 0.81)"), std::string::npos);
  EXPECT_NE(row(html, 2).find("object 5 (IoU 0.30)"), std::string::npos);
  EXPECT_NE(row(html, 3).find("object 1 (IoU 0.62)"), std::string::npos);
  EXPECT_TRUE(row(html, 4).ends_with("<td class=\"text gt unknown\">\u2013</td>")) << row(html, 4);
}

TEST(Report, ShowsTheObjectScoreAndFootingOfObjectsAndMarksAlternatives) {
  TempDir dir;
  writeResults(dir.path());
  // The results above are from before the object set: no object score column.
  EXPECT_EQ(readBytes(reportOf(dir.path())).find("object score"), std::string::npos);
  // Ranks 1 and 2 are objects (ranked by object score), the rest alternatives.
  Json doc = hypothesesJson(4);
  for (int k = 0; k < 4; ++k) {
    Json& h = doc["hypotheses"][static_cast<std::size_t>(k)];
    h["object_set"] = k < 2;
    if (k < 2) {
      h["object_rank"] = k + 1;
      h["object_score"] = 1.25 - 0.5 * k;
    }
    h["context"] = {{"footing", k == 1 ? "surface" : "support"}};
  }
  writeBytes(dir / "hypotheses.json", doc.dump(1));
  const std::string html = readBytes(reportOf(dir.path()));
  EXPECT_NE(html.find("<th>rank</th><th>object score</th><th class=\"text\">stands</th>"
                      "<th>score</th>"),
            std::string::npos);
  EXPECT_NE(row(html, 1).find("<td>1.250</td><td class=\"text\">support</td><td>1.750</td>"),
            std::string::npos)
      << row(html, 1);
  EXPECT_NE(row(html, 2).find("<td>0.750</td><td class=\"text\">surface</td><td>1.500</td>"),
            std::string::npos)
      << row(html, 2);
  EXPECT_NE(row(html, 3).find("<td class=\"text\">alternative</td>"), std::string::npos)
      << row(html, 3);
  EXPECT_NE(html.find("The objects come first"), std::string::npos);
}

TEST(Report, SummarisesTimingsAndDrawsThePrecisionRecallCurve) {
  TempDir dir;
  writeResults(dir.path());
  const std::string html = readBytes(reportOf(dir.path()));
  EXPECT_NE(html.find("frames: 50 read, 49 fused, 1 lost"), std::string::npos);
  EXPECT_NE(html.find("mesh: 138825 vertices, 269590 faces"), std::string::npos);
  EXPECT_NE(html.find("7 hypotheses"), std::string::npos);
  EXPECT_NE(html.find("<td class=\"text\">fuse</td><td>1.25</td>"), std::string::npos);
  EXPECT_NE(html.find("<td class=\"text\">discover</td><td>0.50</td>"), std::string::npos);
  EXPECT_NE(html.find("<td class=\"text\">total</td><td>2.00</td>"), std::string::npos);

  const std::size_t svg = html.find("<svg");
  ASSERT_NE(svg, std::string::npos);
  const std::string plot = html.substr(svg, html.find("</svg>", svg) - svg);
  EXPECT_NE(plot.find("AP = 0.438"), std::string::npos);
  EXPECT_NE(plot.find(">recall<"), std::string::npos);
  EXPECT_NE(plot.find(">precision<"), std::string::npos);
  EXPECT_EQ(countOf(plot, ">0.0<"), 2u);  // a tick label at each axis' origin ...
  EXPECT_EQ(countOf(plot, ">1.0<"), 2u);  // ... and end
  // The polyline goes through (recall, precision) = (0.25, 1), (0.25, 0.5), (0.5, 0.667): the
  // plot is 300 x 240 px from (52, 16).
  EXPECT_NE(plot.find("points=\"127.0,16.0 127.0,136.0 202.0,95.9\""), std::string::npos) << plot;
  for (const char* number :
       {"<dt>objects</dt><dd>4</dd>", "<dt>found</dt><dd>2 (50 %)</dd>",
        "<dt>average precision</dt><dd>0.438</dd>", "<dt>min IoU</dt><dd>0.50</dd>"}) {
    EXPECT_NE(html.find(number), std::string::npos) << number;
  }
}

TEST(Report, AnInterruptedScanSaysWhatItDidNotProduce) {
  TempDir dir;
  writeResults(dir.path(), 7, /*interrupted=*/true);
  const std::string html = readBytes(reportOf(dir.path()));
  const std::size_t notice = html.find("id=\"interrupted\"");
  ASSERT_NE(notice, std::string::npos);
  const std::string text = html.substr(notice, html.find("</div>", notice) - notice);
  EXPECT_NE(text.find("<code>renders/contact_sheet.png</code>"), std::string::npos) << text;
  EXPECT_NE(text.find("<code>evaluation.json</code>"), std::string::npos) << text;
}

TEST(Report, ShowsTheFirstFiftyOfManyHypothesesAndCountsTheRest) {
  TempDir dir;
  writeResults(dir.path(), 60);
  const std::string html = readBytes(reportOf(dir.path()));
  EXPECT_FALSE(row(html, 50).empty());
  EXPECT_TRUE(row(html, 51).empty());
  EXPECT_EQ(countOf(html, "<tr class=\""), 50u);
  EXPECT_NE(html.find("Showing the first 50 of 60 hypotheses; 10 more"), std::string::npos);
}

TEST(Report, LeavesOutTheSectionsWhoseFilesAreMissing) {
  TempDir dir;
  writeBytes(dir / "hypotheses.json", hypothesesJson(4).dump());
  const std::string html = readBytes(reportOf(dir.path()));
  EXPECT_NE(html.find("<section id=\"hypotheses\""), std::string::npos);
  for (const char* id : {"overview", "contact-sheet", "evaluation", "timings", "interrupted"}) {
    EXPECT_EQ(html.find(std::string("id=\"") + id + "\""), std::string::npos) << id;
  }
  EXPECT_EQ(html.find("<img"), std::string::npos);
  EXPECT_EQ(html.find("<svg"), std::string::npos);
  EXPECT_EQ(html.find("ground truth"), std::string::npos);
  EXPECT_EQ(html.find("class=\"swatch\""), std::string::npos);  // nothing painted, no colours
  EXPECT_FALSE(row(html, 4).empty());
  // The summary falls back on hypotheses.json for the mesh size and the count.
  EXPECT_NE(html.find("mesh: 138825 vertices, 269590 faces &middot; 4 hypotheses"),
            std::string::npos);
}

TEST(Report, TimingsWithEveryKeyMissingStillGiveAPage) {
  TempDir dir;
  writeBytes(dir / "hypotheses.json", hypothesesJson(2).dump());
  writeBytes(dir / "timings.json", "{}");
  writeBytes(dir / "evaluation.json", "{}");
  const std::string html = readBytes(reportOf(dir.path()));
  EXPECT_NE(html.find("<section id=\"timings\""), std::string::npos);
  EXPECT_NE(html.find("<section id=\"evaluation\""), std::string::npos);
  EXPECT_NE(html.find("AP = \u2013"), std::string::npos);
}

// --- Errors -----------------------------------------------------------------------------------

TEST(Report, MissingHypothesesIsAnInputErrorNamingIt) {
  TempDir dir;
  writeBytes(dir / "timings.json", timingsJson(false).dump());
  testing::expectInputError([&] { reportOf(dir.path()); }, dir / "hypotheses.json", "missing");
  EXPECT_FALSE(fs::exists(dir / "report.html"));
}

TEST(Report, TruncatedOrMisshapenHypothesesIsAnInputErrorNamingIt) {
  TempDir dir;
  const std::string whole = hypothesesJson(3).dump();
  writeBytes(dir / "hypotheses.json", whole.substr(0, whole.size() / 2));
  testing::expectInputError([&] { reportOf(dir.path()); }, dir / "hypotheses.json",
                            "not valid JSON");
  writeBytes(dir / "hypotheses.json", "[1, 2]");
  testing::expectInputError([&] { reportOf(dir.path()); }, dir / "hypotheses.json",
                            "not an object");
  writeBytes(dir / "hypotheses.json", R"({"scenes": []})");
  testing::expectInputError([&] { reportOf(dir.path()); }, dir / "hypotheses.json",
                            "\"hypotheses\" is missing");
  writeBytes(dir / "hypotheses.json", R"({"hypotheses": [{"rank": 1, "score": "high"}]})");
  testing::expectInputError([&] { reportOf(dir.path()); }, dir / "hypotheses.json",
                            "\"hypotheses[0].score\" is a string, expected a number");
  writeBytes(dir / "hypotheses.json", R"({"hypotheses": [{"score": 1.0}]})");
  testing::expectInputError([&] { reportOf(dir.path()); }, dir / "hypotheses.json",
                            "\"hypotheses[0].rank\"");
  EXPECT_FALSE(fs::exists(dir / "report.html"));
}

TEST(Report, ACorruptOptionalInputIsAnInputErrorNamingIt) {
  TempDir dir;
  writeResults(dir.path());
  writeBytes(dir / "evaluation.json", "{\"ap\": ");
  testing::expectInputError([&] { reportOf(dir.path()); }, dir / "evaluation.json",
                            "not valid JSON");
  writeResults(dir.path());
  writeBytes(dir / "renders" / "rank_002.png", "GIF89a, not a PNG at all, but long enough");
  testing::expectInputError([&] { reportOf(dir.path()); }, dir / "renders" / "rank_002.png",
                            "not a PNG");
}

TEST(Report, AReportThatCannotBeWrittenIsAnOutputError) {
  TempDir dir;
  writeBytes(dir / "hypotheses.json", hypothesesJson(2).dump());
  fs::create_directories(dir / "report.html" / "in-the-way");  // a folder where the page goes
  EXPECT_THROW(reportOf(dir.path()), OutputError);
}

// --- In a browser -----------------------------------------------------------------------------

/// The DOM of `page` after it loaded in headless Chromium (scripts run).
std::string domInChromium(const fs::path& page) {
  return testing::domInChromium(testing::fileUrl(page));
}

TEST(ReportInBrowser, EveryPictureDecodesAndNoScriptFails) {
  TempDir dir;
  writeResults(dir.path());
  const fs::path page = reportOf(dir.path());
  const std::string dom = domInChromium(page);
  const std::string all = std::to_string(kPictureCount) + "/" + std::to_string(kPictureCount);
  EXPECT_EQ(bodyAttribute(dom, "data-images"), all);
  EXPECT_EQ(bodyAttribute(dom, "data-errors"), "0");
  EXPECT_NE(dom.find("<section id=\"evaluation\""), std::string::npos);  // the page is all there
}

// The negative controls: the same page with one picture broken must fail the check, so that
// "5/5" above means the pictures decoded and not that the check cannot fail.
TEST(ReportInBrowser, APictureThatDoesNotDecodeIsCounted) {
  TempDir dir;
  writeResults(dir.path());
  std::string html = readBytes(reportOf(dir.path()));
  const std::vector<std::string> payloads = dataUriPayloads(html);
  ASSERT_EQ(payloads.size(), kPictureCount);
  // The contact sheet's payload with its first 6 bytes (8 base64 characters, "iVBORw0K": the PNG
  // signature) zeroed: still valid base64, no longer an image.
  const std::size_t at = html.find(payloads[1]);
  ASSERT_EQ(html.substr(at, 8), "iVBORw0K");
  html.replace(at, 8, "AAAAAAAA");
  writeBytes(dir / "broken.html", html);
  const std::string dom = domInChromium(dir / "broken.html");
  const std::string n = std::to_string(kPictureCount);
  EXPECT_EQ(bodyAttribute(dom, "data-images"), std::to_string(kPictureCount - 1) + "/" + n);
  EXPECT_EQ(bodyAttribute(dom, "data-errors"), "1");  // the failed load, seen in capture
}

TEST(ReportInBrowser, APictureOfTheWrongSizeIsCounted) {
  TempDir dir;
  writeResults(dir.path());
  std::string html = readBytes(reportOf(dir.path()));
  // rank_001.png is 32 x 24; say 33.
  const std::size_t at = html.find("width=\"32\" height=\"24\"");
  ASSERT_NE(at, std::string::npos);
  html.replace(at, 10, "width=\"33\"");
  writeBytes(dir / "resized.html", html);
  const std::string dom = domInChromium(dir / "resized.html");
  const std::string n = std::to_string(kPictureCount);
  EXPECT_EQ(bodyAttribute(dom, "data-images"), std::to_string(kPictureCount - 1) + "/" + n);
  EXPECT_EQ(bodyAttribute(dom, "data-errors"), "0");
}

}  // namespace
}  // namespace objscan
