// A sparse Cholesky factor L Lᵀ = A of a matrix in 3×3 blocks (one per pair of points), by
// supernodes: consecutive columns of L whose rows below them are the same (George and Liu's
// fundamental supernodes; on a grid, the separators of the fill-reducing ordering) are held
// as one dense column-major panel, so the factor's work is dense products, Cholesky and
// triangular solves (Eigen's blocked, vectorised kernels) instead of one 3×3 block at a time.
// Left-looking, as in CHOLMOD's supernodal factor (Davis and Hager): a supernode gathers its
// columns of A, subtracts the products of every earlier supernode with rows in its columns,
// then factors its diagonal block and scales the panel below it.
//
// The symbolic part (analyse) takes the point pattern of L, e.g. local/global's factor
// (local_global.h): column-compressed, rows ascending, the diagonal first in each column.
// It is built once per pattern; the numeric part (factor) runs every step. The arithmetic
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
  // column_start[j + 1]).
  void analyse(const int* column_start, const int* row_index, std::size_t columns);

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
  // the factor's work: a supernode's rows → rows of its panel, the lists of earlier
  // supernodes waiting for a later one (by their next row), the products they subtract
  std::vector<int> map_, head_, next_, position_;
  Aligned update_;
  mutable Aligned gathered_;
};

}  // namespace drape::detail
