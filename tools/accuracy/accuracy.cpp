// drape-accuracy: measures the speed/accuracy trade of every integrator and precision on
// reference problems whose answers do not come from the engine, and the stability region
// of each integrator. Writes CSV files; tools/accuracy_report.py turns them into
// docs/accuracy.md and plots. Usage: drape-accuracy OUT_DIR [--quick] [--only runs,stiff,stability]
// (--only: those CSV files alone, the others in OUT_DIR are left as they are)
//
// Problems:
//   oscillator  two points and one spring, released from a stretch; analytic solution.
//               error: |separation − exact| at t = 1 s, relative to the amplitude.
//   rope        a 1×20 strip pinned at both ends, damped, settles under gravity; the
//               reference is the static equilibrium found here by Newton's method on the
//               total potential (Eigen, dense). error: max point distance after 8 s / span.
//   fig5        the paper's Fig 5 set-up, a 31×31-point (961) square sheet anchored at its
//               corners (eq 8), falling under gravity; reference: RK4 in double at 1e-5 s.
//               error: max point distance at t = 1 s / sheet width.
//   stiff       a 128×128-point sheet, 1 m square, 1 kg, corners pinned, k from 1e2 to 1e7
//               N/m, falling from flat for 0.2 s; reference: RK4 in double at half its
//               critical step. error: max point distance at t = 0.2 s / sheet width. For the
//               "stiff sheets" section: per k and error budget, the cheapest integrator and step.
#include <drape/drape.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <iostream>
#include <limits>
#include <string>
#include <vector>

