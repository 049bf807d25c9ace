// Supernodal block Cholesky: see supernodal.h.
#include "supernodal.h"

#include "flush_subnormals.h"

#include <Eigen/Cholesky>
#include <Eigen/Core>
#include <algorithm>
#include <limits>
#include <tbb/parallel_invoke.h>
#include <tbb/task_arena.h>
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
void SupernodalFactor<Scalar>::analyse(const int* column_start, const int* row_index, std::size_t columns,
                                       double split_from) {
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
  split_groups(split_from);
}

// The two groups and the top (supernodal.h): from the roots down, the subtree of most work
// joins the top and its children take its place, until the subtrees left can be dealt to
// two groups (the heaviest first, each to the lighter group) within an eighth of each
// other. None when the whole factor is below split_from or no such split leaves the top
// under half the work.
template <class Scalar>
void SupernodalFactor<Scalar>::split_groups(double split_from) {
  const std::size_t supernodes = first_.size() - 1;
  for (auto& g : group_) g.clear();
  top_.clear();
  private_start_.clear();
  top_from_.clear();
  private_.clear();
  private_x_.clear();
  second_gathered_.clear();
  second_update_.clear();
  std::vector<int> parent(supernodes, -1);
  std::vector<double> work(supernodes), subtree(supernodes);
  for (std::size_t s = 0; s < supernodes; ++s) {
    const int width = first_[s + 1] - first_[s], count = row_start_[s + 1] - row_start_[s];
    if (count > width) parent[s] = supernode_of_[std::size_t(rows_[std::size_t(row_start_[s] + width)])];
    const double c = 3.0 * width, m = 3.0 * (count - width);
    work[s] = c * c * c / 3 + m * c * c + m * m * c;
  }
  subtree = work;
  double total = 0;
  for (std::size_t s = 0; s < supernodes; ++s) {
    if (parent[s] >= 0) subtree[std::size_t(parent[s])] += subtree[s];
    total += work[s];
  }
  if (total < split_from) return;
  std::vector<std::vector<int>> children(supernodes);
  std::vector<int> frontier;
  for (std::size_t s = 0; s < supernodes; ++s) (parent[s] >= 0 ? children[std::size_t(parent[s])] : frontier).push_back(int(s));
  std::vector<char> in_top(supernodes, 0);
  double top_work = 0;
  std::vector<int> bin(supernodes, -1);
  for (;;) {
    std::sort(frontier.begin(), frontier.end(), [&](int a, int b) {
      return subtree[std::size_t(a)] != subtree[std::size_t(b)] ? subtree[std::size_t(a)] > subtree[std::size_t(b)] : a < b;
    });
    double load[2] = {0, 0};
    for (int r : frontier) {
      const int g = load[1] < load[0] ? 1 : 0;
      bin[std::size_t(r)] = g;
      load[g] += subtree[std::size_t(r)];
    }
    if (frontier.size() >= 2 && std::max(load[0], load[1]) <= 1.125 * std::min(load[0], load[1])) break;
    const int heaviest = frontier.front();
    if (children[std::size_t(heaviest)].empty() || top_work + work[std::size_t(heaviest)] > 0.5 * total) return;
    in_top[std::size_t(heaviest)] = 1;
    top_work += work[std::size_t(heaviest)];
    frontier.erase(frontier.begin());
    frontier.insert(frontier.end(), children[std::size_t(heaviest)].begin(), children[std::size_t(heaviest)].end());
  }
  // every supernode below a frontier root takes its root's group (parents come after children)
  std::vector<int> group(supernodes, -1);
  for (int r : frontier) group[std::size_t(r)] = bin[std::size_t(r)];
  for (std::size_t s = supernodes; s-- > 0;) {
    if (in_top[s] || group[s] >= 0) continue;
    group[s] = group[std::size_t(parent[s])];
  }
  private_start_.assign(supernodes, 0);
  std::size_t size = 0;
  for (std::size_t s = 0; s < supernodes; ++s) {
    if (in_top[s]) {
      top_.push_back(int(s));
      private_start_[s] = size;
      size += value_start_[s + 1] - value_start_[s];
    } else {
      group_[group[s]].push_back(int(s));
    }
  }
  private_.assign(size, Scalar(0));
  second_update_.resize(update_.size());
  top_from_.assign(supernodes, 0);
  for (std::size_t s = 0; s < supernodes; ++s) {
    const int width = first_[s + 1] - first_[s], count = row_start_[s + 1] - row_start_[s] - width;
    const int* below = rows_.data() + row_start_[s] + width;
    int i = 0;  // rows ascending: a supernode's ancestors in its group come before the top's
    while (i < count && !in_top[std::size_t(supernode_of_[std::size_t(below[i])])]) ++i;
    top_from_[s] = i;
  }
  private_x_.assign(3 * std::size_t(first_.back()), Scalar(0));
  second_gathered_.resize(gathered_.size());
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
  if (top_.empty()) {
    for (std::size_t s = 0; s + 1 < first_.size(); ++s)
      if (!factor_supernode(s, update_.data(), false)) return false;
    return true;
  }
  bool made[2] = {true, true};
  auto run = [&](int g) {
    const FlushSubnormals flush_here;  // the mode is the thread's own
    if (g == 1) std::fill(private_.begin(), private_.end(), Scalar(0));
    for (int s : group_[g])
      if (!(made[g] = factor_supernode(std::size_t(s), g == 0 ? update_.data() : second_update_.data(), g == 1))) return;
  };
  // isolated: this thread, waiting with subnormals flushed, takes no other task meanwhile
  // (another sheet's step would then run in this thread's mode, not its own)
  tbb::this_task_arena::isolate([&] { tbb::parallel_invoke([&] { run(0); }, [&] { run(1); }); });
  if (!made[0] || !made[1]) return false;
  for (int t : top_) {
    Scalar* into = value_.data() + value_start_[std::size_t(t)];
    const Scalar* from = private_.data() + private_start_[std::size_t(t)];
    const std::size_t size = value_start_[std::size_t(t) + 1] - value_start_[std::size_t(t)];
    for (std::size_t i = 0; i < size; ++i) into[i] += from[i];
  }
  for (int t : top_)
    if (!factor_supernode(std::size_t(t), update_.data(), false)) return false;
  return true;
}

