// The implicit integrators' solves against independent references on small sheets: implicit
// Euler's step against a dense solve of Baraff & Witkin's system whose Jacobian is taken by
// finite differences of a hand-written force, local/global's step against the backward-Euler
// equations themselves, and the convergence report of both.
#include <drape/drape.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <memory>
#include <Eigen/SparseCholesky>
#include <cmath>
#include <random>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

#include "flush_subnormals.h"
#include "local_global.h"
#include "supernodal.h"

namespace {

using drape::Integrator;

// A 5×4-cell sheet, stretched 10 % and ruffled so every spring is longer than its rest
// length (no compressed spring: the engine's clamp of their transverse stiffness stays out
// of the comparison), with damping, two anchors, one pin and gravity.
drape::SheetDef small_sheet(double stiffness) {
  drape::SheetDef d;
  d.m = 4;
  d.n = 5;
  d.width = 1.0;
  d.height = 0.8;
  d.mass = 0.6;
  d.stiffness = stiffness;
  d.stiffness_regions = {{0, 2, 0, 3, 3 * stiffness}};
  d.rest_length_h = 0.9 * 0.2;
  d.rest_length_v = 0.9 * 0.2;
  d.damping = 0.05;
  d.anchors = drape::anchors_at(std::vector<std::uint32_t>{5, 29}, 40.0);
  d.pins = {0};
  return d;
}

struct State {
  std::vector<double> x, v;  // 3 per point, interleaved
};

void ruffle(drape::World& world, drape::SheetId id) {
  auto st = world.state(id);
  for (std::size_t p = 0; p < st.size(); ++p) {
    if (p == 0) continue;  // the pin
    st.z[p] += 0.02 * std::sin(1.3 * double(p));
    st.vx[p] = 0.3 * std::cos(0.7 * double(p));
    st.vy[p] = -0.2 * std::sin(2.1 * double(p));
    st.vz[p] = 0.5 * std::cos(1.9 * double(p));
  }
}

State read(const drape::World& world, drape::SheetId id) {
  const auto v = world.view(id);
  State s;
  for (std::size_t p = 0; p < v.size(); ++p) {
    s.x.insert(s.x.end(), {v.x[p], v.y[p], v.z[p]});
    s.v.insert(s.v.end(), {v.vx[p], v.vy[p], v.vz[p]});
  }
  return s;
}

// The sheet's forces written out from eqs (6) and (8), without the engine: springs between
// grid neighbours, anchors to their targets, damping −c·v, gravity m·g.
struct Forces {
  drape::SheetDef d;
  std::vector<double> anchor_target;  // 3 per anchor
  double g = -9.81;