namespace {

using drape::Integrator;
using Clock = std::chrono::steady_clock;

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct Positions {
  std::vector<double> x, y, z;
};

template <class World>
Positions positions(const World& world, drape::SheetId id) {
  const auto v = world.view(id);
  Positions p;
  for (std::size_t i = 0; i < v.size(); ++i) {
    p.x.push_back(v.x[i]);
    p.y.push_back(v.y[i]);
    p.z.push_back(v.z[i]);
  }
  return p;
}

double max_distance(const Positions& a, const Positions& b) {
  double d = 0;
  for (std::size_t i = 0; i < a.x.size(); ++i)
    d = std::max(d, std::hypot(a.x[i] - b.x[i], a.y[i] - b.y[i], a.z[i] - b.z[i]));
  return d;
}

// One timed run: round(seconds/dt) steps of exactly dt, in frames of about 1/60 s (the
// guard runs once per frame, as a scene runner would use it). Stops at the first guard
// failure.
struct Run {
  bool stable = true;
  double wall = 0;  // s
  double simulated = 0;
  std::uint64_t steps = 0;
};

template <class World>
Run timed_run(World& world, double seconds) {
  Run r;
  const double dt = world.def().dt;
  const long total = std::lround(seconds / dt);
  const long per_frame = std::max(1L, std::lround(1.0 / 60 / dt));
  const auto start = Clock::now();
  for (long done = 0; done < total; done += per_frame) {
    if (!world.step(static_cast<int>(std::min(per_frame, total - done))).ok()) {
      r.stable = false;
      break;
    }
  }
  r.wall = std::chrono::duration<double>(Clock::now() - start).count();
  r.simulated = world.time();
  r.steps = world.step_count();
  if (!world.all_finite()) r.stable = false;
  return r;
}

// Wall times on a shared machine are noisy: a measurement that took under 0.3 s is repeated
// (at most 5 times; the simulation itself is deterministic) and its fastest time kept.
template <class Measure>
Run fastest(Measure measure) {
  Run best = measure();
  double spent = best.wall;
  for (int repeat = 1; repeat < 5 && spent < 0.3; ++repeat) {
    const Run again = measure();
    spent += again.wall;
    best.wall = std::min(best.wall, again.wall);
  }
  return best;
}

drape::WorldDef world_def(Integrator integrator, double dt) {
  drape::WorldDef wd;
  wd.integrator = integrator;
  wd.dt = dt;
  wd.threads = 1;
  wd.cg_tolerance = 1e-8;  // a float solve stops at its iteration cap instead; that cost is real
  return wd;
}

// ---- oscillator ---------------------------------------------------------------------

struct Oscillator {
  double k = 100.0, m1 = 1.0, m2 = 3.0, rest = 0.8, width = 1.0;
  double omega() const { return std::sqrt(k * (m1 + m2) / (m1 * m2)); }
  double separation(double t) const { return rest + (width - rest) * std::cos(omega() * t); }
  drape::SheetDef sheet() const {
    drape::SheetDef d;
    d.m = 0;
    d.n = 1;
    d.width = width;
    d.rest_length_h = rest;
    d.point_masses = {m1, m2};
    d.stiffness = k;
    return d;
  }
};

// ---- rope: static equilibrium by Newton's method on the potential --------------------

struct Rope {
  std::uint32_t segments = 20;
  double span = 1.0, slack = 1.25;  // rest length of the whole rope = slack · span
  double mass = 0.1, k = 500.0, damping_rate = 3.0, g = 9.81;
  double point_mass() const { return mass / (segments + 1); }
  double rest() const { return slack * span / segments; }
  drape::SheetDef sheet() const {
    drape::SheetDef d;
    d.m = 0;
    d.n = segments;
    d.width = span;
    d.mass = mass;
    d.stiffness = k;
    d.rest_length_h = rest();
    d.damping = damping_rate * point_mass();
    d.pins = {0, segments};
    return d;
  }
};

// E(z) = Σ ½k(|x_{i+1} − x_i| − ℓ)² + Σ m g z_i over the free points, the rope in the x–z
// plane (the symmetric problem keeps y = 0). Newton with a backtracking line search and a
// Levenberg shift while the Hessian is not positive definite.
Positions rope_equilibrium(const Rope& r) {
  const int n = static_cast<int>(r.segments), free = n - 1;
  const double h = r.span / n, rest = r.rest(), m = r.point_mass();
  auto point = [&](const Eigen::VectorXd& q, int i) -> Eigen::Vector2d {
    if (i == 0) return {-r.span / 2, 0.0};
    if (i == n) return {r.span / 2, 0.0};
    return {q[2 * (i - 1)], q[2 * (i - 1) + 1]};
  };
  auto energy = [&](const Eigen::VectorXd& q) {
    double e = 0;
    for (int i = 0; i < n; ++i) {
      const double len = (point(q, i + 1) - point(q, i)).norm();
      e += 0.5 * r.k * (len - rest) * (len - rest);
    }
    for (int i = 1; i < n; ++i) e += m * r.g * point(q, i)[1];
    return e;
  };
  Eigen::VectorXd q(2 * free);
  for (int i = 1; i < n; ++i) {  // a deep parabola: every segment starts stretched
    const double x = -r.span / 2 + i * h, u = 2 * x / r.span;
    q[2 * (i - 1)] = x;
    q[2 * (i - 1) + 1] = -0.6 * r.span * (1 - u * u);
  }
  for (int it = 0; it < 200; ++it) {
    Eigen::VectorXd grad = Eigen::VectorXd::Zero(2 * free);
    Eigen::MatrixXd hess = Eigen::MatrixXd::Zero(2 * free, 2 * free);
    for (int i = 1; i < n; ++i) grad[2 * (i - 1) + 1] += m * r.g;
    for (int i = 0; i < n; ++i) {
      const Eigen::Vector2d d = point(q, i + 1) - point(q, i);
      const double len = d.norm();
      const Eigen::Vector2d u = d / len;
      const Eigen::Vector2d gb = r.k * (len - rest) * u;  // ∂E/∂x_{i+1}
      const Eigen::Matrix2d kb =
          r.k * (u * u.transpose() + (1 - rest / len) * (Eigen::Matrix2d::Identity() - u * u.transpose()));
      const int a = i - 1, b = i;  // free indices of the two ends (−1 / n−1: pinned)
      const bool fa = i >= 1, fb = i + 1 <= n - 1;
      if (fb) grad.segment<2>(2 * b) += gb;
      if (fa) grad.segment<2>(2 * a) -= gb;
      if (fb) hess.block<2, 2>(2 * b, 2 * b) += kb;
      if (fa) hess.block<2, 2>(2 * a, 2 * a) += kb;
      if (fa && fb) {
        hess.block<2, 2>(2 * a, 2 * b) -= kb;
        hess.block<2, 2>(2 * b, 2 * a) -= kb;
      }
    }
    if (grad.norm() < 1e-13 * r.k) break;
    Eigen::VectorXd step;
    for (double shift = 0;; shift = shift == 0 ? 1e-6 * r.k : 10 * shift) {
      Eigen::LLT<Eigen::MatrixXd> llt(hess + shift * Eigen::MatrixXd::Identity(2 * free, 2 * free));
      if (llt.info() == Eigen::Success) {
        step = -llt.solve(grad);
        break;
      }
    }
    double t = 1, e0 = energy(q);
    while (energy(q + t * step) > e0 && t > 1e-12) t /= 2;
    q += t * step;
  }
  Positions p;
  for (int i = 0; i <= n; ++i) {
    const Eigen::Vector2d x = point(q, i);
    p.x.push_back(x[0]);
    p.y.push_back(0.0);
    p.z.push_back(x[1]);
  }
  return p;
}

// ---- fig 5 ----------------------------------------------------------------------------

drape::SheetDef fig5_sheet() {
  drape::SheetDef d;
  d.m = d.n = 30;  // 961 points: the "1000-point cloth"
  d.width = d.height = 1.0;
  d.mass = 1.0;
  d.stiffness = 200.0;
  d.damping = 0.002;
  d.anchors = drape::anchors_at(drape::corner_points(d.m, d.n), 1000.0);
  return d;
}

// ---- output -----------------------------------------------------------------------------

struct Row {
  std::string problem, integrator, precision;
  double dt;
  Run run;
  double error;
};

void write_runs(const std::string& path, const std::vector<Row>& rows) {
  std::ofstream out(path);
  out << "problem,integrator,precision,dt,steps,simulated_s,wall_s,wall_per_simulated_s,stable,error\n";
  out.precision(10);
  for (const auto& r : rows)
    out << r.problem << ',' << r.integrator << ',' << r.precision << ',' << r.dt << ',' << r.run.steps << ','
        << r.run.simulated << ',' << r.run.wall << ',' << (r.run.simulated > 0 ? r.run.wall / r.run.simulated : kNaN)
        << ',' << (r.run.stable ? 1 : 0) << ',' << (r.run.stable ? r.error : kNaN) << '\n';
}

template <class World>
const char* precision_name() {
  return sizeof(typename World::Scalar) == 8 ? "float64" : "float32";
}

template <class World>
void oscillator_runs(std::vector<Row>& rows, const std::vector<double>& steps) {
  const Oscillator o;
  for (Integrator i : drape::integrators())
    for (double dt : steps) {
      auto wd = world_def(i, dt);
      wd.gravity = {0, 0, 0};
      wd.cg_tolerance = sizeof(typename World::Scalar) == 8 ? 1e-13 : 1e-7;
      double err = 0;
      const Run run = fastest([&] {
        World world(wd);
        const auto id = world.add_sheet(o.sheet());
        const Run r = timed_run(world, 1.0);
        const auto v = world.view(id);
        err = std::abs(double(v.x[1]) - double(v.x[0]) - o.separation(world.time())) / (o.width - o.rest);
        return r;
      });
      rows.push_back({"oscillator", std::string(drape::integrator_name(i)), precision_name<World>(), dt, run, err});
    }
}

template <class World>
void rope_runs(std::vector<Row>& rows, const std::vector<double>& steps, const Rope& rope, const Positions& ref) {
  for (Integrator i : drape::integrators())
    for (double dt : steps) {
      double err = 0;
      const Run run = fastest([&] {
        World world(world_def(i, dt));
        const auto id = world.add_sheet(rope.sheet());
        const Run r = timed_run(world, 8.0);
        err = max_distance(positions(world, id), ref) / rope.span;
        return r;
      });
      rows.push_back({"rope", std::string(drape::integrator_name(i)), precision_name<World>(), dt, run, err});
    }
}

template <class World>
void fig5_runs(std::vector<Row>& rows, const std::vector<double>& steps, const Positions& ref) {
  for (Integrator i : drape::integrators())
    for (double dt : steps) {
      double err = 0;
      const Run run = fastest([&] {
        World world(world_def(i, dt));
        const auto id = world.add_sheet(fig5_sheet());
        const Run r = timed_run(world, 1.0);
        err = max_distance(positions(world, id), ref) / 1.0;
        return r;
      });
      rows.push_back({"fig5", std::string(drape::integrator_name(i)), precision_name<World>(), dt, run, err});
    }
}

// ---- stiff sheets ----------------------------------------------------------------------

constexpr double stiff_seconds = 0.2;

drape::SheetDef stiff_sheet(double k) {
  drape::SheetDef d;
  d.m = d.n = 127;
  d.mass = 1.0;
  d.stiffness = k;
  d.pins = drape::corner_points(d.m, d.n);
  return d;
}

// Every stepping tried on the stiff sheet: explicit ones just inside their limit, the
// implicit ones at frame-sized steps and below; local/global at several budgets.
struct Stepping {
  Integrator integrator;
  double dt;       // > 0: s; ≤ 0: −dt × the integrator's critical step on the sheet
  int iterations;  // local_global_iterations or vertex_block_iterations
};

void stiff_runs(std::ofstream& out, const std::vector<double>& ks, bool quick) {
  for (double k : ks) {
    Positions ref;
    {
      drape::World world(world_def(Integrator::RK4, 1e-3));
      const auto id = world.add_sheet(stiff_sheet(k));
      const double h = 0.5 * world.critical_step(Integrator::RK4);
      const long steps = std::lround(std::ceil(stiff_seconds / h));
      world.set_dt(stiff_seconds / double(steps));
      world.step(int(steps));
      ref = positions(world, id);
    }
    // RK4 is left out (the reference is RK4; at 0.8× its limit it costs several times
    // semi-implicit Euler), and implicit Euler runs only at a frame's step: its 200-iteration
    // solves on 16,384 points cost about a minute per k at smaller steps.
    std::vector<Stepping> steppings = {{Integrator::SemiImplicitEuler, -0.8, 1}, {Integrator::ImplicitEuler, 1.0 / 60, 1}};
    for (double dt : {1.0 / 60, 1.0 / 240, 1.0 / 960})
      for (int it : {2, 10, 50})
        if (!(dt < 1.0 / 500 && it > 10)) steppings.push_back({Integrator::LocalGlobal, dt, it});
    for (double dt : {1.0 / 60, 1.0 / 240})
      for (int it : {2, 10, 50})
        if (!(dt < 1.0 / 200 && it > 10)) steppings.push_back({Integrator::VertexBlockDescent, dt, it});
    if (quick) steppings.resize(3);
    for (const Stepping& s : steppings) {
      auto wd = world_def(s.integrator, 1e-3);
      wd.local_global_iterations = s.iterations;
      wd.vertex_block_iterations = s.iterations;
      double err = 0, stretch = 0;
      std::uint64_t unconverged = 0;
      double dt = s.dt;
      const Run run = fastest([&] {
        drape::World world(wd);
        const auto id = world.add_sheet(stiff_sheet(k));
        if (dt <= 0) dt = -s.dt * world.critical_step(s.integrator);
        dt = stiff_seconds / std::ceil(stiff_seconds / dt);  // land on the reference's time
        world.set_dt(dt);
        const Run r = timed_run(world, stiff_seconds);
        err = max_distance(positions(world, id), ref) / 1.0;
        stretch = world.diagnostics(id).max_strain;
        unconverged = world.solver_stats(id).unconverged_solves;
        return r;
      });
      out << k << ',' << drape::integrator_name(s.integrator) << ',' << dt << ',' << s.iterations << ',' << run.steps
          << ',' << run.wall / run.simulated << ',' << (run.stable ? 1 : 0) << ',' << (run.stable ? err : kNaN) << ','
          << stretch << ',' << unconverged << '\n';
      out.flush();
    }
  }
}

// The sheet of the stability region: 16×16 points, 1 kg, springs and corner anchors of
// stiffness k, slightly prestressed so the stiff modes are excited from the start.
drape::SheetDef region_sheet(double k) {
  drape::SheetDef d;
  d.m = d.n = 15;
  d.mass = 1.0;
  d.stiffness = k;
  d.damping = 0.001;
  d.anchors = drape::anchors_at(drape::corner_points(d.m, d.n), k);
  d.rest_length_h = d.rest_length_v = 0.95 / 15;
  return d;
}

// Largest stable step by bisection in log(dt): a step is stable when 400 steps (or 2 s)
// pass the guard.
template <class World>
bool stable_at(Integrator integrator, double k, double dt) {
  auto wd = world_def(integrator, dt);
  wd.cg_max_iterations = 100;
  World world(wd);
  world.add_sheet(region_sheet(k));
  const int steps = static_cast<int>(std::min(400.0, std::ceil(2.0 / dt)));
  for (int done = 0; done < steps; done += 20)
    if (!world.step(std::min(20, steps - done)).ok()) return false;
  return world.all_finite();
}

// One simulated second at the largest step that is stable and no longer than a 60 fps frame
// (90 % of the measured limit), in frames of 1/60 s: what "stable, as fast as possible"
// costs with each integrator.
template <class World>
std::pair<Run, int> frame_cost(Integrator integrator, double k, double largest_stable) {
  const auto wd = world_def(integrator, std::min(1.0 / 60, 0.9 * largest_stable));
  int cg = 0;
  const Run run = fastest([&] {
    World world(wd);
    const auto id = world.add_sheet(region_sheet(k));
    Run r;
    const auto start = Clock::now();
    for (int f = 0; f < 60 && r.stable; ++f) r.stable = world.advance((f + 1) / 60.0 - world.time()).ok();
    r.wall = std::chrono::duration<double>(Clock::now() - start).count();
    r.simulated = world.time();
    r.steps = world.step_count();
    cg = world.solver_stats(id).iterations;
    return r;
  });
  return {run, cg};
}

template <class World>
void stability_region(std::ofstream& out, const std::vector<double>& stiffnesses) {
  for (Integrator i : drape::integrators())
    for (double k : stiffnesses) {
      double estimate;
      {
        World world(world_def(i, 1e-3));
        world.add_sheet(region_sheet(k));
        estimate = world.critical_step(i);
      }
      const double lo_bound = 1e-9, hi_bound = 1.0;
      double lo = lo_bound, hi = hi_bound;
      if (stable_at<World>(i, k, hi)) {
        lo = hi;
      } else if (!stable_at<World>(i, k, lo)) {
        hi = lo;
      } else {
        while (hi / lo > 1.05) {
          const double mid = std::sqrt(lo * hi);
          (stable_at<World>(i, k, mid) ? lo : hi) = mid;
        }
      }
      const auto [run, cg] = frame_cost<World>(i, k, lo);
      out << precision_name<World>() << ',' << drape::integrator_name(i) << ',' << k << ',' << estimate << ',' << lo
          << ',' << (lo >= hi_bound ? 1 : 0) << ',' << run.steps << ',' << run.wall / run.simulated << ','
          << (run.stable ? 1 : 0) << ',' << cg << '\n';
    }
}

}  // namespace

