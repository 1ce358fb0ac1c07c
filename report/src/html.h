#pragma once

#include <string>
#include <string_view>

/// What report.html and the collection's index.html share: escaping, numbers, the style sheet
/// and the script that counts decoded pictures (data-images, data-errors on <body>).
namespace objscan::report::html {

/// RFC 4648 base64 with padding.
std::string base64(std::string_view bytes);
/// Text safe inside an element and inside a double- or single-quoted attribute.
std::string escape(std::string_view text);
/// A relative path as a URL path: every byte but unreserved characters and '/' percent-encoded.
std::string urlPath(std::string_view path);
/// printf's %.*f.
std::string fixed(double v, int decimals);

/// The pages' style sheet.
extern const std::string_view kStyle;
/// Counts script errors and pictures that failed into <body data-errors>, and once loaded the
/// pictures that decoded at their width attribute's size into data-images="<decoded>/<total>".
extern const std::string_view kScript;

}  // namespace objscan::report::html