  std::size_t points() const { return drape::point_count(d.m, d.n); }
  double mass() const { return d.mass / double(points()); }
  double stiffness(std::uint32_t i0, std::uint32_t j0, std::uint32_t i1, std::uint32_t j1) const {
    const auto& r = d.stiffness_regions[0];
    const bool inside = std::max(i0, i1) <= r.row_end && std::max(j0, j1) <= r.col_end;
    return inside ? r.stiffness : d.stiffness;
  }
  // spring and anchor forces at x (no damping, no gravity)
  std::vector<double> elastic(const std::vector<double>& x) const {
    std::vector<double> f(x.size(), 0.0);
    auto spring = [&](std::uint32_t a, std::uint32_t b, double k, double rest) {
      double dx[3], len2 = 0;
      for (int r = 0; r < 3; ++r) {
        dx[r] = x[3 * a + r] - x[3 * b + r];
        len2 += dx[r] * dx[r];
      }
      const double len = std::sqrt(len2);
      for (int r = 0; r < 3; ++r) {
        f[3 * a + r] -= k * (len - rest) * dx[r] / len;
        f[3 * b + r] += k * (len - rest) * dx[r] / len;
      }
    };
    for (std::uint32_t i = 0; i <= d.m; ++i)
      for (std::uint32_t j = 0; j <= d.n; ++j) {
        const auto p = drape::point_index(d.n, i, j);
        if (j < d.n) spring(p, drape::point_index(d.n, i, j + 1), stiffness(i, j, i, j + 1), *d.rest_length_h);
        if (i < d.m) spring(p, drape::point_index(d.n, i + 1, j), stiffness(i, j, i + 1, j), *d.rest_length_v);
      }
    for (std::size_t k = 0; k < d.anchors.size(); ++k)
      for (int r = 0; r < 3; ++r)
        f[3 * d.anchors[k].point + r] += d.anchors[k].stiffness * (anchor_target[3 * k + r] - x[3 * d.anchors[k].point + r]);
    return f;
  }
};

Forces forces_of(const drape::World& world, drape::SheetId id, const drape::SheetDef& d) {
  Forces f{d, {}};
  const auto v = world.view(id);  // anchors hold their points' initial positions
  for (const auto& a : d.anchors) f.anchor_target.insert(f.anchor_target.end(), {v.x[a.point], v.y[a.point], v.z[a.point]});
  return f;
}

// One step of `wd` on small_sheet(stiffness), ruffled: the states around it, the sheet's
// forces written out, and the engine's report of the solve.
struct OneStep {
  Forces forces;
  State before, after;
  drape::World::SolverStats stats;
};

// The positions implicit Euler's kept Cholesky factor was made at: x, y, z of every point
// after the guess in its integrator memory (ImplicitMemory, implicit.cpp).
State factor_positions(const drape::World& world, drape::SheetId id) {
  const auto memory = world.integrator_memory(id);
  const std::size_t count = world.view(id).size();
  State s;
  for (std::size_t p = 0; p < count; ++p)
    s.x.insert(s.x.end(), {memory[3 * count + p], memory[4 * count + p], memory[5 * count + p]});
  return s;
}

// With `kept`, the step is preconditioned by a factor kept from an earlier step: the sheet
// steps once from the ruffled state (its factor is made there), goes back to that state
// moved by 1e-5 m per point, and the measured step starts from there.
OneStep step_once(const drape::WorldDef& wd, double stiffness, bool kept = false) {
  const drape::SheetDef d = small_sheet(stiffness);
  drape::World world(wd);
  const auto id = world.add_sheet(d);
  OneStep s{forces_of(world, id, d), {}, {}, {}};
  ruffle(world, id);
  if (kept) {
    const State start = read(world, id);
    EXPECT_TRUE(world.step(1).ok());
    auto st = world.state(id);
    for (std::size_t p = 0; p < st.size(); ++p) {
      st.x[p] = start.x[3 * p];
      st.y[p] = start.x[3 * p + 1];
      st.z[p] = start.x[3 * p + 2] + (p == 0 ? 0.0 : 1e-5 * std::cos(double(p)));
      st.vx[p] = start.v[3 * p];
      st.vy[p] = start.v[3 * p + 1];
      st.vz[p] = start.v[3 * p + 2];
    }
  }
  s.before = read(world, id);
  EXPECT_TRUE(world.step(1).ok());
  s.after = read(world, id);
  s.stats = world.solver_stats(id);
  if (kept && wd.cg_preconditioner == drape::Preconditioner::Cholesky) {  // the kept factor served
    EXPECT_NE(factor_positions(world, id).x, s.before.x);
  }
  return s;
}

// One implicit Euler step of the engine against Baraff & Witkin's system solved densely:
//   (M + h·C − h²·K) Δv = h·(f + M g − C v + h·K·v),  K = ∂f/∂x by central differences,
// with the pinned point's rows and columns removed (its Δv is zero).
// Both preconditioners, on a soft and a stiff sheet.
void expect_dense_solve(drape::Preconditioner preconditioner, double stiffness, bool kept = false) {
  SCOPED_TRACE(std::string(drape::preconditioner_name(preconditioner)) + ", k = " + std::to_string(stiffness) +
               (kept ? ", kept factor" : ""));
  drape::WorldDef wd;
  wd.integrator = Integrator::ImplicitEuler;
  wd.dt = 1.0 / 60;
  wd.cg_tolerance = 1e-13;
  wd.cg_max_iterations = 10000;
  wd.cg_preconditioner = preconditioner;
  const auto [forces, before, after, stats] = step_once(wd, stiffness, kept);
  const drape::SheetDef& d = forces.d;
  EXPECT_TRUE(stats.converged);
  EXPECT_LE(stats.relative_residual, 1e-13);
  // an exact factor leaves CG one iteration, two with rounding; the float factor, each
  // iteration shrinking the residual by its rounding error, a few to 1e-13 on this small
  // sheet; a wrong one would still converge (CG corrects it) but take many. A kept factor
  // serves within implicit.cpp's budget of 6 iterations or is replaced.
  if (preconditioner == drape::Preconditioner::Cholesky) {
    EXPECT_LE(stats.iterations, kept ? 6 : 5);
  }

  const std::size_t n3 = 3 * forces.points();
  const double h = wd.dt, m = forces.mass(), c = d.damping;
  Eigen::MatrixXd k(n3, n3);
  const double step = 1e-6;
  for (std::size_t col = 0; col < n3; ++col) {
    std::vector<double> plus = before.x, minus = before.x;
    plus[col] += step;
    minus[col] -= step;
    const auto fp = forces.elastic(plus), fm = forces.elastic(minus);
    for (std::size_t row = 0; row < n3; ++row) k(Eigen::Index(row), Eigen::Index(col)) = (fp[row] - fm[row]) / (2 * step);
  }
  const std::vector<double> f = forces.elastic(before.x);
  const Eigen::Map<const Eigen::VectorXd> v(before.v.data(), Eigen::Index(n3));
  Eigen::MatrixXd a = -h * h * k;
  Eigen::VectorXd b = h * h * (k * v);
  for (std::size_t q = 0; q < n3; ++q) {
    a(Eigen::Index(q), Eigen::Index(q)) += m + h * c;
    b[Eigen::Index(q)] += h * (f[q] - c * before.v[q] + (q % 3 == 2 ? m * forces.g : 0.0));
  }
  // the pin (point 0): drop its three rows and columns
  const Eigen::Index free = Eigen::Index(n3 - 3);
  const Eigen::VectorXd dv = a.bottomRightCorner(free, free).ldlt().solve(b.tail(free));
  double worst = 0, scale = 0;
  for (Eigen::Index q = 0; q < free; ++q) {
    const double engine = after.v[std::size_t(q + 3)] - before.v[std::size_t(q + 3)];
    worst = std::max(worst, std::abs(engine - dv[q]));
    scale = std::max(scale, std::abs(dv[q]));
  }
  EXPECT_LT(worst, 1e-6 * scale) << "largest Δv " << scale;
  for (std::size_t q = 0; q < n3; ++q)  // x advances with the new velocity
    EXPECT_NEAR(after.x[q], before.x[q] + h * after.v[q], 1e-12);
}

TEST(ImplicitEuler, StepSolvesTheLinearisedSystemLikeADenseSolve) {
  for (auto preconditioner : {drape::Preconditioner::BlockJacobi, drape::Preconditioner::Cholesky})
    for (double stiffness : {800.0, 1e5}) expect_dense_solve(preconditioner, stiffness);
}

// A step preconditioned by a Cholesky factor of an earlier step's matrix (the springs since
// turned a little) still solves the step's own system to the tolerance: the same dense
// comparison, and the memory shows that the kept factor was the one used.
TEST(ImplicitEuler, KeptFactorStepSolvesTheLinearisedSystemLikeADenseSolve) {
  for (double stiffness : {800.0, 1e5}) expect_dense_solve(drape::Preconditioner::Cholesky, stiffness, true);
}

// The supernodal factor (supernodal.h) alone, against Eigen's dense Cholesky: a 12×10 grid
// of points with 4-neighbour, diagonal and reach-two couplings (springs, shear, bending),
// random 3×3 blocks made positive definite by a dominant diagonal. Its point pattern comes
// from Eigen's simplicial analysis under AMD, as in the engine (local_global.h); the grid's
// separators must come out as supernodes of several columns. A matrix that is not positive
// definite is refused. In float (implicit Euler's first factor) the solve is as close as
// float's rounding allows: this matrix's condition number is small.
template <class Scalar>
void expect_factor_solves_like_dense(double tolerance, double split_from = drape::detail::SupernodalFactor<Scalar>::kSplitFrom,
                                     int rows = 12, int cols = 10) {
  const int points = rows * cols;
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1, 1);
  Eigen::MatrixXd a = Eigen::MatrixXd::Zero(3 * points, 3 * points);
  std::vector<Eigen::Triplet<double, int>> graph;
  auto couple = [&](int p, int q) {
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) {
        const double w = u(rng);
        a(3 * p + r, 3 * q + c) += w;
        a(3 * q + c, 3 * p + r) += w;
      }
    graph.emplace_back(std::max(p, q), std::min(p, q), 1.0);
  };
  for (int i = 0; i < rows; ++i)
    for (int j = 0; j < cols; ++j) {
      const int p = i * cols + j;
      if (j + 1 < cols) couple(p, p + 1);
      if (i + 1 < rows) couple(p, p + cols);
      if (i + 1 < rows && j + 1 < cols) couple(p, p + cols + 1);
      if (j + 2 < cols) couple(p, p + 2);
      if (i + 2 < rows) couple(p, p + 2 * cols);
      graph.emplace_back(p, p, 40.0);
    }
  a += 40.0 * Eigen::MatrixXd::Identity(3 * points, 3 * points);
  Eigen::SparseMatrix<double, Eigen::ColMajor, int> pattern(points, points);
  pattern.setFromTriplets(graph.begin(), graph.end());
  const Eigen::SimplicialLLT<decltype(pattern), Eigen::Lower, Eigen::AMDOrdering<int>> symbolic(pattern);
  const auto& l = symbolic.matrixL().nestedExpression();
  const Eigen::VectorXi order = symbolic.permutationP().indices();  // point → column of L
  std::vector<int> point_of(points);
  for (int p = 0; p < points; ++p) point_of[std::size_t(order[p])] = p;

  drape::detail::SupernodalFactor<Scalar> factor;
  factor.analyse(l.outerIndexPtr(), l.innerIndexPtr(), std::size_t(points), split_from);
  EXPECT_LT(factor.supernodes(), std::size_t(points) * 3 / 4);
  EXPECT_EQ(factor.split(), split_from == 0);  // this grid is below the default size
  auto write = [&](const Eigen::MatrixXd& m) {
    factor.clear();
    for (int j = 0; j < points; ++j)
      for (int k = l.outerIndexPtr()[j]; k < l.outerIndexPtr()[j + 1]; ++k) {
        const int pi = point_of[std::size_t(l.innerIndexPtr()[k])], pj = point_of[std::size_t(j)];
        Scalar* block = factor.values() + factor.entry_offset(std::size_t(k));
        for (int r = 0; r < 3; ++r)
          for (int c = 0; c < 3; ++c) block[std::size_t(r) + std::size_t(c) * factor.leading(std::size_t(j))] = Scalar(m(3 * pi + r, 3 * pj + c));
      }
  };
  write(a);
  ASSERT_TRUE(factor.factor());
  Eigen::VectorXd b(3 * points);
  for (auto& x : b) x = u(rng);
  typename drape::detail::SupernodalFactor<Scalar>::Aligned x(3 * std::size_t(points));
  for (int p = 0; p < points; ++p)
    for (int r = 0; r < 3; ++r) x[3 * std::size_t(order[p]) + std::size_t(r)] = Scalar(b[3 * p + r]);
  factor.solve(x.data());
  const Eigen::LLT<Eigen::MatrixXd> llt(a);
  Eigen::VectorXd dense(3 * points);
  dense = llt.solve(b);
  double worst = 0;
  for (int p = 0; p < points; ++p)
    for (int r = 0; r < 3; ++r) worst = std::max(worst, std::abs(double(x[3 * std::size_t(order[p]) + std::size_t(r)]) - dense[3 * p + r]));
  EXPECT_LT(worst, tolerance * dense.cwiseAbs().maxCoeff());

  Eigen::MatrixXd indefinite = a;
  indefinite(3 * (points - 1), 3 * (points - 1)) = -1.0;
  write(indefinite);
  EXPECT_FALSE(factor.factor());
  // beyond float's range (3.4e38) the float factor must refuse, not return ∞ or NaN
  write(1e37 * a);
  EXPECT_EQ(factor.factor(), (std::is_same_v<Scalar, double>));
}