// Supernode s: its diagonal block factored, the rows below solved, and their product with
// themselves subtracted from the later panels (with `second`, those of the top in private_).
template <class Scalar>
bool SupernodalFactor<Scalar>::factor_supernode(std::size_t s, Scalar* update, bool second) {
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
    Eigen::Map<Dense<Scalar>> product(update, m, m);
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
      const bool to_top = second && begin - width >= top_from_[s];  // a group is in one supernode
      Scalar* target = to_top ? private_.data() + private_start_[t] : value_.data() + value_start_[t];
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
void forward_fixed(const Scalar* panel, Eigen::Index ld, Scalar* own_x, int count, Scalar* gathered) {
  using Own = Eigen::Map<Eigen::Matrix<Scalar, 3 * W, 1>>;
  using Diagonal = Eigen::Map<const Eigen::Matrix<Scalar, 3 * W, 3 * W>, 0, Eigen::OuterStride<>>;
  using Below = Eigen::Map<const Eigen::Matrix<Scalar, Eigen::Dynamic, 3 * W>, 0, Eigen::OuterStride<>>;
  Own own(own_x);
  own = Diagonal(panel, Eigen::OuterStride<>(ld)).lazyProduct(own).eval();  // the diagonal block's inverse (factor())
  if (count == 0) return;
  Column<Scalar> product(gathered, 3 * count);
  product.noalias() = Below(panel + 3 * W, 3 * count, 3 * W, Eigen::OuterStride<>(ld)).lazyProduct(own);
}

template <int W, class Scalar>
void backward_fixed(const Scalar* panel, Eigen::Index ld, Scalar* own_x, int count, const Scalar* gathered) {
  using Own = Eigen::Map<Eigen::Matrix<Scalar, 3 * W, 1>>;
  using Diagonal = Eigen::Map<const Eigen::Matrix<Scalar, 3 * W, 3 * W>, 0, Eigen::OuterStride<>>;
  using Below = Eigen::Map<const Eigen::Matrix<Scalar, Eigen::Dynamic, 3 * W>, 0, Eigen::OuterStride<>>;
  Own own(own_x);
  if (count > 0) {
    const Eigen::Map<const Eigen::Matrix<Scalar, Eigen::Dynamic, 1>> values(gathered, 3 * count);
    own.noalias() -= Below(panel + 3 * W, 3 * count, 3 * W, Eigen::OuterStride<>(ld)).transpose().lazyProduct(values);
  }
  own = Diagonal(panel, Eigen::OuterStride<>(ld)).transpose().lazyProduct(own).eval();
}

}  // namespace

