// The vector kernels (engine/src/simd) on every instruction set this CPU supports: each
// target gives eq (6) and the explicit update as computed independently here, in every build.
// A world, whose whole row sweep runs on the dispatched target (forces.cpp), keeps its
// bit-identity across threads, row blocks and frames on each target, with and without the
// cloth terms and obstacles (obstacles.cpp, also compiled per target), and differs between
// targets only by rounding.
#include <gtest/gtest.h>

#include <drape/drape.h>

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <random>
#include <string>
#include <type_traits>
#include <vector>

#include "bounds.h"
#include "each_target.h"
#include "forces.h"
#include "integrate.h"
#include "simd/kernels.h"

namespace drape {
namespace {

using test::for_each_target;

TEST(Simd, EveryTargetTheCpuSupportsIsRunAndNamed) {
  const std::string widest = detail::simd::target_name();
  std::vector<std::string> names;
  for_each_target([&](std::int64_t) { names.push_back(detail::simd::target_name()); });
  ASSERT_FALSE(names.empty());
  std::string list;
  for (const std::string& n : names) list += " " + n;
  std::printf("kernels run with:%s\n", list.c_str());  // in ctest's log: which sets were tested
  EXPECT_EQ(names.front(), widest);  // the default is the widest
  for (std::size_t k = 1; k < names.size(); ++k) EXPECT_NE(names[k], names[k - 1]);  // dispatch really switched
  EXPECT_EQ(detail::simd::target_name(), widest);
}

// eq (6) in long double, from the equation: f_a = −k(|d| − ℓ) d/|d|, nothing at |d| = 0.
template <class Real>
void expect_springs_match_the_equation() {
  std::mt19937 rng(15);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const std::size_t count = 37;  // whole vectors of every width and a remainder
  std::vector<Real> a[3], b[3], rest(count), k(count);
  for (int c = 0; c < 3; ++c)
    for (std::size_t e = 0; e < count; ++e) {
      a[c].push_back(Real(u(rng)));
      b[c].push_back(e % 11 == 3 ? a[c][e] : Real(u(rng)));  // some zero-length springs
    }
  for (std::size_t e = 0; e < count; ++e) {
    rest[e] = Real(0.5 + 0.4 * u(rng));
    k[e] = Real(100 + 50 * u(rng));
  }
  const double tolerance = std::is_same_v<Real, double> ? 1e-12 : 1e-4;
  // store_only: a run whose one output is the stored force (a row's own springs), whose
  // remainder is a whole vector over the last springs (kernels-inl.h, over_lanes_storing)
  for_each_target([&](std::int64_t) {
    for (int variant = 0; variant < 4; ++variant) {
      const bool per_spring = (variant & 1) == 0, store_only = (variant & 2) != 0;
      std::vector<Real> store[3], add[3], sub[3];
      for (int c = 0; c < 3; ++c) {
        store[c].assign(count, Real(7));
        add[c].assign(count, Real(1));
        sub[c].assign(count, Real(2));
      }
      auto run = detail::simd::SpringRun<Real>::between(count, a[0].data(), a[1].data(), a[2].data(), b[0].data(),
                                                        b[1].data(), b[2].data());
      if (per_spring)
        run.per_spring(rest.data(), k.data());
      else
        run.same(rest[0], k[0]);
      run.store(store[0].data(), store[1].data(), store[2].data());
      if (!store_only) {
        run.add(add[0].data(), add[1].data(), add[2].data());
        run.sub(sub[0].data(), sub[1].data(), sub[2].data());
      }
      detail::simd::springs(run);
      for (std::size_t e = 0; e < count; ++e) {
        long double d[3], len2 = 0;
        for (int c = 0; c < 3; ++c) {
          d[c] = static_cast<long double>(a[c][e]) - b[c][e];
          len2 += d[c] * d[c];
        }
        const long double len = std::sqrt(len2);
        const long double ke = per_spring ? k[e] : k[0], le = per_spring ? rest[e] : rest[0];
        for (int c = 0; c < 3; ++c) {
          const long double f = len > 0 ? -ke * (len - le) * d[c] / len : 0;
          EXPECT_NEAR(store[c][e], double(f), tolerance * ke) << "spring " << e << " axis " << c;
          EXPECT_NEAR(add[c][e], store_only ? 1.0 : double(1 + f), tolerance * ke) << "spring " << e << " axis " << c;
          EXPECT_NEAR(sub[c][e], store_only ? 2.0 : double(2 - f), tolerance * ke) << "spring " << e << " axis " << c;
          if (len == 0) {
            EXPECT_EQ(store[c][e], Real(0));  // exactly nothing, not NaN
          }
        }
      }
    }
  });
}

TEST(Simd, SpringKernelOfEveryTargetGivesEquationSixInDouble) { expect_springs_match_the_equation<double>(); }
TEST(Simd, SpringKernelOfEveryTargetGivesEquationSixInFloat) { expect_springs_match_the_equation<float>(); }

// The bounds pass (bounds.h, include_points) on every target, against the smallest and
// largest value found by a plain search: equal, as min and max round nothing. Lengths from
// 1 to 40 cover runs shorter than a vector, whole vectors and every remainder; the longer
// ones reach the four running vectors of 16 floats and what follows them; a NaN first
// coordinate gives a NaN box, a NaN later one is skipped.
template <class Real>
void expect_bounds_are_the_smallest_and_largest() {
  std::mt19937 rng(151);
  std::uniform_real_distribution<double> u(-5.0, 5.0);
  const Real nan = std::numeric_limits<Real>::quiet_NaN();
  for_each_target([&](std::int64_t) {
    std::vector<std::size_t> counts;
    for (std::size_t count = 1; count <= 40; ++count) counts.push_back(count);
    for (std::size_t count : {63, 64, 65, 79, 80, 127, 128, 129, 150}) counts.push_back(count);
    for (std::size_t count : counts)
      for (int nan_at : {-1, 0, int(count) - 1, int(count) / 2, int(count) - 17}) {
        std::vector<Real> a[3];
        for (int c = 0; c < 3; ++c)
          for (std::size_t i = 0; i < count; ++i) a[c].push_back(Real(u(rng)));
        if (nan_at >= 0) a[1][std::size_t(nan_at)] = nan;
        // the extremes anywhere, not only where a uniform draw puts them
        a[2][std::size_t(nan_at >= 0 ? nan_at : 0)] = Real(-7);
        detail::Aabb box = detail::empty_box();
        detail::include_points(box, a[0].data(), a[1].data(), a[2].data(), count);
        for (int c = 0; c < 3; ++c) {
          SCOPED_TRACE(testing::Message() << "count " << count << ", axis " << c << ", NaN at " << nan_at);
          if (c == 1 && nan_at == 0) {
            EXPECT_TRUE(std::isnan(box.lo[c]) && std::isnan(box.hi[c]));
            continue;
          }
          double lo = std::numeric_limits<double>::infinity(), hi = -lo;
          for (Real v : a[c])
            if (!std::isnan(v)) {
              lo = std::min(lo, double(v));
              hi = std::max(hi, double(v));
            }
          EXPECT_EQ(box.lo[c], lo);
          EXPECT_EQ(box.hi[c], hi);
        }
      }
  });
}

TEST(Simd, BoundsOfEveryTargetAreTheSmallestAndLargestCoordinate) { expect_bounds_are_the_smallest_and_largest<double>(); }
TEST(Simd, BoundsOfEveryTargetAreTheSmallestAndLargestCoordinateInFloat) {
  expect_bounds_are_the_smallest_and_largest<float>();
}

// Cell boxes from two rows of points: each holds its four corners and is no larger.
template <class Real>
void expect_cell_boxes_hold_their_corners() {
  std::mt19937 rng(152);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  for_each_target([&](std::int64_t) {
    for (std::size_t cells : {std::size_t(1), std::size_t(3), std::size_t(8), std::size_t(21)}) {
      std::vector<Real> a(cells + 1), b(cells + 1), lo(cells, Real(9)), hi(cells, Real(9));
      for (std::size_t j = 0; j <= cells; ++j) {
        a[j] = Real(u(rng));
        b[j] = j % 5 == 2 ? a[j] : Real(u(rng));  // some ties
      }
      detail::simd::cell_boxes(detail::simd::CellRow<Real>{cells, a.data(), b.data(), lo.data(), hi.data()});
      for (std::size_t j = 0; j < cells; ++j) {
        const Real corners[4] = {a[j], a[j + 1], b[j], b[j + 1]};
        EXPECT_EQ(lo[j], *std::min_element(corners, corners + 4)) << "cell " << j << " of " << cells;
        EXPECT_EQ(hi[j], *std::max_element(corners, corners + 4)) << "cell " << j << " of " << cells;
      }
    }
  });
}

TEST(Simd, CellBoxesOfEveryTargetHoldTheirFourCorners) { expect_cell_boxes_hold_their_corners<double>(); }
TEST(Simd, CellBoxesOfEveryTargetHoldTheirFourCornersInFloat) { expect_cell_boxes_hold_their_corners<float>(); }

// The same boxes where the corners tie at zeros of both signs or are not numbers: each box is
// std::min(std::min(a0, a1), std::min(b0, b1)) and the same with std::max, bit for bit (which
// zero, which NaN), on every target: the kernels' min and max (simd/select-inl.h) are one
// instruction on x86, whose operand order decides exactly these cases.
template <class Real>
void expect_cell_boxes_keep_std_min_and_max_bits() {
  using Bits = std::conditional_t<std::is_same_v<Real, double>, std::uint64_t, std::uint32_t>;
  const Real nan = std::numeric_limits<Real>::quiet_NaN();
  const Real values[] = {Real(0), -Real(0), Real(1), -Real(1), nan, -nan};
  // Row a holds every ordered pair of the values (x, y) as neighbours, row b the pairs in
  // another order, so the cells meet every pair on a's side and many on both.
  const std::size_t kinds = std::size(values), pairs = kinds * kinds, cells = 2 * pairs - 1;
  std::vector<Real> a, b;
  for (std::size_t k = 0; k < pairs; ++k) {
    a.insert(a.end(), {values[k / kinds], values[k % kinds]});
    const std::size_t other = (7 * k + 3) % pairs;
    b.insert(b.end(), {values[other % kinds], values[other / kinds]});
  }
  const auto bits = [](Real v) { return std::bit_cast<Bits>(v); };
  for_each_target([&](std::int64_t) {
    std::vector<Real> lo(cells, Real(9)), hi(cells, Real(9));
    detail::simd::cell_boxes(detail::simd::CellRow<Real>{cells, a.data(), b.data(), lo.data(), hi.data()});
    for (std::size_t j = 0; j < cells; ++j) {
      const Real want_lo = std::min(std::min(a[j], a[j + 1]), std::min(b[j], b[j + 1]));
      const Real want_hi = std::max(std::max(a[j], a[j + 1]), std::max(b[j], b[j + 1]));
      EXPECT_EQ(bits(lo[j]), bits(want_lo)) << detail::simd::target_name() << ", cell " << j << ": " << a[j] << " "
                                            << a[j + 1] << " " << b[j] << " " << b[j + 1];
      EXPECT_EQ(bits(hi[j]), bits(want_hi)) << detail::simd::target_name() << ", cell " << j << ": " << a[j] << " "
                                            << a[j + 1] << " " << b[j] << " " << b[j + 1];
    }
  });
}

TEST(Simd, CellBoxesOfEveryTargetKeepStdMinAndMaxBitsAtSignedZerosAndNaN) {
  expect_cell_boxes_keep_std_min_and_max_bits<double>();
}
TEST(Simd, CellBoxesOfEveryTargetKeepStdMinAndMaxBitsAtSignedZerosAndNaNInFloat) {
  expect_cell_boxes_keep_std_min_and_max_bits<float>();
}

// Air on a row of cells (terms/air.h) against the law in long double, written with the
// cell's unit normal n = c/|c| and area A = |c|/2 of the diagonals' cross product c: the
// pressure −hp·2A |v·n|(v·n) n and the friction −hf·2A |v_t| v_t, v_t = v − (v·n) n, for
// v the corners' mean velocity less the wind. A collapsed cell feels exactly nothing.
template <class Real>
void expect_air_cells_follow_the_drag_law() {
  std::mt19937 rng(153);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const std::size_t cells = 19;  // whole vectors of every width and a remainder
  std::vector<Real> x[2][3], v[2][3];
  for (int row = 0; row < 2; ++row)
    for (int c = 0; c < 3; ++c)
      for (std::size_t j = 0; j <= cells; ++j) {
        x[row][c].push_back(Real((c == 0 ? double(j) : c == 1 ? double(row) : 0.0) + 0.3 * u(rng)));
        v[row][c].push_back(Real(u(rng)));
      }
  for (int row = 0; row < 2; ++row)  // cell 7 collapsed to a point
    for (int c = 0; c < 3; ++c) x[row][c][7] = x[row][c][8] = x[0][c][7];
  const Real hp = Real(0.6), hf = Real(0.05), wind[3] = {Real(0.2), Real(-0.1), Real(0.3)};
  const double tolerance = std::is_same_v<Real, double> ? 1e-12 : 2e-5;
  for_each_target([&](std::int64_t) {
    std::vector<Real> f[3];
    for (auto& fc : f) fc.assign(cells, Real(7));
    detail::simd::AirCells<Real> r;
    r.count = cells;
    r.ax = x[0][0].data(), r.ay = x[0][1].data(), r.az = x[0][2].data();
    r.bx = x[1][0].data(), r.by = x[1][1].data(), r.bz = x[1][2].data();
    r.avx = v[0][0].data(), r.avy = v[0][1].data(), r.avz = v[0][2].data();
    r.bvx = v[1][0].data(), r.bvy = v[1][1].data(), r.bvz = v[1][2].data();
    r.fx = f[0].data(), r.fy = f[1].data(), r.fz = f[2].data();
    r.half_pressure = hp, r.half_friction = hf, r.wx = wind[0], r.wy = wind[1], r.wz = wind[2];
    detail::simd::air_cells(r);
    for (std::size_t j = 0; j < cells; ++j) {
      long double d1[3], d2[3], vel[3];
      for (int c = 0; c < 3; ++c) {
        d1[c] = static_cast<long double>(x[1][c][j + 1]) - x[0][c][j];
        d2[c] = static_cast<long double>(x[1][c][j]) - x[0][c][j + 1];
        vel[c] = (static_cast<long double>(v[0][c][j]) + v[0][c][j + 1] + v[1][c][j] + v[1][c][j + 1]) / 4 - wind[c];
      }
      const long double cr[3] = {d1[1] * d2[2] - d1[2] * d2[1], d1[2] * d2[0] - d1[0] * d2[2],
                                 d1[0] * d2[1] - d1[1] * d2[0]};
      const long double two_area = std::sqrt(cr[0] * cr[0] + cr[1] * cr[1] + cr[2] * cr[2]);
      if (two_area == 0) {
        for (int c = 0; c < 3; ++c) EXPECT_EQ(f[c][j], Real(0)) << "collapsed cell " << j;
        continue;
      }
      long double n[3], vn = 0, t[3], tt = 0;
      for (int c = 0; c < 3; ++c) n[c] = cr[c] / two_area;
      for (int c = 0; c < 3; ++c) vn += vel[c] * n[c];
      for (int c = 0; c < 3; ++c) {
        t[c] = vel[c] - vn * n[c];
        tt += t[c] * t[c];
      }
      for (int c = 0; c < 3; ++c) {
        const long double expected = -hp * two_area * std::fabs(vn) * vn * n[c] - hf * two_area * std::sqrt(tt) * t[c];
        EXPECT_NEAR(f[c][j], double(expected), tolerance) << "cell " << j << " axis " << c;
      }
    }
  });
}

TEST(Simd, AirKernelOfEveryTargetGivesTheDragLaw) { expect_air_cells_follow_the_drag_law<double>(); }
TEST(Simd, AirKernelOfEveryTargetGivesTheDragLawInFloat) { expect_air_cells_follow_the_drag_law<float>(); }

// One step by hand: forward Euler moves x with the old v, semi-implicit Euler with the new.
// The row sweep's springs on rows of whole vectors of every width (32 points), where
// AVX-512 joins a row's horizontal springs and the vertical ones above it into one pass
// (simd::rows_joined) and the other targets net them through the scratch row: every target
// gives the first target's bits, for the whole sheet and for two blocks of rows, and each
// point's force is eq (6) summed spring by spring over the topology's edge list.
template <class Real>
void expect_rows_of_whole_vectors_give_equation_six() {
  for (bool regions : {false, true}) {
    SCOPED_TRACE(regions ? "per-spring stiffness" : "one stiffness");
    SheetDef def;
    def.m = 6;
    def.n = 31;  // rows of 32 points
    def.stiffness = 150;
    if (regions) def.stiffness_regions = {{1, 4, 5, 20, 900.0}};
    auto s = detail::build_sheet<Real>(def);
    ASSERT_EQ(s.topology->uniform.has_value(), !regions);
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> jitter(-0.01, 0.01);
    for (std::size_t p = 0; p < s.size(); ++p) {
      s.position.x[p] += Real(jitter(rng));
      s.position.y[p] += Real(jitter(rng));
      s.position.z[p] += Real(jitter(rng));
    }
    const auto& t = *s.topology;
    std::vector<long double> want[3];
    for (auto& w : want) w.assign(s.size(), 0.0L);
    for (std::size_t e = 0; e < t.a.size(); ++e) {
      const std::uint32_t a = t.a[e], b = t.b[e];
      const long double d[3] = {(long double)s.position.x[a] - s.position.x[b],
                                (long double)s.position.y[a] - s.position.y[b],
                                (long double)s.position.z[a] - s.position.z[b]};
      const long double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      for (int c = 0; c < 3; ++c) {
        const long double f = -(long double)t.stiffness[e] * (len - t.rest_length[e]) * d[c] / len;
        want[c][a] += f;
        want[c][b] -= f;
      }
    }
    // rounding of coordinates near 0.5 m, through up to four springs of the largest k
    const double tolerance = (std::is_same_v<Real, double> ? 1e-12 : 2e-6) * (regions ? 900.0 : 150.0);
    std::vector<Real> first;
    for_each_target([&](std::int64_t) {
      std::vector<Real> got;
      for (int blocks : {1, 2}) {
        const std::uint32_t rows = t.rows(), cut = blocks == 1 ? rows : 3;
        std::fill(s.force.x.begin(), s.force.x.end(), Real(-1));
        detail::spring_forces(t, cptr(s.position), ptr(s.force), ptr(s.row_scratch), 0, cut);
        if (cut < rows) detail::spring_forces(t, cptr(s.position), ptr(s.force), ptr(s.row_scratch), cut, rows);
        for (std::size_t p = 0; p < s.size(); ++p) {
          const Real f[3] = {s.force.x[p], s.force.y[p], s.force.z[p]};
          for (int c = 0; c < 3; ++c) {
            EXPECT_NEAR(double(f[c]), double(want[c][p]), tolerance) << "point " << p << " axis " << c;
            got.push_back(f[c]);
          }
        }
      }
      if (first.empty())
        first = got;
      else
        EXPECT_TRUE(got == first) << "not the first target's bits";
    });
  }
}

TEST(Simd, RowsOfWholeVectorsGiveEquationSixAndEveryTargetsBits) { expect_rows_of_whole_vectors_give_equation_six<double>(); }
TEST(Simd, RowsOfWholeVectorsGiveEquationSixAndEveryTargetsBitsInFloat) {
  expect_rows_of_whole_vectors_give_equation_six<float>();
}

TEST(Simd, PointUpdateOfEveryTargetIsTheEulerStepByHand) {
  const std::size_t count = 21;
  for_each_target([&](std::int64_t) {
    for (bool semi : {false, true}) {
      std::vector<double> x[3], v[3], f[3], im(count);
      for (int c = 0; c < 3; ++c)
        for (std::size_t i = 0; i < count; ++i) {
          x[c].push_back(0.25 * double(i) + c);  // all exact in binary: the step is exact too
          v[c].push_back(0.5 * double(c) - 1.0);
          f[c].push_back(double(i % 4) - 2.0);
        }
      for (std::size_t i = 0; i < count; ++i) im[i] = i % 2 ? 2.0 : 0.5;
      const double dt = 0.125, g[3] = {0.0, 1.0, -8.0};
      detail::simd::update_points(detail::simd::PointUpdate<double>::of(count, x[0].data(), x[1].data(), x[2].data(),
                                                                        v[0].data(), v[1].data(), v[2].data(),
                                                                        f[0].data(), f[1].data(), f[2].data(), im.data())
                                      .step(dt, g[0], g[1], g[2], semi));
      for (int c = 0; c < 3; ++c)
        for (std::size_t i = 0; i < count; ++i) {
          const double v0 = 0.5 * double(c) - 1.0, x0 = 0.25 * double(i) + c;
          const double a = (double(i % 4) - 2.0) * (i % 2 ? 2.0 : 0.5) + g[c];
          const double v1 = v0 + dt * a;
          EXPECT_EQ(v[c][i], v1) << "point " << i << " axis " << c;
          EXPECT_EQ(x[c][i], x0 + dt * (semi ? v1 : v0)) << "point " << i << " axis " << c << (semi ? " semi" : "");
        }
    }
  });
}

// The update's growing variant (PointUpdate::grow) on every target: the same positions and
// velocities, bit for bit, as the plain update, and a box that is the smallest and largest
// new position found by a plain search, merged into the box it started from. Lengths 1 to
// 40 and some longer cover runs shorter than a vector, whole vectors and every remainder.
template <class Real>
void expect_growing_update_gives_the_box_of_the_new_positions() {
  std::mt19937 rng(246);
  std::uniform_real_distribution<double> u(-3.0, 3.0);
  for_each_target([&](std::int64_t) {
    std::vector<std::size_t> counts;
    for (std::size_t count = 1; count <= 40; ++count) counts.push_back(count);
    for (std::size_t count : {63, 64, 65, 127, 129}) counts.push_back(count);
    for (std::size_t count : counts)
      for (bool semi : {false, true})
        for (bool from_none : {false, true}) {
          std::vector<Real> x[3], v[3], f[3], im;
          for (int c = 0; c < 3; ++c)
            for (std::size_t i = 0; i < count; ++i) {
              x[c].push_back(Real(u(rng)));
              v[c].push_back(Real(u(rng)));
              f[c].push_back(Real(u(rng)));
            }
          for (std::size_t i = 0; i < count; ++i) im.push_back(Real(1.0 + 0.5 * u(rng)));
          auto plain_x = x[0], plain_y = x[1], plain_z = x[2], plain_vz = v[2];
          auto update = [&](Real* xs, Real* ys, Real* zs, Real* vz) {
            return detail::simd::PointUpdate<Real>::of(count, xs, ys, zs, v[0].data(), v[1].data(), vz, f[0].data(),
                                                       f[1].data(), f[2].data(), im.data())
                .step(Real(0.1), Real(0), Real(0.5), Real(-9.81), semi);
          };
          const auto v0 = v[0], v1 = v[1];
          detail::simd::update_points(update(plain_x.data(), plain_y.data(), plain_z.data(), plain_vz.data()));
          v[0] = v0;  // the plain update moved them: the growing one starts from the same state
          v[1] = v1;
          // a box that already holds something, or none yet
          auto box = from_none ? detail::simd::Extent<Real>::none()
                               : detail::simd::Extent<Real>{{Real(-1), Real(-1), Real(-1)}, {Real(1), Real(1), Real(1)}};
          const auto before = box;
          detail::simd::update_points(update(x[0].data(), x[1].data(), x[2].data(), v[2].data()).grow(&box));
          EXPECT_EQ(x[0], plain_x);
          EXPECT_EQ(x[1], plain_y);
          EXPECT_EQ(x[2], plain_z);
          EXPECT_EQ(v[2], plain_vz);
          for (int c = 0; c < 3; ++c) {
            SCOPED_TRACE(testing::Message() << "count " << count << ", axis " << c << (semi ? ", semi" : ""));
            Real lo = before.lo[c], hi = before.hi[c];
            for (Real p : x[c]) {
              lo = std::min(lo, p);
              hi = std::max(hi, p);
            }
            EXPECT_EQ(box.lo[c], lo);
            EXPECT_EQ(box.hi[c], hi);
          }
        }
  });
}

TEST(Simd, GrowingUpdateOfEveryTargetGivesTheBoxOfTheNewPositions) {
  expect_growing_update_gives_the_box_of_the_new_positions<double>();
}
TEST(Simd, GrowingUpdateOfEveryTargetGivesTheBoxOfTheNewPositionsInFloat) {
  expect_growing_update_gives_the_box_of_the_new_positions<float>();
}

// The smallest and largest coordinate of a sheet's points, by a plain search.
template <class Real>
detail::Aabb searched_box(const detail::Sheet<Real>& s) {
  detail::Aabb box = detail::empty_box();
  const std::vector<Real, detail::CacheAligned<Real>>* xs[3] = {&s.position.x, &s.position.y, &s.position.z};
  for (int c = 0; c < 3; ++c)
    for (Real p : *xs[c]) {
      box.lo[c] = std::min(box.lo[c], double(p));
      box.hi[c] = std::max(box.hi[c], double(p));
    }
  return box;
}

void expect_same_box(const detail::Aabb& a, const detail::Aabb& b) {
  for (int c = 0; c < 3; ++c) {
    EXPECT_TRUE(std::isfinite(b.lo[c]) && std::isfinite(b.hi[c]) && b.lo[c] < b.hi[c]) << "axis " << c;
    EXPECT_EQ(a.lo[c], b.lo[c]) << "axis " << c;
    EXPECT_EQ(a.hi[c], b.hi[c]) << "axis " << c;
  }
}

// A sheet whose pinned points were given a large velocity and targets away from the sheet:
// the update moves a pinned point far before its pin holds it, and the pin's target is
// the sheet's extreme, so a box that took a pinned point's update, or missed its pin, is
// wrong. Pins in point order, or not (then the box comes from a pass).
template <class Real>
detail::Sheet<Real> pinned_sheet(std::uint32_t m, std::uint32_t n, bool pins_in_order) {
  SheetDef def;
  def.m = m;
  def.n = n;
  def.damping = 0.01;
  def.pins = {0, 5, (m + 1) * (n + 1) - 1};
  if (!pins_in_order) std::reverse(def.pins.begin(), def.pins.end());
  auto s = detail::build_sheet<Real>(def);
  for (std::size_t k = 0; k < s.pins.point.size(); ++k) {
    const std::uint32_t q = s.pins.point[k];
    s.velocity.z[q] = Real(-200);
    s.velocity.x[q] = Real(150);
    s.pins.tz[k] = Real(0.75 + 0.25 * double(k));
    s.pins.tx[k] = Real(-2.0 - double(k));
  }
  return s;
}

// Every integrator's step with its box (integrate's bounds, from the update's registers for
// the per-point ones, from a pass for the others): the box is that of the points after the
// step and the pins, and the step's bits are those of a step without a box. The per-point
// integrators also on a sheet beyond the cache budget, whose rows are moved one by one as
// the sweep finishes them (sheet_forces_by_rows).
template <class Real>
void expect_every_integrators_box_is_its_points_box() {
  for_each_target([&](std::int64_t) {
    for (Integrator integrator : integrators())
      for (bool in_order : {true, false})
        for (bool large : {false, true}) {
          if (large && !detail::updates_per_point(integrator)) continue;
          SCOPED_TRACE(testing::Message() << integrator_info(integrator).name << (in_order ? "" : ", pins out of order")
                                          << (large ? ", beyond the cache budget" : ""));
          auto s = large ? pinned_sheet<Real>(200, 150, in_order) : pinned_sheet<Real>(9, 6, in_order), plain = s;
          if (large) {
            ASSERT_FALSE(detail::fits_cache_budget(s));
          }
          const detail::StepParams<Real> params{Real(1e-3), Real(0), Real(0), Real(-9.81)};
          for (int step = 0; step < 4; ++step) {
            detail::Aabb box;
            detail::integrate(integrator, s, params, &box);
            detail::integrate(integrator, plain, params);
            expect_same_box(box, searched_box(s));
            ASSERT_EQ(s.position.z, plain.position.z);
            ASSERT_EQ(s.position.x, plain.position.x);
          }
        }
  });
}

TEST(Simd, EveryIntegratorsBoxIsThatOfItsPointsAfterTheStep) { expect_every_integrators_box_is_its_points_box<double>(); }
TEST(Simd, EveryIntegratorsBoxIsThatOfItsPointsAfterTheStepInFloat) {
  expect_every_integrators_box_is_its_points_box<float>();
}

// A sheet split into row blocks as the world splits it (forces of every block, then each
// block's update growing its own box): the blocks' boxes merged in block order are the box
// of the sheet's points, and the points are those of the whole-sheet step.
template <class Real>
void expect_row_blocks_boxes_make_the_sheets_box() {
  for_each_target([&](std::int64_t) {
    for (Integrator integrator : {Integrator::ForwardEuler, Integrator::SemiImplicitEuler})
      for (bool in_order : {true, false}) {
        SCOPED_TRACE(testing::Message() << integrator_info(integrator).name << (in_order ? "" : ", pins out of order"));
        auto s = pinned_sheet<Real>(10, 11, in_order), whole = s;  // 11 × 12 points
        const std::uint32_t rows = s.topology->rows(), cols = s.topology->cols();
        const std::uint32_t cuts[] = {0, 4, 5, 9, rows};
        const std::size_t blocks = std::size(cuts) - 1;
        const std::size_t stride = s.topology->scratch_cols();
        s.row_scratch.resize(blocks * stride);
        const detail::StepParams<Real> params{Real(1e-3), Real(0), Real(0), Real(-9.81)};
        for (int step = 0; step < 4; ++step) {
          auto row = detail::ptr(s.row_scratch);
          for (std::size_t b = 0; b < blocks; ++b)
            detail::sheet_forces_rows(s, detail::cptr(s.position), detail::cptr(s.velocity), detail::ptr(s.force),
                                      {row.x + b * stride, row.y + b * stride, row.z + b * stride}, cuts[b], cuts[b + 1]);
          detail::Aabb box = detail::empty_box();
          for (std::size_t b = 0; b < blocks; ++b) {
            auto block = detail::simd::Extent<Real>::none();
            detail::update_points(integrator, s, params, std::size_t(cuts[b]) * cols, std::size_t(cuts[b + 1]) * cols,
                                  &block);
            detail::include_extent(box, block);
          }
          detail::integrate(integrator, whole, params);
          expect_same_box(box, searched_box(s));
          ASSERT_EQ(s.position.z, whole.position.z);
          ASSERT_EQ(s.position.y, whole.position.y);
        }
      }
  });
}

TEST(Simd, RowBlocksBoxesMakeTheSheetsBox) { expect_row_blocks_boxes_make_the_sheets_box<double>(); }
TEST(Simd, RowBlocksBoxesMakeTheSheetsBoxInFloat) { expect_row_blocks_boxes_make_the_sheets_box<float>(); }

// A world whose free sheets step in one task each (frames), split into row blocks, with
// per-spring parameters and pins; every spring starts stretched or compressed.
// With `cloth`, the first sheet also has shear springs, bending and air against a wind:
// every term of the sweep runs on the target. With `obstacles`, a floor with friction lies
// just under both sheets and a sphere just under the second: eq (9) on every point, the
// plane's and a curved shape's rows, the projection and friction.
template <class W>
W make_world(Integrator integrator, int threads, std::uint32_t block_points, bool cloth = false,
             bool obstacles = false) {
  WorldDef wd;
  wd.dt = 1e-4;
  wd.integrator = integrator;
  wd.threads = threads;
  wd.block_points = block_points;
  wd.contact_strength = 0;
  wd.guard = false;
  if (cloth) wd.wind.velocity = {2.0, 0.0, 0.5};
  W w(wd);
  if (obstacles) {
    ObstacleDef floor;
    floor.shape = ObstacleShape::Plane;
    floor.center = {0.0, 0.0, -0.005};
    floor.c = 0.01;
    floor.xi = 0.01;
    floor.friction = 0.5;
    w.add_obstacle(floor);
    ObstacleDef ball = floor;
    ball.shape = ObstacleShape::Sphere;
    ball.size = {0.3, 0.3, 0.3};
    ball.center = {2.0, 0.0, -0.305};
    ball.friction = 0.0;
    w.add_obstacle(ball);
  }
  SheetDef d;
  d.m = 60;
  d.n = 37;  // rows of 38 points: whole vectors and a remainder on every width
  d.stiffness = 120;
  d.damping = 0.002;
  d.stiffness_regions = {{5, 30, 3, 12, 300.0}};
  d.pins = corner_points(d.m, d.n);
  d.initial_velocity = {0.3, -0.1, 0.2};
  if (cloth) {
    d.shear = ShearDef{40.0, std::nullopt};
    d.bending = BendingDef{0.05};
    d.air = AirDef{1.2, 0.05};
  }
  w.add_sheet(d);
  d.shear.reset();
  d.bending.reset();
  d.air.reset();
  d.stiffness_regions.clear();  // a uniform topology: one k and ℓ for all springs
  d.center = {2, 0, 0};
  d.m = 200;
  d.n = 80;  // beyond the cache budget: stepped as a wave
  d.pins = corner_points(d.m, d.n);
  w.add_sheet(d);
  for (SheetId id : w.sheets()) {
    auto st = w.state(id);
    for (std::size_t p = 0; p < st.x.size(); ++p) {
      st.x[p] += 0.004 * std::sin(1.7 * double(p));
      st.z[p] += 0.004 * std::cos(2.3 * double(p));
    }
  }
  return w;
}

template <class W>
std::vector<double> run_world(Integrator integrator, int threads, std::uint32_t block_points, int frames,
                              int substeps, bool cloth = false, bool obstacles = false) {
  W w = make_world<W>(integrator, threads, block_points, cloth, obstacles);
  for (int k = 0; k < frames; ++k) w.step(substeps);
  std::vector<double> out;
  for (SheetId id : w.sheets()) {
    const auto v = w.view(id);
    for (auto span : {v.x, v.y, v.z, v.vx, v.vy, v.vz}) out.insert(out.end(), span.begin(), span.end());
  }
  return out;
}

template <class W>
void expect_bit_identity_on_every_target(bool cloth, bool obstacles = false) {
  for_each_target([&](std::int64_t) {
    for (Integrator integrator : {Integrator::SemiImplicitEuler, Integrator::ForwardEuler}) {
      auto run = [&](int threads, std::uint32_t block_points, int frames, int substeps) {
        return run_world<W>(integrator, threads, block_points, frames, substeps, cloth, obstacles);
      };
      const auto reference = run(1, 1u << 30, 12, 1);
      EXPECT_TRUE(run(2, 1u << 30, 12, 1) == reference) << integrator_name(integrator);
      EXPECT_TRUE(run(2, 600u, 12, 1) == reference) << integrator_name(integrator) << " blocks";
      EXPECT_TRUE(run(1, 1u << 30, 2, 6) == reference) << integrator_name(integrator) << " frames";
      EXPECT_TRUE(run(2, 600u, 3, 4) == reference) << integrator_name(integrator) << " frames in blocks";
    }
  });
}

TEST(Simd, EveryTargetGivesTheSameBitsOnOneAndTwoThreadsInBlocksAndFrames) {
  expect_bit_identity_on_every_target<World>(false);
}
TEST(Simd, EveryTargetGivesTheSameBitsOnOneAndTwoThreadsInBlocksAndFramesInFloat) {
  expect_bit_identity_on_every_target<WorldF>(false);
}
TEST(Simd, EveryTargetGivesTheSameBitsWithShearBendingAndAir) { expect_bit_identity_on_every_target<World>(true); }
TEST(Simd, EveryTargetGivesTheSameBitsWithShearBendingAndAirInFloat) {
  expect_bit_identity_on_every_target<WorldF>(true);
}
TEST(Simd, EveryTargetGivesTheSameBitsWithObstaclesAndFriction) {
  expect_bit_identity_on_every_target<World>(false, true);
}
TEST(Simd, EveryTargetGivesTheSameBitsWithObstaclesAndFrictionInFloat) {
  expect_bit_identity_on_every_target<WorldF>(false, true);
}

// Between instruction sets a result may differ only by rounding: over 300 substeps of a
// sheet moving by centimetres, no coordinate of any target strays from the widest's by
// more than a few hundred units in the last place of the coordinates' size.
template <class W, class Real>
void expect_targets_differ_only_by_rounding() {
  for (int extras = 0; extras < 3; ++extras) {
    const bool cloth = extras == 1, obstacles = extras == 2;
    SCOPED_TRACE(cloth ? "with shear, bending and air" : obstacles ? "with obstacles and friction" : "grid springs");
    std::vector<double> widest;
    for_each_target([&](std::int64_t) {
      const auto run = run_world<W>(Integrator::SemiImplicitEuler, 2, 600u, 30, 10, cloth, obstacles);
      if (widest.empty()) {
        widest = run;
        return;
      }
      ASSERT_EQ(run.size(), widest.size());
      double worst = 0, scale = 0;
      for (std::size_t p = 0; p < run.size(); ++p) {
        ASSERT_TRUE(std::isfinite(run[p]));
        worst = std::max(worst, std::abs(run[p] - widest[p]));
        scale = std::max(scale, std::abs(widest[p]));
      }
      EXPECT_LE(worst, 300 * std::numeric_limits<Real>::epsilon() * scale);
    });
  }
}

TEST(Simd, InstructionSetsDifferOnlyByRoundingOverARun) { expect_targets_differ_only_by_rounding<World, double>(); }
TEST(Simd, InstructionSetsDifferOnlyByRoundingOverARunInFloat) {
  expect_targets_differ_only_by_rounding<WorldF, float>();
}

}  // namespace
}  // namespace drape
