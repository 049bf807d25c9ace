// World::sheet_crossings against a brute force of its own (every edge against every
// triangle by Möller–Trumbore's parametric test, not the engine's orientation volumes), on
// sheets crumpled at random, and on sheets that contacts hold apart or that a speed past
// the contact's barrier sends through each other.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>
#include <random>
#include <set>
#include <utility>
#include <vector>

#include "surface_distance.h"

#include <drape/drape.h>

namespace drape {
namespace {

using test::cross;
using test::dot;
using test::P3;
using test::sub;

// Where segment pq meets the inside of triangle abc, as (t along pq, hit point), by solving
// p + t·(q − p) = a + u·(b − a) + v·(c − a) with Cramer's rule; nullopt when it misses or
// the segment lies in the triangle's plane.
std::optional<std::pair<double, P3>> segment_hits(P3 p, P3 q, P3 a, P3 b, P3 c) {
  const P3 d = sub(q, p), e1 = sub(b, a), e2 = sub(c, a), s = sub(p, a);
  const P3 h = cross(d, e2);
  const double det = dot(e1, h);
  if (det == 0) return std::nullopt;
  const double u = dot(s, h) / det;
  const P3 k = cross(s, e1);
  const double v = dot(d, k) / det, t = dot(e2, k) / det;
  if (!(u > 0 && v > 0 && u + v < 1 && t > 0 && t < 1)) return std::nullopt;
  return std::pair{t, P3{p[0] + t * d[0], p[1] + t * d[1], p[2] + t * d[2]}};
}

template <class Real>
P3 at(const SheetView<Real>& s, std::uint32_t k) {
  return {double(s.x[k]), double(s.y[k]), double(s.z[k])};
}

// Every crossing of an edge of q with a triangle of s, and for each the pair (q's end of the
// edge nearer the hit, s's corner nearest it), or the reverse when `swap`. q == s: a sheet
// through itself, the triangles of cells that share a point with the edge's cell left out
// (an edge belongs to the cell it bounds on its top, left or diagonal; the last row's and
// column's outer edges to the cell inside them).
struct Brute {
  std::size_t count = 0;
  std::set<std::pair<std::uint32_t, std::uint32_t>> points;  // (point of a, point of b)
};

template <class Real>
void brute_edges_through(const SheetView<Real>& q, const SheetView<Real>& s, bool self, bool swap, Brute& out) {
  const std::uint32_t qc = q.n + 1, sc = s.n + 1;
  struct Edge {
    std::uint32_t u, v;
    long ci, cj;  // its cell
  };
  std::vector<Edge> edges;
  for (std::uint32_t i = 0; i <= q.m; ++i)
    for (std::uint32_t j = 0; j <= q.n; ++j) {
      const std::uint32_t u = i * qc + j;
      const long row = std::min<long>(i, long(q.m) - 1), col = std::min<long>(j, long(q.n) - 1);
      if (j < q.n) edges.push_back({u, u + 1, row, long(j)});
      if (i < q.m) edges.push_back({u, u + qc, long(i), col});
      if (i < q.m && j < q.n) edges.push_back({u, u + qc + 1, long(i), long(j)});
    }
  for (const auto& [u, v, ci, cj] : edges)
    for (std::uint32_t i = 0; i < s.m; ++i)
      for (std::uint32_t j = 0; j < s.n; ++j) {
        if (self && std::abs(long(i) - ci) <= 1 && std::abs(long(j) - cj) <= 1) continue;
        const std::uint32_t c = i * sc + j;
        const std::array<std::array<std::uint32_t, 3>, 2> triangles{{{c, c + 1, c + sc + 1}, {c, c + sc + 1, c + sc}}};
        for (const auto& tri : triangles) {
          const auto hit = segment_hits(at(q, u), at(q, v), at(s, tri[0]), at(s, tri[1]), at(s, tri[2]));
          if (!hit) continue;
          ++out.count;
          const std::uint32_t mine = hit->first < 0.5 ? u : v;
          std::uint32_t theirs = tri[0];
          for (std::uint32_t k : tri) {
            const P3 dk = sub(at(s, k), hit->second), dt = sub(at(s, theirs), hit->second);
            if (dot(dk, dk) < dot(dt, dt)) theirs = k;
          }
          out.points.insert(swap ? std::pair{theirs, mine} : std::pair{mine, theirs});
        }
      }
}

template <class Real>
Brute brute_crossings(const SheetView<Real>& a, const SheetView<Real>& b, bool self) {
  Brute out;
  brute_edges_through(a, b, self, false, out);
  if (!self) brute_edges_through(b, a, false, true, out);
  return out;
}

// Every point of the sheet moved to a random place in a cube of side `extent`: a crumpled
// surface with many crossings, none of them on a plane or an edge but by chance.
template <class Real>
void scramble(BasicWorld<Real>& w, SheetId id, std::mt19937& rng, double extent, double dx) {
  std::uniform_real_distribution<double> u(0, extent);
  auto s = w.state(id);
  for (std::size_t p = 0; p < s.size(); ++p) {
    s.x[p] = Real(dx + u(rng));
    s.y[p] = Real(u(rng));
    s.z[p] = Real(u(rng));
  }
}

template <class Real>
void crumpled_sheets_match_the_brute_force() {
  std::mt19937 rng(7);
  for (int round = 0; round < 4; ++round) {
    WorldDef wd;
    BasicWorld<Real> w(wd);
    SheetDef d;
    d.m = 5;
    d.n = 7;
    const SheetId a = w.add_sheet(d);
    d.m = d.n = 6;
    d.self_collision = true;
    const SheetId b = w.add_sheet(d);
    d.m = d.n = 3;
    d.self_collision = false;
    const SheetId far = w.add_sheet(d);  // crumpled too, but where its box meets no other
    scramble(w, a, rng, 0.1, 0.0);
    scramble(w, b, rng, 0.1, 0.02 * round);
    scramble(w, far, rng, 0.1, 5.0);
    const Brute ab = brute_crossings(w.view(a), w.view(b), false);
    const Brute bb = brute_crossings(w.view(b), w.view(b), true);
    ASSERT_GT(ab.count, 0u) << "round " << round;  // the case is not empty
    ASSERT_GT(bb.count, 10u);
    const std::vector<SheetCrossing> got = w.sheet_crossings();
    ASSERT_EQ(got.size(), 2u) << "a with b, and b through itself; not a through itself, nor the far sheet";
    EXPECT_EQ(got[0].a, a);
    EXPECT_EQ(got[0].b, b);
    EXPECT_EQ(got[0].edges, ab.count);
    EXPECT_TRUE(ab.points.count({got[0].point_a, got[0].point_b})) << got[0].point_a << " " << got[0].point_b;
    EXPECT_EQ(got[1].a, b);
    EXPECT_EQ(got[1].b, b);
    EXPECT_EQ(got[1].edges, bb.count);
    EXPECT_TRUE(bb.points.count({got[1].point_a, got[1].point_b})) << got[1].point_a << " " << got[1].point_b;
  }
}

TEST(Crossings, CrumpledSheetsMatchEveryEdgeAgainstEveryTriangle) { crumpled_sheets_match_the_brute_force<double>(); }
TEST(Crossings, CrumpledSheetsMatchEveryEdgeAgainstEveryTriangleInFloat) {
  crumpled_sheets_match_the_brute_force<float>();
}

// Crossings are what contacts fail to prevent: with contact_strength = 0 sheets are meant to
// pass through each other, and a sheet without self_collision through itself.
TEST(Crossings, OnlySheetsThatContactsWouldHoldApartAreReported) {
  std::mt19937 rng(11);
  WorldDef wd;
  wd.contact_strength = 0;
  World w(wd);
  SheetDef d;
  d.m = d.n = 5;
  d.self_collision = true;
  const SheetId a = w.add_sheet(d), b = w.add_sheet(d);
  scramble(w, a, rng, 0.1, 0.0);
  scramble(w, b, rng, 0.1, 0.0);
  ASSERT_GT(brute_crossings(w.view(a), w.view(b), false).count, 0u);
  EXPECT_TRUE(w.sheet_crossings().empty());
}

// Flat sheets 3 mm apart (within the contact thickness, not through) and a flat sheet beside
// itself: no crossing. A point of the upper sheet pushed 1 mm below the lower one: its four
// edges to its row and column neighbours and the diagonals through it cross; the pair is
// reported with that point.
TEST(Crossings, APointPushedThroughTheSheetBelowIsNamed) {
  World w(WorldDef{});
  SheetDef d;
  d.m = d.n = 8;
  d.width = d.height = 0.16;
  d.self_collision = true;
  const SheetId lower = w.add_sheet(d);
  d.center = {0.0061, 0.0073, 0.003};  // no edge meets the lower sheet on its edges
  const SheetId upper = w.add_sheet(d);
  EXPECT_TRUE(w.sheet_crossings().empty());
  const std::uint32_t p = 4 * 9 + 3;
  w.state(upper).z[p] = -0.001;
  const std::vector<SheetCrossing> got = w.sheet_crossings();
  ASSERT_EQ(got.size(), 1u);
  EXPECT_EQ(got[0].a, lower);
  EXPECT_EQ(got[0].b, upper);
  EXPECT_EQ(got[0].point_b, p);
  const Brute brute = brute_crossings(w.view(lower), w.view(upper), false);
  EXPECT_EQ(got[0].edges, brute.count);
  EXPECT_GE(got[0].edges, 6u);  // the point's six edges (row, column, diagonals), each through one triangle at least
}

// Sheets dropped onto a pinned one, stacked, settle on it without a crossing at any frame;
// then the top sheet's half is thrown down far faster than the barrier holds (½·m·v² ≫
// c·exp(h/ξ)): it passes through the sheets below while its other half stays on them, and
// the crossing is reported, in agreement with the brute force.
TEST(Crossings, SheetsSettlingInContactNeverCrossAndAThrownHalfDoes) {
  WorldDef wd;
  wd.dt = 2e-4;
  World w(wd);
  SheetDef d;
  d.m = d.n = 10;
  d.width = d.height = 0.2;
  d.mass = 0.05;
  d.pins = {0, 10, 110, 120};
  w.add_sheet(d);  // the pinned base
  d.pins.clear();
  std::vector<SheetId> layers;
  for (int k = 1; k <= 2; ++k) {
    d.center = {0.004 * k, 0.003 * k, 0.008 * k};
    layers.push_back(w.add_sheet(d));
  }
  std::size_t touching = 0;
  for (int frame = 0; frame < 30; ++frame) {
    w.step(25);
    touching += w.contact_pair_count();
    ASSERT_TRUE(w.sheet_crossings().empty()) << "frame " << frame;
  }
  ASSERT_GT(touching, 0u);
  const SheetId top = layers.back();
  auto s = w.state(top);
  for (std::size_t p = 0; p < s.size(); ++p)
    if (p % 11 < 5) s.vz[p] = -60;  // ½·m·v² = 0.74 J a point against a barrier of 0.012 J
  w.step(10);
  const std::vector<SheetCrossing> got = w.sheet_crossings();
  ASSERT_FALSE(got.empty());
  for (const SheetCrossing& c : got) {
    EXPECT_EQ(c.b, top);
    const Brute brute = brute_crossings(w.view(c.a), w.view(c.b), false);
    EXPECT_EQ(c.edges, brute.count);
    EXPECT_TRUE(brute.points.count({c.point_a, c.point_b}));
  }
}

// A sheet of long cells (15 cm) laid across the edge of a pinned one, 1 cm above it, two of
// its three columns of points over the pinned sheet: they land on it (friction holds them)
// and the cells reaching past the edge rest on that edge, whose far points cannot tip down
// without lifting the near ones (a cell is straight). No point of the laid sheet comes
// within contact range of the pinned one's edge (each is 5 cm or more from it), so only the
// rims (contacts.h: the pinned sheet's edge against the laid sheet's edges passing it) hold
// the cells on the edge: without them the cells cut through the pinned sheet's outer cells
// (a crossing, sheet_crossings) and the sheet falls through; with them no frame has a
// crossing and every point stays above the pinned sheet's plane.
TEST(Crossings, ASheetDrapedOverAnotherSheetsEdgeStaysOnItWithRimContacts) {
  for (bool rims : {false, true}) {
    WorldDef wd;
    wd.dt = 2e-4;
    wd.contact_rims = rims;
    World w(wd);
    SheetDef table;
    table.m = table.n = 2;
    table.width = table.height = 0.2;
    for (std::uint32_t p = 0; p < 9; ++p) table.pins.push_back(p);
    const SheetId under = w.add_sheet(table);
    SheetDef cloth;
    cloth.m = 1;
    cloth.n = 2;
    cloth.width = 0.3;
    cloth.height = 0.1;
    cloth.mass = 0.01;
    cloth.stiffness = 50;
    cloth.damping = 0.01;
    cloth.friction = 1;  // the part on the table holds the part hanging
    cloth.center = {0.0, 0.003, 0.01};  // points at x = −0.15, 0, 0.15; the table's edge at x = 0.1
    const SheetId over = w.add_sheet(cloth);
    std::size_t frames_crossed = 0;
    for (int frame = 0; frame < 50; ++frame) {
      w.step(50);
      frames_crossed += !w.sheet_crossings().empty();
    }
    const auto v = w.view(over);
    const double lowest = *std::min_element(v.z.begin(), v.z.end());
    if (rims) {
      EXPECT_EQ(frames_crossed, 0u);
      EXPECT_GT(lowest, 0.0);
    } else {
      EXPECT_GT(frames_crossed, 0u) << "the case needs the rims";
      EXPECT_LT(lowest, 0.0);
    }
    (void)under;
  }
}

}  // namespace
}  // namespace drape
