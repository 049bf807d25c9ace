// Supernodal block Cholesky: see supernodal.h.
#include "supernodal.h"

#include "flush_subnormals.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <type_traits>

namespace drape::detail {

namespace {
template <class Scalar>
using Dense = Eigen::Matrix<Scalar, Eigen::Dynamic, Eigen::Dynamic>;
template <class Scalar>
using Panel = Eigen::Map<Dense<Scalar>, 0, Eigen::OuterStride<>>;
template <class Scalar>
using ConstPanel = Eigen::Map<const Dense<Scalar>, 0, Eigen::OuterStride<>>;
template <class Scalar>
using Column = Eigen::Map<Eigen::Matrix<Scalar, Eigen::Dynamic, 1>>;
}  // namespace

template <class Scalar>
void SupernodalFactor<Scalar>::analyse(const int* column_start, const int* row_index, std::size_t columns) {
  // Column j + 1 joins j's supernode when it is j's first row below the diagonal and has one
  // row fewer: then its rows are j's without j (a column's rows below it are a subset of
  // those of its first row's column).
  first_.clear();
  for (std::size_t j = 0; j < columns; ++j) {
    const int count = column_start[j + 1] - column_start[j];
    const bool joins = j > 0 && column_start[j] - column_start[j - 1] == count + 1 &&
                       row_index[column_start[j - 1] + 1] == int(j);
    if (!joins) first_.push_back(int(j));
  }
  first_.push_back(int(columns));
  const std::size_t supernodes = first_.size() - 1;
  supernode_of_.resize(columns);
  row_start_.assign(1, 0);
  rows_.clear();
  value_start_.assign(1, 0);
  leading_.resize(supernodes);
  for (std::size_t s = 0; s < supernodes; ++s) {
    const int c0 = first_[s], width = first_[s + 1] - c0;
    for (int j = c0; j < first_[s + 1]; ++j) supernode_of_[std::size_t(j)] = int(s);
    rows_.insert(rows_.end(), row_index + column_start[c0], row_index + column_start[c0 + 1]);
    row_start_.push_back(int(rows_.size()));
    const std::size_t count = std::size_t(row_start_[s + 1] - row_start_[s]);
    leading_[s] = 3 * count;
    value_start_.push_back(value_start_[s] + 9 * count * std::size_t(width));
  }
  entry_offset_.resize(std::size_t(column_start[columns]));
  for (std::size_t j = 0; j < columns; ++j) {
    const std::size_t s = std::size_t(supernode_of_[j]), local = j - std::size_t(first_[s]);
    for (int k = column_start[j]; k < column_start[j + 1]; ++k)
      entry_offset_[std::size_t(k)] =
          value_start_[s] + 3 * local * leading_[s] + 3 * (local + std::size_t(k - column_start[j]));
  }
  value_.assign(value_start_.back(), Scalar(0));
  group_start_.assign(1, 0);
  group_target_.clear();
  group_begin_.clear();
  relative_start_.clear();
  relative_.clear();
  std::size_t largest = 0;
  for (std::size_t s = 0; s < supernodes; ++s) {
    const int* rows = rows_.data() + row_start_[s];
    const int count = row_start_[s + 1] - row_start_[s];
    const int width = first_[s + 1] - first_[s];
    largest = std::max(largest, std::size_t(count - width));
    for (int b = width; b < count;) {
      const int t = supernode_of_[std::size_t(rows[b])];
      group_target_.push_back(t);
      group_begin_.push_back(b);
      relative_start_.push_back(relative_.size());
      const int* target = rows_.data() + row_start_[std::size_t(t)];
      int at = 0;
      for (int a = b; a < count; ++a) {
        while (target[at] != rows[a]) ++at;
        relative_.push_back(at);
      }
      while (b < count && rows[b] < first_[std::size_t(t) + 1]) ++b;
    }
    group_start_.push_back(int(group_target_.size()));
  }
  update_.resize(9 * largest * largest);  // the largest product
  gathered_.resize(3 * columns);
}

template <class Scalar>
void SupernodalFactor<Scalar>::clear() { std::fill(value_.begin(), value_.end(), Scalar(0)); }

namespace {
// f(std::integral_constant<int, W>) for a supernode W = w3 / 3 points wide that has fixed-size
// kernels (one to four points: most supernodes of a grid's ordering); false for a wider one
// (Eigen's blocked kernels).
template <class F>
bool fixed_width(Eigen::Index w3, F&& f) {
  switch (w3) {
    case 3: f(std::integral_constant<int, 1>{}); return true;
    case 6: f(std::integral_constant<int, 2>{}); return true;
    case 9: f(std::integral_constant<int, 3>{}); return true;
    case 12: f(std::integral_constant<int, 4>{}); return true;
    default: return false;
  }
}

// The N × N lower triangle L at the top of a panel (leading dimension ld) → L⁻¹, its upper
// triangle zeroed: column j of L⁻¹ by forward substitution on e_j, all sizes fixed, the
// pivots' reciprocals first (independent divisions, not a chain of them). Only the solves
// read a diagonal block once its supernode is factored; with L⁻¹ there, a triangular solve
// is a product.
template <int N, class Scalar>
void invert_lower(Scalar* l, Eigen::Index ld) {
  Scalar reciprocal[N];
  for (int i = 0; i < N; ++i) reciprocal[i] = Scalar(1) / l[i + i * ld];
  Scalar inverse[N][N] = {};  // [column][row]
  for (int j = 0; j < N; ++j) {
    inverse[j][j] = reciprocal[j];
    for (int i = j + 1; i < N; ++i) {
      Scalar sum = 0;
      for (int k = j; k < i; ++k) sum += l[i + k * ld] * inverse[j][k];
      inverse[j][i] = -sum * reciprocal[i];
    }
  }
  for (int j = 0; j < N; ++j)
    for (int i = 0; i < N; ++i) l[i + j * ld] = inverse[j][i];
}
}  // namespace

// Up to this many rows below a supernode its update is the whole product, both triangles:
// Eigen's triangular product costs more than the other half below about that size.
constexpr Eigen::Index kWholeProduct = 96;

template <class Scalar>
bool SupernodalFactor<Scalar>::factor() {
  const FlushSubnormals flush;
  const std::size_t supernodes = first_.size() - 1;
  for (std::size_t s = 0; s < supernodes; ++s) {
    const int c0 = first_[s], width = first_[s + 1] - c0;
    const int* rows = rows_.data() + row_start_[s];
    const int count = row_start_[s + 1] - row_start_[s];
    const Eigen::Index ld = Eigen::Index(leading_[s]);
    Panel<Scalar> panel(value_.data() + value_start_[s], ld, 3 * width, Eigen::OuterStride<>(ld));
    const Eigen::Index w3 = 3 * width;
    auto diagonal = panel.topLeftCorner(w3, w3);
    Eigen::LLT<Eigen::Ref<Dense<Scalar>>, Eigen::Lower> llt(diagonal);
    // LLT refuses a pivot ≤ 0 but passes NaN and ∞ (a matrix beyond float's range)
    if (llt.info() != Eigen::Success || !diagonal.diagonal().allFinite()) return false;
    if (count > width) {
      auto below = panel.bottomRows(ld - w3);
      diagonal.template triangularView<Eigen::Lower>().transpose().template solveInPlace<Eigen::OnTheRight>(below);
      // Right-looking: the rows below times themselves, subtracted at once from the later
      // supernodes' panels (the lower triangle, one group of rows at a time). Each
      // supernode's update is one product, not one per later supernode it reaches.
      const Eigen::Index m = ld - w3;
      Eigen::Map<Dense<Scalar>> product(update_.data(), m, m);
      if (m <= kWholeProduct)
        product.noalias() = below * below.transpose();
      else
        product.template triangularView<Eigen::Lower>() = below * below.transpose();
      for (int g = group_start_[s]; g < group_start_[s + 1]; ++g) {
        const std::size_t t = std::size_t(group_target_[std::size_t(g)]);
        const int begin = group_begin_[std::size_t(g)];
        const int end = g + 1 < group_start_[s + 1] ? group_begin_[std::size_t(g) + 1] : count;
        const int* relative = relative_.data() + relative_start_[std::size_t(g)];  // rows begin, begin + 1, …
        const std::size_t tld = leading_[t];
        Scalar* target = value_.data() + value_start_[t];
        for (int b = begin; b < end; ++b) {
          const std::size_t column = 3 * std::size_t(rows[b] - first_[t]);
          for (int c = 0; c < 3; ++c) {
            Scalar* into = target + (column + std::size_t(c)) * tld;
            const Scalar* from = product.col(3 * (b - width) + c).data();
            for (int r = c; r < 3; ++r) into[3 * relative[b - begin] + r] -= from[3 * (b - width) + r];  // (lower)
            for (int a = b + 1; a < count; ++a) {
              Scalar* t3 = into + 3 * relative[a - begin];
              const Scalar* u = from + 3 * (a - width);
              t3[0] -= u[0];
              t3[1] -= u[1];
              t3[2] -= u[2];
            }
          }
        }
      }
    }
    fixed_width(w3, [&](auto w) { invert_lower<3 * decltype(w)::value>(panel.data(), ld); });  // for solve()
  }
  return true;
}

namespace {
// One supernode's part of the solves with its width fixed at W points (3W columns): most
// supernodes of a grid's ordering are one or two points wide, and Eigen's dynamic-size
// triangular solve and matrix–vector product cost more in dispatch than in arithmetic at
// that size. Fixed sizes give Eigen's coefficient-wise kernels, vectorised along the panel's
// rows (forward) or its columns (backward), with nothing dispatched at run time. The
// diagonal block holds its inverse (factor()), so the triangular solve is a product.
template <int W, class Scalar>
void forward_fixed(const Scalar* panel, Eigen::Index ld, Scalar* x, Scalar* own_x, const int* rows, int count,
                   Scalar* gathered) {
  using Own = Eigen::Map<Eigen::Matrix<Scalar, 3 * W, 1>>;
  using Diagonal = Eigen::Map<const Eigen::Matrix<Scalar, 3 * W, 3 * W>, 0, Eigen::OuterStride<>>;
  using Below = Eigen::Map<const Eigen::Matrix<Scalar, Eigen::Dynamic, 3 * W>, 0, Eigen::OuterStride<>>;
  Own own(own_x);
  own = Diagonal(panel, Eigen::OuterStride<>(ld)).lazyProduct(own).eval();  // the diagonal block's inverse (factor())
  if (count == 0) return;
  Column<Scalar> product(gathered, 3 * count);
  product.noalias() = Below(panel + 3 * W, 3 * count, 3 * W, Eigen::OuterStride<>(ld)).lazyProduct(own);
  for (int i = 0; i < count; ++i)
    for (int r = 0; r < 3; ++r) x[3 * rows[i] + r] -= gathered[3 * i + r];
}

template <int W, class Scalar>
void backward_fixed(const Scalar* panel, Eigen::Index ld, const Scalar* x, Scalar* own_x, const int* rows, int count,
                    Scalar* gathered) {
  using Own = Eigen::Map<Eigen::Matrix<Scalar, 3 * W, 1>>;
  using Diagonal = Eigen::Map<const Eigen::Matrix<Scalar, 3 * W, 3 * W>, 0, Eigen::OuterStride<>>;
  using Below = Eigen::Map<const Eigen::Matrix<Scalar, Eigen::Dynamic, 3 * W>, 0, Eigen::OuterStride<>>;
  Own own(own_x);
  if (count > 0) {
    for (int i = 0; i < count; ++i)
      for (int r = 0; r < 3; ++r) gathered[3 * i + r] = x[3 * rows[i] + r];
    const Column<Scalar> values(gathered, 3 * count);
    own.noalias() -= Below(panel + 3 * W, 3 * count, 3 * W, Eigen::OuterStride<>(ld)).transpose().lazyProduct(values);
  }
  own = Diagonal(panel, Eigen::OuterStride<>(ld)).transpose().lazyProduct(own).eval();
}

}  // namespace

template <class Scalar>
void SupernodalFactor<Scalar>::solve(Scalar* x) const {
  const std::size_t supernodes = first_.size() - 1;
  // supernode s: its panel, x at its columns, its rows below them
  struct Part {
    const ConstPanel<Scalar> panel;
    Column<Scalar> own;
    const int* rows;
    int count;
  };
  auto part = [&](std::size_t s) {
    const int width = first_[s + 1] - first_[s];
    const Eigen::Index ld = Eigen::Index(leading_[s]);
    return Part{ConstPanel<Scalar>(value_.data() + value_start_[s], ld, 3 * width, Eigen::OuterStride<>(ld)),
                Column<Scalar>(x + 3 * first_[s], 3 * width), rows_.data() + row_start_[s] + width,
                row_start_[s + 1] - row_start_[s] - width};
  };
  Column<Scalar> gathered(gathered_.data(), Eigen::Index(gathered_.size()));
  for (std::size_t s = 0; s < supernodes; ++s) {  // L y = b
    Part p = part(s);
    const Eigen::Index w3 = p.own.size();
    if (fixed_width(w3, [&](auto w) {
          forward_fixed<decltype(w)::value>(p.panel.data(), p.panel.outerStride(), x, p.own.data(), p.rows, p.count,
                                        gathered.data());
        }))
      continue;
    p.panel.topLeftCorner(w3, w3).template triangularView<Eigen::Lower>().solveInPlace(p.own);
    if (p.count == 0) continue;
    gathered.head(3 * p.count).noalias() = p.panel.bottomRows(3 * p.count) * p.own;
    for (int i = 0; i < p.count; ++i)
      for (int r = 0; r < 3; ++r) x[3 * p.rows[i] + r] -= gathered[3 * i + r];
  }
  for (std::size_t s = supernodes; s-- > 0;) {  // Lᵀ x = y
    Part p = part(s);
    const Eigen::Index w3 = p.own.size();
    if (fixed_width(w3, [&](auto w) {
          backward_fixed<decltype(w)::value>(p.panel.data(), p.panel.outerStride(), x, p.own.data(), p.rows, p.count,
                                        gathered.data());
        }))
      continue;
    if (p.count > 0) {
      for (int i = 0; i < p.count; ++i)
        for (int r = 0; r < 3; ++r) gathered[3 * i + r] = x[3 * p.rows[i] + r];
      p.own.noalias() -= p.panel.bottomRows(3 * p.count).transpose() * gathered.head(3 * p.count);
    }
    p.panel.topLeftCorner(w3, w3).template triangularView<Eigen::Lower>().transpose().solveInPlace(p.own);
  }
}

template class SupernodalFactor<double>;
template class SupernodalFactor<float>;

}  // namespace drape::detail