TEST(Supernodal, FactorSolvesLikeADenseCholeskyOnAGrid) {
  expect_factor_solves_like_dense<double>(1e-12);
  expect_factor_solves_like_dense<float>(1e-5);
}

// The same factor split for two threads (supernodal.h): two groups of subtrees, the second's
// updates to the top summed apart, then the top.
TEST(Supernodal, SplitFactorSolvesLikeADenseCholeskyOnAGrid) {
  expect_factor_solves_like_dense<double>(1e-12, 0.0, 24, 20);
  expect_factor_solves_like_dense<float>(1e-5, 0.0, 24, 20);
}

// Implicit Euler takes its factor's pattern from the symbolic analysis alone
// (cholesky_pattern, local_global.h): on grids with the couplings the engine makes (4
// neighbours; diagonals; reach two; points cut loose, as pins leave them), it must be the
// pattern of Eigen's numeric simplicial factor in the same ordering, entry for entry.
TEST(Supernodal, SymbolicPatternIsTheNumericFactorsPattern) {
  struct Grid {
    int rows, cols;
    bool diagonals, reach_two;
    int cut_every;  // every this many points has no couplings (0: none)
  };
  for (const Grid g : {Grid{7, 9, false, false, 0}, Grid{16, 16, true, false, 0}, Grid{12, 10, true, true, 0},
                       Grid{20, 13, false, true, 5}, Grid{1, 30, false, false, 0}}) {
    const int points = g.rows * g.cols;
    std::vector<Eigen::Triplet<double, int>> entries;
    std::vector<double> diagonal(std::size_t(points), 1.0);
    auto couple = [&](int p, int q) {
      if (g.cut_every > 0 && (p % g.cut_every == 0 || q % g.cut_every == 0)) return;
      entries.emplace_back(std::max(p, q), std::min(p, q), -0.1);
      diagonal[std::size_t(p)] += 0.1;
      diagonal[std::size_t(q)] += 0.1;
    };
    for (int i = 0; i < g.rows; ++i)
      for (int j = 0; j < g.cols; ++j) {
        const int p = i * g.cols + j;
        if (j + 1 < g.cols) couple(p, p + 1);
        if (i + 1 < g.rows) couple(p, p + g.cols);
        if (g.diagonals && i + 1 < g.rows && j + 1 < g.cols) couple(p, p + g.cols + 1);
        if (g.diagonals && i + 1 < g.rows && j > 0) couple(p, p + g.cols - 1);
        if (g.reach_two && j + 2 < g.cols) couple(p, p + 2);
        if (g.reach_two && i + 2 < g.rows) couple(p, p + 2 * g.cols);
      }
    for (int p = 0; p < points; ++p) entries.emplace_back(p, p, diagonal[std::size_t(p)]);
    drape::detail::LocalGlobalScratch::Matrix lower(points, points);
    lower.setFromTriplets(entries.begin(), entries.end());
    const Eigen::SimplicialLLT<drape::detail::LocalGlobalScratch::Matrix, Eigen::Lower, Eigen::AMDOrdering<int>> numeric(lower);
    ASSERT_EQ(numeric.info(), Eigen::Success);
    const auto& l = numeric.matrixL().nestedExpression();
    std::vector<int> column_start, row_index, permutation;
    drape::detail::cholesky_pattern(lower, column_start, row_index, permutation);
    SCOPED_TRACE(std::to_string(g.rows) + "x" + std::to_string(g.cols));
    EXPECT_EQ(column_start, std::vector<int>(l.outerIndexPtr(), l.outerIndexPtr() + points + 1));
    EXPECT_EQ(row_index, std::vector<int>(l.innerIndexPtr(), l.innerIndexPtr() + l.nonZeros()));
    const auto& order = numeric.permutationP().indices();
    EXPECT_EQ(permutation, std::vector<int>(order.data(), order.data() + points));
  }
}

