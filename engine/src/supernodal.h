// A sparse Cholesky factor L Lᵀ = A of a matrix in 3×3 blocks (one per pair of points), by
// supernodes: consecutive columns of L whose rows below them are the same (George and Liu's
// fundamental supernodes; on a grid, the separators of the fill-reducing ordering) are held
// as one dense column-major panel, so the factor's work is dense products, Cholesky and
// triangular solves (Eigen's blocked, vectorised kernels) instead of one 3×3 block at a time.
// Right-looking: each supernode in turn factors its diagonal block (its panel holding its
// columns of A less every earlier supernode's update by then), scales the panel below it,
// and subtracts that panel times itself from the later supernodes its rows reach, one
// product per supernode (a left-looking factor, as CHOLMOD's, makes one per pair of
// supernodes, and on a grid's many narrow supernodes those small products cost more than
// their arithmetic). The factor runs with subnormal numbers flushed to zero
// (flush_subnormals.h): a stiff sheet's fill decays below float's smallest normal number.
//
// The symbolic part (analyse) takes the point pattern of L, e.g. local/global's factor
// (local_global.h): column-compressed, rows ascending, the diagonal first in each column.
// It is built once per pattern; the numeric part (factor) runs every step. A large factor
// is split for two threads: two groups of whole subtrees of the supernodes' elimination tree
// factored as two tasks, then the supernodes above them (below, `group_`); the solve runs
// the groups as two tasks too. The arithmetic
// depends only on the pattern and the values, so a factor is the same bit for bit whichever
// thread computes it, provided the buffers' alignment is the same every time: Eigen's
// vector kernels peel a different number of leading elements (another order of sums) at
// another alignment, so every buffer they read, the caller's too, is aligned to at least
// Eigen's largest packet (Aligned below: CacheAligned's 64 bytes, or 2 MiB for a large block,
// a multiple of it).
#pragma once

#include "aligned.h"

#include <Eigen/Core>
#include <cstddef>
#include <vector>

namespace drape::detail {

template <class Scalar>
class SupernodalFactor {
 public:
  using Aligned = std::vector<Scalar, CacheAligned<Scalar>>;

  // The point pattern of L: `columns` columns, column j's rows at row_index[column_start[j] ..
  // column_start[j + 1]). A factor of at least `split_from` multiply-adds is split for two
  // threads (below).
  void analyse(const int* column_start, const int* row_index, std::size_t columns,
               double split_from = kSplitFrom);
  // Whether analyse split the factor in two groups of subtrees and a top.
  bool split() const { return !top_.empty(); }
  static constexpr double kSplitFrom = 4e6;

  // Where A's block of the pattern's entry k (row row_index[k], column j) goes, before
  // factor(): value(r, c) of the block at values()[entry_offset(k) + r + c·leading(j)].
  std::size_t entry_offset(std::size_t k) const { return entry_offset_[k]; }
  std::size_t leading(std::size_t column) const { return leading_[supernode_of_[column]]; }
  std::size_t supernodes() const { return first_.empty() ? 0 : first_.size() - 1; }
  // Zeroes the panels; the caller then writes A's lower blocks into them.
  void clear();
  Scalar* values() { return value_.data(); }

  // A's blocks (written as above) → L in place, except that a panel at most four points
  // wide holds the inverse of its diagonal block, the form solve reads. False when A is
  // not positive definite in this precision (a pivot ≤ 0, or not finite: A beyond its range).
  bool factor();
  // x ← (L Lᵀ)⁻¹ x, 3 values per point, in the pattern's (permuted) order; x aligned as Aligned.
  void solve(Scalar* x) const;

 private:
  std::vector<int> first_;                  // per supernode: its first column; one more at the end
  std::vector<int> row_start_, rows_;       // per supernode: its rows (its own columns first)
  std::vector<std::size_t> value_start_;    // per supernode: its panel, 3·rows × 3·columns
  std::vector<std::size_t> leading_;        // per supernode: 3·rows
  std::vector<int> supernode_of_;           // per column
  std::vector<std::size_t> entry_offset_;   // per entry of the point pattern
  Aligned value_;
  // Where a supernode's update goes: its rows below its columns, in runs that fall in one
  // later supernode's columns (a group), each with its target, its first row, and the
  // positions in the target's rows of its rows from there down (rows_ ascending, so they
  // are a subset of the target's rows).
  std::vector<int> group_start_;                 // per supernode, into the groups
  std::vector<int> group_target_, group_begin_;  // per group; its rows end at the next group's
  std::vector<std::size_t> relative_start_;      // per group, into relative_
  std::vector<int> relative_;
  Aligned update_, second_update_;  // the supernode's product, its rows below × themselves (per group)
  mutable Aligned gathered_;
  // Two threads: two groups of whole subtrees of the supernodes' elimination tree, of about
  // equal work, and the top (every supernode above them). A group's updates reach only its
  // own supernodes and the top's; the second group's to the top go to `private_` (the top's
  // panels again, from zero), added to the top's panels once both groups are done, so the
  // sums are the same whichever thread runs which group, or one thread both.
  std::vector<int> group_[2], top_;
  std::vector<int> top_from_;               // per supernode: where the top's rows start among its rows below
  std::vector<std::size_t> private_start_;  // per supernode: its panel in private_ (top ones only)
  Aligned private_;
  mutable Aligned private_x_, second_gathered_;  // the solve's, for the second group
  void split_groups(double split_from);
  void solve_part(std::size_t s, bool backward, Scalar* x, Scalar* x_top, int top_from, Scalar* gathered) const;
  bool factor_supernode(std::size_t s, Scalar* update, bool second);
};

}  // namespace drape::detail