// Supernode s's part of L y = b (forward): its x solved, the rows below it updated, those
// from `top_from` on (the top's rows, for the second group) in x_top instead of x; or of
// Lᵀ x = y (backward): its x less the rows below's share, solved.
template <class Scalar>
void SupernodalFactor<Scalar>::solve_part(std::size_t s, bool backward, Scalar* x, Scalar* x_top, int top_from,
                                          Scalar* gathered) const {
  const int width = first_[s + 1] - first_[s];
  const Eigen::Index ld = Eigen::Index(leading_[s]), w3 = 3 * width;
  const Scalar* panel = value_.data() + value_start_[s];
  Scalar* own = x + 3 * first_[s];
  const int* rows = rows_.data() + row_start_[s] + width;
  const int count = row_start_[s + 1] - row_start_[s] - width;
  const ConstPanel<Scalar> whole(panel, ld, w3, Eigen::OuterStride<>(ld));
  Column<Scalar> own_x(own, w3);
  if (backward) {
    for (int i = 0; i < count; ++i)
      for (int r = 0; r < 3; ++r) gathered[3 * i + r] = x[3 * rows[i] + r];
    if (fixed_width(w3, [&](auto w) { backward_fixed<decltype(w)::value>(panel, ld, own, count, gathered); })) return;
    if (count > 0) own_x.noalias() -= whole.bottomRows(3 * count).transpose() * Column<Scalar>(gathered, 3 * count);
    whole.topLeftCorner(w3, w3).template triangularView<Eigen::Lower>().transpose().solveInPlace(own_x);
    return;
  }
  if (!fixed_width(w3, [&](auto w) { forward_fixed<decltype(w)::value>(panel, ld, own, count, gathered); })) {
    whole.topLeftCorner(w3, w3).template triangularView<Eigen::Lower>().solveInPlace(own_x);
    if (count > 0) Column<Scalar>(gathered, 3 * count).noalias() = whole.bottomRows(3 * count) * own_x;
  }
  for (int i = 0; i < count; ++i) {
    Scalar* into = (i < top_from ? x : x_top) + 3 * rows[i];
    for (int r = 0; r < 3; ++r) into[r] -= gathered[3 * i + r];
  }
}

template <class Scalar>
void SupernodalFactor<Scalar>::solve(Scalar* x) const {
  const std::size_t supernodes = first_.size() - 1;
  constexpr int all = std::numeric_limits<int>::max();  // every row below in x
  if (top_.empty()) {
    for (std::size_t s = 0; s < supernodes; ++s) solve_part(s, false, x, x, all, gathered_.data());
    for (std::size_t s = supernodes; s-- > 0;) solve_part(s, true, x, x, 0, gathered_.data());
    return;
  }
  // The two groups apart (supernodal.h): forward, the second group's updates to the top's
  // rows summed in private_x_ and added in, then the top; backward, the top first, then
  // the groups, which read the top's x and write only their own.
  Scalar* x_top = private_x_.data();
  for (int t : top_) std::fill(x_top + 3 * first_[std::size_t(t)], x_top + 3 * first_[std::size_t(t) + 1], Scalar(0));
  tbb::parallel_invoke(
      [&] {
        for (int s : group_[0]) solve_part(std::size_t(s), false, x, x, all, gathered_.data());
      },
      [&] {
        for (int s : group_[1])
          solve_part(std::size_t(s), false, x, x_top, top_from_[std::size_t(s)], second_gathered_.data());
      });
  for (int t : top_)
    for (int c = 3 * first_[std::size_t(t)]; c < 3 * first_[std::size_t(t) + 1]; ++c) x[c] += x_top[c];
  for (int t : top_) solve_part(std::size_t(t), false, x, x, all, gathered_.data());
  for (auto t = top_.rbegin(); t != top_.rend(); ++t) solve_part(std::size_t(*t), true, x, x, 0, gathered_.data());
  tbb::parallel_invoke(
      [&] {
        for (auto s = group_[0].rbegin(); s != group_[0].rend(); ++s)
          solve_part(std::size_t(*s), true, x, x, 0, gathered_.data());
      },
      [&] {
        for (auto s = group_[1].rbegin(); s != group_[1].rend(); ++s)
          solve_part(std::size_t(*s), true, x, x, 0, second_gathered_.data());
      });
}

template class SupernodalFactor<double>;
template class SupernodalFactor<float>;

}  // namespace drape::detail