// The factor runs with subnormals flushed (flush_subnormals.h): while the guard lives, a
// product below float's smallest normal (1.2e-38) is zero and a subnormal operand reads as
// zero; once it goes, the thread's previous mode is back. (Run after the factor's tests in
// this program, the first check also catches a factor that left the mode behind.)
TEST(Supernodal, SubnormalsAreZeroOnlyWhileFlushed) {
  volatile float tiny = 1e-20f;
  const float subnormal = tiny * tiny;  // 1e-40
  ASSERT_GT(subnormal, 0.0f) << "this thread flushes subnormals outside the factor";
  {
    const drape::detail::FlushSubnormals flush;
    if (!drape::detail::FlushSubnormals::kFlushes) GTEST_SKIP() << "no flush mode on this architecture";
    EXPECT_EQ(tiny * tiny, 0.0f);
    volatile float operand = subnormal;
    EXPECT_EQ(operand * 1.0f, 0.0f);
  }
  EXPECT_EQ(tiny * tiny, subnormal);
}

// Implicit Euler at dt = 1/60 s with the Cholesky preconditioner.
drape::WorldDef cholesky_world() {
  drape::WorldDef wd;
  wd.integrator = Integrator::ImplicitEuler;
  wd.dt = 1.0 / 60;
  wd.cg_preconditioner = drape::Preconditioner::Cholesky;
  return wd;
}

