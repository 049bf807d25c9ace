// Where two sheets pass through each other (World::sheet_crossings): an edge of one
// surface crossing a triangle of the other, each cell split into the two triangles the
// contacts use, (i,j)(i,j+1)(i+1,j+1) and (i,j)(i+1,j+1)(i+1,j). A diagnostic for a frame,
// not a step: exact orientation tests in double over the sheets' boxes.
#pragma once

#include <cstddef>
#include <cstdint>

#include "contacts.h"

namespace drape::detail {

struct Crossings {
  std::size_t count = 0;  // edge–triangle crossings, either sheet's edges through the other's triangles
  // Of the first crossing found (row order of a's points, then of b's): the point of a and
  // the point of b nearest where the edge meets the triangle.
  std::uint32_t point_a = 0, point_b = 0;
};

// The crossings of a and b (a == b: the sheet's edges through its own triangles, those of
// the cells that share a point with the edge's cell left out). Boxes made from the positions
// now.
template <class Real>
Crossings sheet_crossings(const Sheet<Real>& a, const SheetBoxes<Real>& boxes_a, const Sheet<Real>& b,
                          const SheetBoxes<Real>& boxes_b);

}  // namespace drape::detail
