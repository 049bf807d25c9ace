// Backward Euler by Vertex Block Descent, after Chen, Liu, Yang and Yuksel, "Vertex Block
// Descent" (SIGGRAPH 2024): the same energy as local/global (local_global.h),
//   ½ (x − x̂)ᵀ M̃ (x − x̂)/dt² + Σ_e ½ k_e (|x_a − x_b| − ℓ_e)² + (anchor energy, eq 8),
// minimised by Gauss–Seidel over points: each point in turn takes one Newton step on its
// own 3 coordinates with the others held (a 3×3 solve, its springs' Hessians with the
// transverse part clamped at 0 so the block stays positive definite). Points are grouped
// by colour so that no two points of a colour share a spring (a 4-neighbour grid needs two:
// red–black; with shear diagonals, which are springs here too, four); a colour's points are
// independent, so they run in parallel, and the result does not depend on the thread count.
// Fixed iteration budget (vertex_block_iterations). Bending stays held at the start of the
// step: its triples join points two apart, which share a red–black colour.
#pragma once

#include <vector>

#include "local_global.h"

namespace drape::detail {

struct VertexBlockScratch {
  LocalGlobalScratch step;  // the shared backward-Euler set-up (no factor)
  std::shared_ptr<const void> topology;  // the adjacency below was built for it
  std::vector<std::uint32_t> neighbour_start, neighbour, neighbour_spring;  // per point, CSR
  std::vector<std::uint32_t> anchor_start, anchor_index;                    // per point, CSR
  std::vector<std::uint32_t> anchor_key;                                    // anchors.point it was built for
  std::vector<std::vector<std::uint32_t>> colours;                          // points of each colour, ascending
};

template <class Real>
void vertex_block_step(Sheet<Real>& sheet, const StepParams<Real>& params);

}  // namespace drape::detail