// A 16×16 sheet of `mass` hanging from its corners.
drape::SheetDef hanging_sheet(double stiffness, double mass) {
  drape::SheetDef d;
  d.m = d.n = 15;
  d.mass = mass;
  d.stiffness = stiffness;
  d.pins = drape::corner_points(d.m, d.n);
  return d;
}

// Issue 16: every solve reaches its tolerance across k from 1e-2 to 1e8 N/m at dt = 1/60 s
// with the default preconditioner (Auto), on a sheet hanging from its corners, and the
// run stays finite. The residual is the engine's report; the test above checks that
// report against a dense solve.
TEST(ImplicitEuler, EverySolveConvergesFromSoftToStiffSheets) {
  for (double stiffness : {1e-2, 1.0, 1e2, 1e4, 1e6, 1e8}) {
    drape::WorldDef wd;
    wd.integrator = Integrator::ImplicitEuler;
    wd.dt = 1.0 / 60;
    drape::World world(wd);
    const auto id = world.add_sheet(hanging_sheet(stiffness, 1.0));
    const auto report = world.step(30);
    const auto stats = world.solver_stats(id);
    EXPECT_TRUE(report.ok()) << "k = " << stiffness << ": " << drape::describe(report);
    EXPECT_EQ(stats.unconverged_solves, 0u) << "k = " << stiffness;
    EXPECT_TRUE(stats.converged) << "k = " << stiffness;
    EXPECT_LE(stats.relative_residual, wd.cg_tolerance) << "k = " << stiffness;
    EXPECT_TRUE(world.all_finite()) << "k = " << stiffness;
  }
}

// The Cholesky preconditioner factors in float first and in double only when float's does
// not bring CG to its tolerance within 10 iterations (implicit.cpp). Float's factor serves
// even at k = 1e8 N/m with masses 1e6 apart (one or two iterations); it cannot where the
// matrix leaves float's range: k = 1e42 N/m at dt = 1/60 s puts dt²k ≈ 3e38 per spring on
// the diagonal, whose sums pass float's 3.4e38, so the float factor refuses it (the test
// above). With 1e30 kg the matrix is as well conditioned as a 1 kg sheet at k = 1e12 N/m,
// and the double factor must take over and solve every step in one or two iterations, or
// a few with the factor kept from an earlier step (block Jacobi, the last resort, takes
// tens here). The residual is the engine's
// |b − A·Δv|, which no preconditioner enters.
TEST(ImplicitEuler, CholeskyGoesOnInDoubleWhereTheFloatFactorCannotServe) {
  const drape::WorldDef wd = cholesky_world();
  drape::World world(wd);
  const auto id = world.add_sheet(hanging_sheet(1e42, 1e30));
  for (int step = 0; step < 3; ++step) {
    ASSERT_TRUE(world.step(1).ok()) << "step " << step;
    const auto stats = world.solver_stats(id);
    EXPECT_TRUE(stats.converged) << "step " << step;
    EXPECT_LE(stats.iterations, 6) << "step " << step;  // two on a new factor, six at most on a kept one
  }
  EXPECT_EQ(world.solver_stats(id).unconverged_solves, 0u);
  EXPECT_TRUE(world.all_finite());
}

// Auto's rule (Preconditioner::Auto): block Jacobi while dt·ω_max ≤ 10, the factor above.
// Each side of the threshold gives exactly the bits of the preconditioner it names.
TEST(ImplicitEuler, AutoPicksBlockJacobiForSoftAndCholeskyForStiffSheets) {
  auto run = [](drape::Preconditioner preconditioner, double stiffness) {
    drape::WorldDef wd;
    wd.integrator = Integrator::ImplicitEuler;
    wd.dt = 1.0 / 60;
    wd.cg_preconditioner = preconditioner;
    drape::World world(wd);
    const auto id = world.add_sheet(small_sheet(stiffness));
    ruffle(world, id);
    world.step(3);
    const double omega = 2.0 / world.stable_step_estimate(id);
    return std::pair{read(world, id).x, wd.dt * omega};
  };
  const auto [soft, soft_omega_dt] = run(drape::Preconditioner::Auto, 0.2);
  EXPECT_LT(soft_omega_dt, 10.0);
  EXPECT_EQ(soft, run(drape::Preconditioner::BlockJacobi, 0.2).first);
  EXPECT_NE(soft, run(drape::Preconditioner::Cholesky, 0.2).first);
  const auto [stiff, stiff_omega_dt] = run(drape::Preconditioner::Auto, 1e4);
  EXPECT_GT(stiff_omega_dt, 10.0);
  EXPECT_EQ(stiff, run(drape::Preconditioner::Cholesky, 1e4).first);
  EXPECT_NE(stiff, run(drape::Preconditioner::BlockJacobi, 1e4).first);
}

