#include "html.h"

#include <cstdint>
#include <cstdio>

// The pieces of HTML that report.html and the collection's index.html share.

namespace objscan::report::html {

/// RFC 4648 base64 with padding. Written here rather than taken from a library: Debian's choices
/// (OpenSSL's EVP_EncodeBlock, libb64) would be a new dependency for a dozen lines.
std::string base64(std::string_view bytes) {
  static constexpr char kAlphabet[] =
      "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string out;
  out.reserve((bytes.size() + 2) / 3 * 4);
  std::size_t i = 0;
  for (; i + 3 <= bytes.size(); i += 3) {
    const std::uint32_t v = static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i])) << 16 |
                            static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i + 1]))
                                << 8 |
                            static_cast<unsigned char>(bytes[i + 2]);
    out += kAlphabet[v >> 18 & 63];
    out += kAlphabet[v >> 12 & 63];
    out += kAlphabet[v >> 6 & 63];
    out += kAlphabet[v & 63];
  }
  if (const std::size_t rest = bytes.size() - i; rest > 0) {
    std::uint32_t v = static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i])) << 16;
    if (rest == 2) v |= static_cast<std::uint32_t>(static_cast<unsigned char>(bytes[i + 1])) << 8;
    out += kAlphabet[v >> 18 & 63];
    out += kAlphabet[v >> 12 & 63];
    out += rest == 2 ? kAlphabet[v >> 6 & 63] : '=';
    out += '=';
  }
  return out;
}

/// Text safe inside an element and inside a double- or single-quoted attribute.
std::string escape(std::string_view text) {
  std::string out;
  out.reserve(text.size());
  for (const char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&#39;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

/// A relative path as a URL path: every byte but unreserved characters and '/' percent-encoded,
/// so '#', '?', '%' and ':' (no "javascript:" link can come out of a file name) stay literal.
std::string urlPath(std::string_view path) {
  static constexpr char kHex[] = "0123456789ABCDEF";
  std::string out;
  for (const char c : path) {
    const auto u = static_cast<unsigned char>(c);
    if ((u >= 'a' && u <= 'z') || (u >= 'A' && u <= 'Z') || (u >= '0' && u <= '9') || u == '-' ||
        u == '.' || u == '_' || u == '~' || u == '/') {
      out += c;
    } else {
      out += '%';
      out += kHex[u >> 4];
      out += kHex[u & 15];
    }
  }
  return out;
}

std::string fixed(double v, int decimals) {
  char text[64];
  std::snprintf(text, sizeof text, "%.*f", decimals, v);
  return text;
}

const std::string_view kStyle = R"css(
:root { color-scheme: light; }
body { margin: 0 auto; max-width: 1400px; padding: 1.5rem 1.5rem 3rem; background: #fafbfc;
  color: #1f2328; font: 15px/1.5 system-ui, -apple-system, "Segoe UI", Roboto, "Helvetica Neue",
  Arial, sans-serif; }
h1 { font-size: 1.6rem; margin: 0 0 .25rem; }
h2 { font-size: 1.2rem; margin: 2rem 0 .75rem; padding-bottom: .25rem; border-bottom: 1px solid #d8dee4; }
code { font: .9em ui-monospace, SFMono-Regular, Menlo, Consolas, monospace; overflow-wrap: anywhere; }
.meta, .summary, figcaption, .note { color: #57606a; }
.meta, .summary { margin: .2rem 0; }
nav { margin: .75rem 0 0; }
nav a { margin-right: 1rem; color: #0969da; text-decoration: none; }
a { color: #0969da; }
figure { margin: 0; }
figure img { display: block; max-width: 100%; height: auto; background: #fff; border: 1px solid #d8dee4; }
figcaption, .note { font-size: .9rem; margin-top: .35rem; }
.notice { margin: 1rem 0; padding: .75rem 1rem; border: 1px solid #d4a72c; border-radius: 6px;
  background: #fff8c5; }
.scroll { overflow-x: auto; }
table { border-collapse: collapse; background: #fff; font-variant-numeric: tabular-nums;
  border: 1px solid #d8dee4; }
th, td { padding: .3rem .5rem; text-align: right; vertical-align: middle; white-space: nowrap;
  border-bottom: 1px solid #eaeef2; }
th { background: #f0f3f6; font-size: .85rem; font-weight: 600; text-align: center; white-space: normal; }
th.text, td.text { text-align: left; }
tbody tr:nth-child(even) { background: #f6f8fa; }
tfoot td { font-weight: 600; border-top: 2px solid #d8dee4; }
td.unknown { color: #8c959f; }
tr.top td.rank { font-weight: 700; }
tr.rest { color: #57606a; }
.swatch { display: inline-block; width: .9em; height: .9em; margin-right: .4em; vertical-align: -.1em;
  border-radius: 2px; border: 1px solid rgba(0,0,0,.25); }
img.thumb { display: block; width: 80px; height: auto; background: #fff; border: 1px solid #d8dee4; }
td.gt { white-space: normal; min-width: 8em; }
td.hit { color: #1a7f37; }
td.miss { color: #9a6700; }
.bar { height: .6em; min-width: 1px; border-radius: 2px; background: #0969da; }
td.barcell { width: 240px; }
.numbers { display: grid; grid-template-columns: max-content auto; gap: .15rem 1rem; margin: 0 0 1rem; }
.numbers dt { color: #57606a; }
.numbers dd { margin: 0; font-variant-numeric: tabular-nums; }
.evaluation { display: flex; flex-wrap: wrap; gap: 2rem; align-items: flex-start; }
svg.pr { background: #fff; border: 1px solid #d8dee4; }
svg.pr text { font: 12px system-ui, sans-serif; fill: #1f2328; }
#mesh-view { height: 480px; border: 1px solid #d0d7de; border-radius: 6px; overflow: hidden; }
footer { margin-top: 3rem; color: #8c959f; font-size: .85rem; }
)css";

// Counts errors (script errors, and with the capture phase also pictures that fail to load) into
// data-errors, and once everything has loaded writes "<decoded>/<total>" pictures into
// data-images; a picture counts when it decoded at the size its width attribute says. Only
// a check for tests and the curious: the page does not need scripts to show everything.
const std::string_view kScript = R"js(
(function () {
  'use strict';
  var errors = 0;
  window.addEventListener('error', function () {
    ++errors;
    if (document.body) document.body.dataset.errors = String(errors);
  }, true);
  window.addEventListener('load', function () {
    var images = document.images, loaded = 0;
    for (var i = 0; i < images.length; ++i) {
      var img = images[i], width = img.getAttribute('width');
      if (img.complete && img.naturalWidth > 0 &&
          (width === null || img.naturalWidth === Number(width))) ++loaded;
    }
    document.body.dataset.errors = String(errors);
    document.body.dataset.images = loaded + '/' + images.length;
  });
})();
)js";

}  // namespace objscan::report::html
