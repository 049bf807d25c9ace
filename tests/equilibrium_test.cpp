// The paper's Fig 5 set-up at rest: a damped sheet pinned at its four corners sags under
// gravity until the springs carry its weight. The resting shape is checked against a static
// equilibrium found independently, by Newton's method on the total potential energy.
#include <drape/drape.h>
#include <gtest/gtest.h>

#include <Eigen/Dense>
#include <cmath>
#include <vector>

namespace {

struct Grid {
  std::uint32_t m, n;
  double width, mass, k, g;
};

// Newton's method with a backtracking line search on
//   E(x) = Σ_springs ½k(|xa − xb| − h)² − Σ_points m g·x,
// corners held fixed. Written from the energy, sharing no code with the engine's kernels.
std::vector<double> static_equilibrium(const Grid& s) {
  const std::uint32_t cols = s.n + 1, count = (s.m + 1) * cols;
  const double h = s.width / s.n, pm = s.mass / count;
  std::vector<std::pair<std::uint32_t, std::uint32_t>> springs;
  for (std::uint32_t i = 0; i <= s.m; ++i)
    for (std::uint32_t j = 0; j <= s.n; ++j) {
      if (j < s.n) springs.push_back({i * cols + j, i * cols + j + 1});
      if (i < s.m) springs.push_back({i * cols + j, (i + 1) * cols + j});
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
  auto energy = [&](const Eigen::VectorXd& y) {
    double e = 0;
    for (auto [a, b] : springs) {
      const double len = (y.segment<3>(3 * a) - y.segment<3>(3 * b)).norm();
      e += 0.5 * s.k * (len - h) * (len - h);
    }
    for (std::uint32_t p = 0; p < count; ++p) e += pm * s.g * y[3 * p + 2];
    return e;
  };
  for (int iter = 0; iter < 100; ++iter) {
    Eigen::VectorXd grad = Eigen::VectorXd::Zero(3 * count);
    Eigen::MatrixXd hess = Eigen::MatrixXd::Zero(3 * count, 3 * count);
    for (auto [a, b] : springs) {
      const Eigen::Vector3d d = x.segment<3>(3 * a) - x.segment<3>(3 * b);
      const double len = d.norm();
      const Eigen::Vector3d u = d / len;
      const Eigen::Vector3d ga = s.k * (len - h) * u;
      // ∂²E/∂xa² = k[u uᵀ + (1 − h/len)(I − u uᵀ)], the transverse part clamped at 0
      const Eigen::Matrix3d block = s.k * (u * u.transpose() + std::max(0.0, 1 - h / len) *
                                                                   (Eigen::Matrix3d::Identity() - u * u.transpose()));
      grad.segment<3>(3 * a) += ga;
      grad.segment<3>(3 * b) -= ga;
      hess.block<3, 3>(3 * a, 3 * a) += block;
      hess.block<3, 3>(3 * b, 3 * b) += block;
      hess.block<3, 3>(3 * a, 3 * b) -= block;
      hess.block<3, 3>(3 * b, 3 * a) -= block;
    }
    for (std::uint32_t p = 0; p < count; ++p) grad[3 * p + 2] += pm * s.g;
    for (std::uint32_t p = 0; p < count; ++p)
      if (fixed[p])
        for (int c = 0; c < 3; ++c) {
          const int r = 3 * p + c;
          grad[r] = 0;
          hess.row(r).setZero();
          hess.col(r).setZero();
          hess(r, r) = 1;
        }
    if (grad.norm() < 1e-12) break;
    const Eigen::VectorXd step = hess.ldlt().solve(-grad);
    const double e0 = energy(x);
    double t = 1;
    while (t > 1e-8 && energy(x + t * step) > e0 + 1e-4 * t * grad.dot(step)) t /= 2;
    x += t * step;
  }
  return {x.data(), x.data() + x.size()};
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