// The factor that preconditions a step is the step's own or one kept from an earlier step
// of the same sheet (implicit.cpp), which depends on the sheet's history only: one or two
// threads (sheets in parallel), frames or single substeps, the same bits.
TEST(ImplicitEuler, CholeskyRunsChangeNoBitWithThreadsOrFrames) {
  auto run = [](int threads, int frames, int substeps) {
    drape::WorldDef wd;
    wd.integrator = Integrator::ImplicitEuler;
    wd.dt = 1.0 / 60;
    wd.threads = threads;
    wd.contact_strength = 0;
    wd.cg_preconditioner = drape::Preconditioner::Cholesky;
    drape::World world(wd);
    std::vector<double> out;
    for (int k = 0; k < 3; ++k) {
      drape::SheetDef d = small_sheet(1e4 * (k + 1));
      d.center = {2.0 * k, 0, 0};
      ruffle(world, world.add_sheet(d));
    }
    for (int f = 0; f < frames; ++f) world.step(substeps);
    for (drape::SheetId id : world.sheets()) {
      const State s = read(world, id);
      out.insert(out.end(), s.x.begin(), s.x.end());
      out.insert(out.end(), s.v.begin(), s.v.end());
    }
    return out;
  };
  const auto one_by_one = run(1, 6, 1);
  EXPECT_EQ(run(1, 2, 3), one_by_one);
  EXPECT_EQ(run(2, 6, 1), one_by_one);
  EXPECT_EQ(run(2, 1, 6), one_by_one);
}

// One sheet large enough that its factor is split for two threads (SupernodalFactor's
// kSplitFrom): its two groups run on both threads or one after the other on one, with the
// same bits.
TEST(ImplicitEuler, SplitFactorChangesNoBitWithThreads) {
  auto run = [](int threads) {
    drape::WorldDef wd = cholesky_world();
    wd.threads = threads;
    drape::World world(wd);
    drape::SheetDef d = small_sheet(1e5);
    d.m = d.n = 31;
    d.stiffness_regions = {{0, 10, 0, 12, 3e5}};
    d.rest_length_h = d.rest_length_v = 0.9 / 31;
    const drape::SheetId id = world.add_sheet(d);
    ruffle(world, id);
    world.step(8);
    const State s = read(world, id);
    std::vector<double> out(s.x.begin(), s.x.end());
    out.insert(out.end(), s.v.begin(), s.v.end());
    return out;
  };
  EXPECT_EQ(run(2), run(1));
}

// A kept factor lives in the integrator memory (the positions and dt it was made at), so a
// run resumed from state and memory, in a fresh world or in one that has stepped (and holds
// another factor), makes the same factor and repeats the uninterrupted run bit for bit.
// Without the factor's part of the memory the resumed run differs (in rounding): the
// factor's age does enter the bits, which is why it is part of the memory.
TEST(ImplicitEuler, ResumedRunRemakesTheKeptFactorBitForBit) {
  const drape::WorldDef wd = cholesky_world();
  auto make = [&] {
    auto world = std::make_unique<drape::World>(wd);
    world->add_sheet(hanging_sheet(1e4, 1.0));
    return world;
  };
  auto uninterrupted = make();
  const drape::SheetId id = uninterrupted->sheets()[0];
  // settling, up to a step whose next one tries the kept factor (no back-off left: the
  // memory's last value but one is zero)
  int steps = 0;
  for (uninterrupted->step(60), steps = 60; steps < 300; uninterrupted->step(1), ++steps) {
    const auto m = uninterrupted->integrator_memory(id);
    if (m[m.size() - 2] == 0 && m[m.size() - 3] != 0 && factor_positions(*uninterrupted, id).x != read(*uninterrupted, id).x) break;
  }
  ASSERT_LT(steps, 300);
  const auto v = uninterrupted->view(id);
  const std::vector<double> x(v.x.begin(), v.x.end()), y(v.y.begin(), v.y.end()), z(v.z.begin(), v.z.end());
  const std::vector<double> vx(v.vx.begin(), v.vx.end()), vy(v.vy.begin(), v.vy.end()), vz(v.vz.begin(), v.vz.end());
  const auto memory = uninterrupted->integrator_memory(id);
  const std::vector<double> full(memory.begin(), memory.end());
  ASSERT_NE(factor_positions(*uninterrupted, id).x, read(*uninterrupted, id).x);  // a kept factor, not this step's
  auto resume = [&](drape::World& world, const std::vector<double>& with) {
    const drape::SheetId to = world.sheets()[0];
    world.set_state(to, {v.m, v.n, x, y, z, vx, vy, vz});
    world.set_integrator_memory(to, with);
    world.set_step_count(uninterrupted->step_count());
    world.step(30);
    return read(world, to);
  };
  auto fresh = make();
  auto stepped = make();
  stepped->step(steps - 1);  // holds a factor of its own
  auto forgotten = make();
  uninterrupted->step(30);
  const State expected = read(*uninterrupted, id);
  const State a = resume(*fresh, full), b = resume(*stepped, full);
  EXPECT_EQ(a.x, expected.x);
  EXPECT_EQ(a.v, expected.v);
  EXPECT_EQ(b.x, expected.x);
  EXPECT_EQ(b.v, expected.v);
  const State c = resume(*forgotten, std::vector<double>(full.begin(), full.begin() + std::ptrdiff_t(3 * v.size())));
  EXPECT_NE(c.x, expected.x);
}