int main(int argc, char** argv) {
  const char* usage = "usage: drape-accuracy OUT_DIR [--quick] [--only runs,stiff,stability]\n";
  if (argc < 2) {
    std::cerr << usage;
    return 2;
  }
  const std::string dir = argv[1];
  bool quick = false;
  std::string only = "runs,stiff,stability";
  for (int k = 2; k < argc; ++k) {
    if (std::strcmp(argv[k], "--quick") == 0) {
      quick = true;
    } else if (std::strcmp(argv[k], "--only") == 0 && k + 1 < argc) {
      only = argv[++k];
    } else {
      std::cerr << "drape-accuracy: unknown argument " << argv[k] << "\n" << usage;
      return 2;
    }
  }
  auto wanted = [&](const std::string& section) { return ("," + only + ",").find("," + section + ",") != std::string::npos; };
  for (std::size_t at = 0; at <= only.size();) {
    const std::size_t comma = std::min(only.find(',', at), only.size());
    const std::string section = only.substr(at, comma - at);
    if (section != "runs" && section != "stiff" && section != "stability") {
      std::cerr << "drape-accuracy: --only: unknown section \"" << section << "\"\n" << usage;
      return 2;
    }
    at = comma + 1;
  }
  {
    std::ofstream probe(dir + "/accuracy_meta.csv");
    if (!probe) {
      std::cerr << "drape-accuracy: cannot write to directory " << dir << "\n";
      return 1;
    }
    probe << "key,value\n";
    probe << "compiler,\"" << __VERSION__ << "\"\n";
    probe << "build_type," << DRAPE_BUILD_TYPE << "\n";
    probe << "flags,\"" << DRAPE_CXX_FLAGS << "\"\n";
    probe << "threads,1\n";
    const drape::WorldDef defaults = world_def(Integrator::ImplicitEuler, 1e-3);
    probe << "cg_tolerance," << defaults.cg_tolerance << "\n";
    probe << "cg_max_iterations," << defaults.cg_max_iterations << "\n";
    probe << "cg_preconditioner," << drape::preconditioner_name(defaults.cg_preconditioner) << "\n";
    probe << "local_global_iterations," << defaults.local_global_iterations << "\n";
    probe << "vertex_block_iterations," << defaults.vertex_block_iterations << "\n";
    // the integrator table, so the report names, orders and classes them as the engine does
    for (const drape::IntegratorInfo& row : drape::integrator_table())
      probe << "integrator:" << row.name << ',' << row.order << ':' << (row.is_explicit ? 1 : 0) << "\n";
    probe << "stiff_seconds," << stiff_seconds << "\n";
  }

  if (wanted("runs")) {
    std::vector<Row> rows;
    std::cerr << "oscillator...\n";
    const std::vector<double> osc_steps = quick ? std::vector<double>{1e-2, 1e-3}
                                                : std::vector<double>{1e-1, 5e-2, 2e-2, 1e-2, 5e-3, 2e-3, 1e-3,
                                                                      5e-4, 2e-4, 1e-4, 5e-5, 2e-5, 1e-5};
    oscillator_runs<drape::World>(rows, osc_steps);
    oscillator_runs<drape::WorldF>(rows, osc_steps);

    std::cerr << "rope...\n";
    const Rope rope;
    const Positions rope_ref = rope_equilibrium(rope);
    const std::vector<double> rope_steps = quick ? std::vector<double>{1e-3}
                                                 : std::vector<double>{1.0 / 60, 1e-2, 5e-3, 2e-3, 1e-3, 5e-4, 2e-4};
    rope_runs<drape::World>(rows, rope_steps, rope, rope_ref);
    rope_runs<drape::WorldF>(rows, rope_steps, rope, rope_ref);

    std::cerr << "fig5 reference...\n";
    Positions fig5_ref;
    {
      drape::World ref(world_def(Integrator::RK4, quick ? 1e-4 : 1e-5));
      const auto id = ref.add_sheet(fig5_sheet());
      ref.step(quick ? 10000 : 100000);
      fig5_ref = positions(ref, id);
    }
    std::cerr << "fig5...\n";
    const std::vector<double> fig5_steps =
        quick ? std::vector<double>{1e-3}
              : std::vector<double>{1.0 / 60, 1e-2, 4e-3, 2e-3, 1e-3, 5e-4, 2e-4, 1e-4, 5e-5};
    fig5_runs<drape::World>(rows, fig5_steps, fig5_ref);
    fig5_runs<drape::WorldF>(rows, fig5_steps, fig5_ref);
    write_runs(dir + "/accuracy_runs.csv", rows);
  }

  if (wanted("stiff")) {
    std::cerr << "stiff sheets...\n";
    std::ofstream stiff(dir + "/accuracy_stiff.csv");
    stiff << "k,integrator,dt,iterations,steps,wall_per_simulated_s,stable,error,max_stretch,unconverged_solves\n";
    stiff.precision(6);
    stiff_runs(stiff, quick ? std::vector<double>{1e2, 1e5} : std::vector<double>{1e2, 1e3, 1e4, 1e5, 1e6, 1e7}, quick);
  }

  if (wanted("stability")) {
    std::cerr << "stability region...\n";
    std::ofstream out(dir + "/accuracy_stability.csv");
    out << "precision,integrator,k,estimate_dt,largest_stable_dt,at_search_limit,frame_run_steps,frame_run_wall_per_simulated_s,frame_run_stable,frame_run_cg_iterations\n";
    out.precision(6);
    const std::vector<double> ks = quick ? std::vector<double>{1, 1e4} : std::vector<double>{1, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6, 1e7, 1e8};
    stability_region<drape::World>(out, ks);
    stability_region<drape::WorldF>(out, ks);
  }
  return 0;
}
