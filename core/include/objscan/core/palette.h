#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

namespace objscan {

/// The colours (8-bit RGB) that mark the top-ranked hypotheses: kRankPalette[(r - 1) % 10] is
/// rank r's (ranks past ten reuse them in order). The renderer paints the overview with them and
/// the HTML report draws the same swatches in its ranked table, so a colour identifies a
/// hypothesis across both. They follow Sasha Trubetskoy's list of 20 distinct colours (its 2017
/// values), in its order, leaving out its yellow and pastels, which fade into a light page.
inline constexpr std::array<std::array<std::uint8_t, 3>, 10> kRankPalette = {{
    {230, 25, 75},   // 1 red
    {60, 180, 75},   // 2 green
    {0, 130, 200},   // 3 blue
    {245, 130, 48},  // 4 orange
    {145, 30, 180},  // 5 purple
    {70, 240, 240},  // 6 cyan
    {240, 50, 230},  // 7 magenta
    {210, 245, 60},  // 8 lime
    {0, 128, 128},   // 9 teal
    {170, 110, 40},  // 10 brown
}};

/// Rank `rank`'s colour (1-based; 0 reads as 1); ranks past the palette's ten reuse it in order.
inline const std::array<std::uint8_t, 3>& rankColour(std::size_t rank) {
  return kRankPalette[(rank == 0 ? 0 : rank - 1) % kRankPalette.size()];
}

}  // namespace objscan