// A new dt changes the matrix: the factor kept for the old one must not precondition the
// new one's first step, which factors its own matrix (one or two iterations: a kept factor
// of the old dt would spend its probe first) and keeps that.
TEST(ImplicitEuler, NewStepSizeMakesANewFactor) {
  const drape::WorldDef wd = cholesky_world();
  drape::World world(wd);
  const auto id = world.add_sheet(hanging_sheet(1e4, 1.0));
  world.step(60);
  for (double dt : {1.0 / 240, 1.0 / 30}) {
    world.set_dt(dt);
    const State before = read(world, id);
    ASSERT_TRUE(world.step(1).ok());
    const auto stats = world.solver_stats(id);
    EXPECT_TRUE(stats.converged) << "dt " << dt;
    EXPECT_LE(stats.iterations, 2) << "dt " << dt;
    EXPECT_EQ(factor_positions(world, id).x, before.x) << "dt " << dt;
    EXPECT_EQ(world.integrator_memory(id)[6 * before.x.size() / 3], dt);
  }
}

// Local/global converges to the backward-Euler step itself: with enough iterations, the
// engine's new state satisfies M(v1 − v0) = h·(f(x1) − C·v1 + M g), x1 = x0 + h·v1, with f
// written out independently, to rounding; and it says so in solver_stats.
void expect_backward_euler_solved(Integrator integrator, int iterations) {
  for (double stiffness : {50.0, 5e3}) {
    drape::WorldDef wd;
    wd.integrator = integrator;
    wd.dt = 1.0 / 60;
    wd.local_global_iterations = iterations;
    wd.vertex_block_iterations = iterations;
    wd.cg_tolerance = 1e-10;
    const auto [forces, before, after, stats] = step_once(wd, stiffness);
    const drape::SheetDef& d = forces.d;
    const double h = wd.dt, m = forces.mass(), c = d.damping;
    const std::vector<double> f = forces.elastic(after.x);
    double worst = 0, scale = 0;
    for (std::size_t q = 3; q < after.x.size(); ++q) {  // every point but the pin
      const double left = m * (after.v[q] - before.v[q]);
      const double right = h * (f[q] - c * after.v[q] + (q % 3 == 2 ? m * forces.g : 0.0));
      worst = std::max(worst, std::abs(left - right));
      scale = std::max(scale, std::abs(left));
      EXPECT_NEAR(after.x[q], before.x[q] + h * after.v[q], 1e-12);
    }
    EXPECT_LT(worst, 1e-8 * scale) << drape::integrator_name(integrator) << " k = " << stiffness
                                   << ", largest momentum change " << scale;
    EXPECT_TRUE(stats.converged) << drape::integrator_name(integrator) << " " << stats.relative_residual;
    EXPECT_EQ(stats.iterations, iterations);
  }
}

TEST(LocalGlobal, EnoughIterationsSolveTheBackwardEulerEquations) {
  expect_backward_euler_solved(Integrator::LocalGlobal, 30000);
}

// Vertex block descent minimises the same energy point by point: enough sweeps reach the
// same backward-Euler step.
TEST(VertexBlockDescent, EnoughIterationsSolveTheBackwardEulerEquations) {
  expect_backward_euler_solved(Integrator::VertexBlockDescent, 30000);
}

// The fixed budget is the knob: more iterations leave a smaller backward-Euler residual on
// a stiff sheet, and a budget too small for the tolerance is reported, per solve and in the
// stability report, without stopping the run.
TEST(LocalGlobal, MoreIterationsLeaveLessResidualAndShortBudgetsAreReported) {
  double previous = INFINITY;
  for (int budget : {1, 4, 16, 64}) {
    drape::WorldDef wd;
    wd.integrator = Integrator::LocalGlobal;
    wd.dt = 1.0 / 60;
    wd.local_global_iterations = budget;
    drape::World world(wd);
    const auto id = world.add_sheet(small_sheet(1e5));
    ruffle(world, id);
    const auto report = world.step(3);
    const auto stats = world.solver_stats(id);
    EXPECT_LT(stats.relative_residual, previous) << budget << " iterations";
    previous = stats.relative_residual;
    if (budget == 1) {
      EXPECT_FALSE(stats.converged);
      EXPECT_EQ(stats.unconverged_solves, 3u);
      EXPECT_TRUE(report.ok());
      EXPECT_EQ(report.unconverged_solves, 3u);
      EXPECT_NE(drape::describe(report).find("3 implicit solves stopped"), std::string::npos) << drape::describe(report);
    }
  }
}

