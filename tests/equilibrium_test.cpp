// The paper's Fig 5 set-up at rest: a damped sheet pinned at its four corners sags under
// gravity until the springs carry its weight. The resting shape is checked against a static
// equilibrium found independently, by Newton's method on the total potential energy.
#include <drape/drape.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <vector>

#include "newton_equilibrium.h"

namespace {

struct Grid {
  std::uint32_t m, n;
  double width, mass, k, g;
};

// The static equilibrium by Newton's method on the total potential energy (springs and
// gravity), corners held fixed (newton_equilibrium.h: written from the energy, sharing no
// code with the engine's kernels).
std::vector<double> static_equilibrium(const Grid& s) {
  const std::uint32_t cols = s.n + 1, count = (s.m + 1) * cols;
  const double h = s.width / s.n, pm = s.mass / count;
  std::vector<drape::testing::Spring> springs;
  for (std::uint32_t i = 0; i <= s.m; ++i)
    for (std::uint32_t j = 0; j <= s.n; ++j) {
      if (j < s.n) springs.push_back({i * cols + j, i * cols + j + 1, s.k, h});
      if (i < s.m) springs.push_back({i * cols + j, (i + 1) * cols + j, s.k, h});
    }
  std::vector<bool> fixed(count, false);
  for (std::uint32_t p : {0u, s.n, s.m * cols, s.m * cols + s.n}) fixed[p] = true;

  // start from a sagging guess so every spring is stretched and the Hessian is definite
  Eigen::VectorXd x(3 * count);
  for (std::uint32_t i = 0; i <= s.m; ++i)
    for (std::uint32_t j = 0; j <= s.n; ++j) {
      const std::uint32_t p = i * cols + j;
      const double u = double(j) / s.n, v = double(i) / s.m;
      x.segment<3>(3 * p) << j * h - s.width / 2, i * h - s.width / 2,
          fixed[p] ? 0.0 : -0.2 * s.width * std::sin(M_PI * u) * std::sin(M_PI * v) - 0.01;
    }
  const Eigen::VectorXd eq = drape::testing::newton_equilibrium(x, springs, std::vector<double>(count, pm), fixed, s.g);
  return {eq.data(), eq.data() + eq.size()};
}

struct Rest {
  double sag;
  double kinetic;
  std::vector<double> z;
};

Rest simulate_to_rest(const Grid& s) {
  drape::WorldDef wd;
  wd.gravity = {0, 0, -s.g};
  drape::World world(wd);
  drape::SheetDef d;
  d.m = s.m;
  d.n = s.n;
  d.width = d.height = s.width;
  d.mass = s.mass;
  d.stiffness = s.k;
  d.pins = drape::corner_points(d.m, d.n);
  // enough damping to settle in a few seconds of simulated time
  d.damping = 2.0 * s.mass / ((d.m + 1) * (d.n + 1));
  const auto id = world.add_sheet(d);
  world.set_dt(0.5 * world.stable_step_estimate());
  const int steps = static_cast<int>(8.0 / world.def().dt);
  world.step(steps);
  const auto v = world.view(id);
  return {-v.z[drape::center_point(d.m, d.n)], world.energies().kinetic, {v.z.begin(), v.z.end()}};
}

TEST(Equilibrium, PinnedSheetComesToRestAtTheStaticEquilibrium) {
  const Grid grid{10, 10, 1.0, 0.1, 20.0, 9.81};
  const Rest rest = simulate_to_rest(grid);
  const std::vector<double> eq = static_equilibrium(grid);
  const std::uint32_t c = drape::center_point(grid.m, grid.n);
  const double eq_sag = -eq[3 * c + 2];
  ASSERT_GT(eq_sag, 0.01);
  EXPECT_LT(rest.kinetic, 1e-6 * grid.mass * grid.g * eq_sag);  // at rest: KE a millionth of the work gravity did
  EXPECT_NEAR(rest.sag / eq_sag, 1.0, 0.01) << "simulated " << rest.sag << " m, equilibrium " << eq_sag << " m";
  // the whole shape, not only the centre
  for (std::size_t p = 0; p < rest.z.size(); ++p) EXPECT_NEAR(rest.z[p], eq[3 * p + 2], 0.01 * eq_sag) << "point " << p;
}

TEST(Equilibrium, SagShrinksAsStiffnessGrows) {
  // Fig 5: the same surface with growing k hangs less deep.
  double previous = INFINITY;
  for (double k : {5.0, 20.0, 80.0}) {
    const Grid grid{8, 8, 1.0, 0.1, k, 9.81};
    const Rest rest = simulate_to_rest(grid);
    const std::vector<double> eq = static_equilibrium(grid);
    const double eq_sag = -eq[3 * drape::center_point(grid.m, grid.n) + 2];
    EXPECT_NEAR(rest.sag / eq_sag, 1.0, 0.01) << "k = " << k;
    EXPECT_LT(rest.sag, previous) << "k = " << k;
    previous = rest.sag;
  }
}

}  // namespace