// Implicit Euler's cap: a solve stopped there is not silent.
TEST(ImplicitEuler, SolvesStoppedByTheIterationCapAreReported) {
  drape::WorldDef wd;
  wd.integrator = Integrator::ImplicitEuler;
  wd.dt = 1.0 / 60;
  wd.cg_max_iterations = 2;
  wd.cg_preconditioner = drape::Preconditioner::BlockJacobi;  // the factor needs one iteration
  drape::World world(wd);
  const auto id = world.add_sheet(small_sheet(1e5));
  ruffle(world, id);
  const auto report = world.step(4);
  const auto stats = world.solver_stats(id);
  EXPECT_EQ(stats.iterations, 2);
  EXPECT_FALSE(stats.converged);
  EXPECT_GT(stats.relative_residual, wd.cg_tolerance);
  EXPECT_EQ(stats.unconverged_solves, 4u);
  EXPECT_EQ(report.unconverged_solves, 4u);
}

}  // namespace

namespace {

// Local/global puts bending's constant Hessian into its factored matrix (local_global.h),
// so a stiff bending term no longer limits its step. The strip of
// Bending.CantileverTipDeflectionMatchesBeamTheory (terms_test.cpp: two grid lines, EI =
// k_b h³ each, clamped by two pinned columns) at a frame step, dt = 1/60 s, about 800 times
// the explicit limit of its bending stiffness: it settles to Euler–Bernoulli's tip
// deflection δ = q L⁴ / (8 EI). With bending held explicit, as before, this step blows up.
TEST(LocalGlobal, StiffBendingCantileverMatchesBeamTheoryAtAFrameStep) {
  const std::uint32_t n = 40;
  const double h = 0.025, mass_point = 2.5e-3, g = 9.81, kb = 1e6;
  drape::SheetDef d;
  d.m = 1;
  d.n = n;
  d.width = n * h;
  d.height = 0.02;
  d.stiffness = 2e4;
  d.bending = drape::BendingDef{kb};
  d.point_masses.assign(2 * (n + 1), mass_point);
  d.point_masses[n] = d.point_masses[2 * n + 1] = mass_point / 2;  // the free end carries half a cell
  d.damping = 0.25;
  d.pins = {0, 1, n + 1, n + 2};
  drape::WorldDef wd;
  wd.integrator = Integrator::LocalGlobal;
  wd.dt = 1.0 / 60;
  wd.local_global_iterations = 20;
  drape::World w(wd);
  const auto id = w.add_sheet(d);
  EXPECT_GT(wd.dt, 500 * w.stable_step_estimate(id));
  const double z0 = w.view(id).z[n];
  const auto report = w.step(600);
  ASSERT_TRUE(report.ok()) << drape::describe(report);
  const auto v = w.view(id);
  EXPECT_LT(std::abs(v.vz[n]), 1e-6);  // at rest
  const double sag = z0 - 0.5 * (v.z[n] + v.z[2 * n + 1]);
  const double L = (n - 0.5) * h;           // from the clamp to the tip
  const double q = 2 * mass_point * g / h;  // two rows of points, one every h
  const double EI = 2 * kb * h * h * h;     // two lines
  const double beam = q * L * L * L * L / (8 * EI);
  EXPECT_NEAR(sag, beam, 0.01 * beam);
  // at rest the step is backward Euler's, and says so (its residual is measured against the
  // forces that hold the strip up, not against a vanishing momentum change)
  EXPECT_TRUE(w.solver_stats(id).converged) << w.solver_stats(id).relative_residual;
}

// Shear diagonals are springs of eq (6): local/global and vertex block descent project them
// in their local step like the grid's, so stiff shear is as stable as stiff stretch at a
// frame step. A 16×16 sheet hanging from its corners, k = 1e5 N/m on grid and diagonals,
// dt = 1/60 s (about 300 times the explicit limit): the run stays finite and its springs
// stretch by well under 1 %. With the diagonals held explicit, as before, it blows up.
TEST(LocalGlobal, StiffShearSpringsStayStableAtAFrameStep) {
  for (Integrator integrator : {Integrator::LocalGlobal, Integrator::VertexBlockDescent}) {
    drape::WorldDef wd;
    wd.integrator = integrator;
    wd.dt = 1.0 / 60;
    wd.local_global_iterations = 20;
    wd.vertex_block_iterations = 20;
    drape::World w(wd);
    drape::SheetDef d;
    d.m = d.n = 15;
    d.mass = 1.0;
    d.stiffness = 1e5;
    d.shear = drape::ShearDef{1e5, std::nullopt};
    d.pins = drape::corner_points(d.m, d.n);
    const auto id = w.add_sheet(d);
    EXPECT_GT(wd.dt, 100 * w.stable_step_estimate(id));
    const auto report = w.step(60);
    EXPECT_TRUE(report.ok()) << drape::integrator_name(integrator) << ": " << drape::describe(report);
    EXPECT_TRUE(w.all_finite()) << drape::integrator_name(integrator);
    EXPECT_LT(w.diagnostics(id).max_strain, 0.01) << drape::integrator_name(integrator);
  }
}

}  // namespace
