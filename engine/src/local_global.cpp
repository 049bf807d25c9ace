// Local/global backward Euler (Liu et al. 2013): see local_global.h for the iteration.
#include "local_global.h"

#include <Eigen/SparseCholesky>

#include <algorithm>
#include <cmath>

#include "forces.h"
#include "terms/terms.h"

namespace drape::detail {

namespace {

template <class Real>
std::vector<double> widen(const AlignedArray<Real>& a) { return {a.begin(), a.end()}; }
template <class Real>
std::vector<double> widen(const std::vector<Real>& a) { return {a.begin(), a.end()}; }

// Whether `wide` holds exactly the values of `a` (compared without a copy: this runs every step).
template <class Array>
bool same_values(const std::vector<double>& wide, const Array& a) {
  return wide.size() == a.size() && std::equal(a.begin(), a.end(), wide.begin(), [](auto x, double y) { return double(x) == y; });
}

// Whether the factored matrix was built for this sheet and step.
template <class Real>
bool factor_current(const LocalGlobalScratch& sc, const Sheet<Real>& s, double dt) {
  return sc.topology == s.topology && sc.dt == dt && same_values(sc.mass, s.mass) && same_values(sc.damping, s.damping) &&
         sc.anchor_point == s.anchors.point && same_values(sc.anchor_stiffness, s.anchors.stiffness) &&
         sc.pin_point == s.pins.point;
}

}  // namespace

void cholesky_pattern(const LocalGlobalScratch::Matrix& lower, std::vector<int>& column_start, std::vector<int>& row_index,
                      std::vector<int>& permutation) {
  using Matrix = LocalGlobalScratch::Matrix;
  const Eigen::Index n = lower.rows();
  Eigen::SimplicialLLT<Matrix, Eigen::Lower, Eigen::AMDOrdering<int>> ordering;
  ordering.analyzePattern(lower);
  const auto& order = ordering.permutationP();
  permutation.assign(order.indices().data(), order.indices().data() + n);
  Matrix upper(n, n);  // the permuted matrix's upper triangle: column k holds row k of L's pattern source
  upper.template selfadjointView<Eigen::Upper>() = lower.template selfadjointView<Eigen::Lower>().twistedBy(order);
  // the elimination tree (path compression through `ancestor`)
  std::vector<int> parent(std::size_t(n), -1), ancestor(std::size_t(n), -1);
  for (int k = 0; k < int(n); ++k)
    for (Matrix::InnerIterator it(upper, k); it; ++it)
      for (int i = int(it.row()), next; i != -1 && i < k; i = next) {
        next = ancestor[std::size_t(i)];
        ancestor[std::size_t(i)] = k;
        if (next == -1) parent[std::size_t(i)] = k;
      }
  // row k of L: the columns on the tree's paths up from row k's entries of A to k; two
  // passes, counting and then filling, k ascending so each column's rows come in order
  std::vector<int> mark(std::size_t(n), -1), fill(std::size_t(n) + 1, 0);
  column_start.assign(std::size_t(n) + 1, 0);
  for (int pass = 0; pass < 2; ++pass) {
    std::fill(mark.begin(), mark.end(), -1);
    for (int k = 0; k < int(n); ++k) {
      mark[std::size_t(k)] = k;
      auto add = [&](int column) {
        if (pass == 0)
          ++column_start[std::size_t(column) + 1];
        else
          row_index[std::size_t(fill[std::size_t(column)]++)] = k;
      };
      add(k);  // the diagonal, first in its column
      for (Matrix::InnerIterator it(upper, k); it; ++it)
        for (int j = int(it.row()); mark[std::size_t(j)] != k; j = parent[std::size_t(j)]) {
          mark[std::size_t(j)] = k;
          add(j);
        }
    }
    if (pass == 0) {
      for (Eigen::Index j = 0; j < n; ++j) column_start[std::size_t(j) + 1] += column_start[std::size_t(j)];
      std::copy(column_start.begin(), column_start.end(), fill.begin());
      row_index.resize(std::size_t(column_start.back()));
    }
  }
}

namespace {

// The key and the buffers of a step, and with factor_too the factored M̃ + dt²·L +
// dt²·K_anchor over the free points (with pattern_only, only its pattern and permutation);
// a pinned point's row and column are the identity (its springs to free points move to the
// right-hand side, local_global_step).
template <class Real>
void build_factor(LocalGlobalScratch& sc, const Sheet<Real>& s, double dt, bool factor_too, bool pattern_only = false) {
  const auto& t = *s.topology;
  const std::size_t count = s.size();
  sc.topology = s.topology;
  sc.dt = dt;
  sc.mass = widen(s.mass);
  sc.damping = widen(s.damping);
  sc.anchor_point = s.anchors.point;
  sc.anchor_stiffness = widen(s.anchors.stiffness);
  // the topology is part of the key: these stay valid with it
  sc.edge_a = t.a;
  sc.edge_b = t.b;
  sc.rest = widen(t.rest_length);
  sc.stiffness = widen(t.stiffness);
  if (t.shear)
    shear::for_each_spring(t, [&](std::uint32_t a, std::uint32_t b) {
      sc.edge_a.push_back(a);
      sc.edge_b.push_back(b);
      sc.rest.push_back(double(t.shear->rest));
      sc.stiffness.push_back(double(t.shear->stiffness));
    });
  sc.implicit_bending = factor_too && t.bending.has_value();
  sc.pin_point = s.pins.point;
  sc.pinned.assign(count, 0);
  for (std::uint32_t p : s.pins.point) sc.pinned[p] = 1;
  for (int r = 0; r < 3; ++r) {
    sc.inertia[r].resize(Eigen::Index(count));
    sc.rhs[r].resize(Eigen::Index(count));
    sc.solution[r].resize(Eigen::Index(count));
    sc.start[r].resize(count);
    sc.spring_force[r].resize(count);
    sc.other_force[r].resize(count);
    sc.direction[r].resize(sc.edge_a.size());
  }
  sc.column_start.clear();
  sc.inverse_diagonal.clear();
  if (!factor_too) return;  // vertex block descent needs the key and the buffers only

  const double dt2 = dt * dt;
  std::vector<double> diagonal(count);
  for (std::size_t p = 0; p < count; ++p) diagonal[p] = sc.mass[p] + (sc.damping.empty() ? 0.0 : dt * sc.damping[p]);
  for (std::size_t k = 0; k < sc.anchor_point.size(); ++k) diagonal[sc.anchor_point[k]] += dt2 * sc.anchor_stiffness[k];
  std::vector<Eigen::Triplet<double, int>> entries;
  entries.reserve(count + sc.edge_a.size());
  for (std::size_t e = 0; e < sc.edge_a.size(); ++e) {
    const std::uint32_t a = sc.edge_a[e], b = sc.edge_b[e];
    const double w = dt2 * sc.stiffness[e];
    diagonal[a] += w;
    diagonal[b] += w;
    if (!sc.pinned[a] && !sc.pinned[b]) entries.emplace_back(int(std::max(a, b)), int(std::min(a, b)), -w);
  }
  // bending's Hessian k_b DᵀD = −J (terms/bending.h), the lower triangle
  if (sc.implicit_bending)
    bending::add_jacobian(t, [&](std::uint32_t p, std::uint32_t q, const Real (&j)[3][3]) {
      const double w = -dt2 * double(j[0][0]);
      if (p == q)
        diagonal[p] += w;
      else if (p > q && !sc.pinned[p] && !sc.pinned[q])
        entries.emplace_back(int(p), int(q), w);
    });
  for (std::size_t p = 0; p < count; ++p) entries.emplace_back(int(p), int(p), sc.pinned[p] ? 1.0 : diagonal[p]);
  LocalGlobalScratch::Matrix system(static_cast<Eigen::Index>(count), static_cast<Eigen::Index>(count));
  system.setFromTriplets(entries.begin(), entries.end());
  ++sc.factorisations;
  if (pattern_only) {
    sc.value.clear();
    cholesky_pattern(system, sc.column_start, sc.row_index, sc.permutation);
    return;
  }
  // SPD: positive masses on the diagonal, a weighted Laplacian added
  Eigen::SimplicialLLT<LocalGlobalScratch::Matrix, Eigen::Lower, Eigen::AMDOrdering<int>> factor(system);
  const auto& l = factor.matrixL().nestedExpression();
  sc.column_start.assign(l.outerIndexPtr(), l.outerIndexPtr() + count + 1);
  sc.row_index.assign(l.innerIndexPtr(), l.innerIndexPtr() + l.nonZeros());
  sc.value.assign(l.valuePtr(), l.valuePtr() + l.nonZeros());
  sc.inverse_diagonal.resize(count);
  for (std::size_t j = 0; j < count; ++j) sc.inverse_diagonal[j] = 1.0 / sc.value[std::size_t(sc.column_start[j])];
  const auto& indices = factor.permutationP().indices();
  sc.permutation.assign(indices.data(), indices.data() + count);
  sc.work.resize(3 * count);
}

// The local step at positions `x` (sc.solution): every spring's d_e; with `force`, also
// the spring forces k(x_a − x_b − d_e) (eq 6) into sc.spring_force.
void local_step(LocalGlobalScratch& sc, const std::vector<std::uint32_t>& ea, const std::vector<std::uint32_t>& eb,
                const double* rest, const double* stiffness, std::uint32_t springs, bool force) {
  const double* x[3] = {sc.solution[0].data(), sc.solution[1].data(), sc.solution[2].data()};
  if (force)
    for (int r = 0; r < 3; ++r) std::fill(sc.spring_force[r].begin(), sc.spring_force[r].end(), 0.0);
  for (std::uint32_t e = 0; e < springs; ++e) {
    const std::uint32_t a = ea[e], b = eb[e];
    const double d[3] = {x[0][a] - x[0][b], x[1][a] - x[1][b], x[2][a] - x[2][b]};
    const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
    // eq (6): a spring of zero length has no direction and no force; with ℓ = 0, d_e = 0
    const double scale = len > 0 ? rest[e] / len : (rest[e] == 0 ? 0.0 : 1.0);
    for (int r = 0; r < 3; ++r) {
      const double de = scale * d[r];
      sc.direction[r][e] = de;
      if (force) {
        const double f = stiffness[e] * (de - d[r]);  // on a: −k(1 − ℓ/L)(x_a − x_b)
        sc.spring_force[r][a] += f;
        sc.spring_force[r][b] -= f;
      }
    }
  }
}

// Bending's force at `x` (sc.solution), added to sc.spring_force: f = J x, exact for the
// quadratic energy (its Jacobian is constant, terms/bending.h).
template <class Real>
void add_bending_force(LocalGlobalScratch& sc, const Topology<Real>& t) {
  const double* x[3] = {sc.solution[0].data(), sc.solution[1].data(), sc.solution[2].data()};
  bending::add_jacobian(t, [&](std::uint32_t p, std::uint32_t q, const Real (&j)[3][3]) {
    for (int r = 0; r < 3; ++r) sc.spring_force[r][p] += double(j[0][0]) * x[r][q];
  });
}

// Springs' (and implicit bending's) forces at sc.solution into sc.spring_force.
template <class Real>
void implicit_forces(LocalGlobalScratch& sc, const Topology<Real>& t) {
  local_step(sc, sc.edge_a, sc.edge_b, sc.rest.data(), sc.stiffness.data(), std::uint32_t(sc.edge_a.size()), true);
  if (sc.implicit_bending) add_bending_force(sc, t);
}

// The global step for all three axes: sc.rhs → sc.solution through L Lᵀ (permuted). The
// axes run interleaved, so each entry of L is read once for three values: measured on this
// machine, one pass for three axes took half the time of three passes, which beats even
// three passes on two cores.
void global_solve(LocalGlobalScratch& sc) {
  const std::size_t count = sc.inverse_diagonal.size();
  double* w = sc.work.data();
  const int* start = sc.column_start.data();
  const int* row = sc.row_index.data();
  const double* l = sc.value.data();
  for (std::size_t p = 0; p < count; ++p) {
    double* q = w + 3 * std::size_t(sc.permutation[p]);
    q[0] = sc.rhs[0][Eigen::Index(p)];
    q[1] = sc.rhs[1][Eigen::Index(p)];
    q[2] = sc.rhs[2][Eigen::Index(p)];
  }
  for (std::size_t j = 0; j < count; ++j) {  // L y = b, column by column
    const double inv = sc.inverse_diagonal[j];
    const double a0 = w[3 * j] * inv, a1 = w[3 * j + 1] * inv, a2 = w[3 * j + 2] * inv;
    w[3 * j] = a0;
    w[3 * j + 1] = a1;
    w[3 * j + 2] = a2;
    for (int k = start[j] + 1; k < start[j + 1]; ++k) {
      double* q = w + 3 * std::size_t(row[k]);
      q[0] -= l[k] * a0;
      q[1] -= l[k] * a1;
      q[2] -= l[k] * a2;
    }
  }
  for (std::size_t j = count; j-- > 0;) {  // Lᵀ x = y, a dot product per column
    double s0 = w[3 * j], s1 = w[3 * j + 1], s2 = w[3 * j + 2];
    for (int k = start[j] + 1; k < start[j + 1]; ++k) {
      const double* q = w + 3 * std::size_t(row[k]);
      s0 -= l[k] * q[0];
      s1 -= l[k] * q[1];
      s2 -= l[k] * q[2];
    }
    const double inv = sc.inverse_diagonal[j];
    w[3 * j] = s0 * inv;
    w[3 * j + 1] = s1 * inv;
    w[3 * j + 2] = s2 * inv;
  }
  for (std::size_t p = 0; p < count; ++p) {
    const double* q = w + 3 * std::size_t(sc.permutation[p]);
    sc.solution[0][Eigen::Index(p)] = q[0];
    sc.solution[1][Eigen::Index(p)] = q[1];
    sc.solution[2][Eigen::Index(p)] = q[2];
  }
}

}  // namespace

template <class Real>
void prepare_factor(LocalGlobalScratch& sc, const Sheet<Real>& s, double dt) {
  if (!factor_current(sc, s, dt) || sc.inverse_diagonal.size() != s.size()) build_factor(sc, s, dt, true);
}

template <class Real>
void prepare_pattern(LocalGlobalScratch& sc, const Sheet<Real>& s, double dt) {
  if (!factor_current(sc, s, dt) || sc.column_start.size() != s.size() + 1) build_factor(sc, s, dt, true, true);
}

template <class Real>
void backward_euler_begin(LocalGlobalScratch& sc, Sheet<Real>& s, const StepParams<Real>& p, bool factor) {
  const double h = static_cast<double>(p.dt), h2 = h * h;
  if (factor)
    prepare_factor(sc, s, h);
  else if (!factor_current(sc, s, h))
    build_factor(sc, s, h, false);

  const auto& t = *s.topology;
  const std::size_t count = s.size();
  const Real* x[3] = {s.position.x.data(), s.position.y.data(), s.position.z.data()};
  const Real* v[3] = {s.velocity.x.data(), s.velocity.y.data(), s.velocity.z.data()};
  const double g[3] = {static_cast<double>(p.gx), static_cast<double>(p.gy), static_cast<double>(p.gz)};
  const auto& an = s.anchors;
  const bool damped = !sc.damping.empty();

  // Every force but springs, damping and anchors (contacts, obstacles, and any term added
  // to sheet_forces later) enters explicitly, at the start of the step: the total minus
  // those three, which the iteration treats implicitly.
  for (int r = 0; r < 3; ++r) {
    sc.start[r].assign(x[r], x[r] + count);
    std::copy(x[r], x[r] + count, sc.solution[r].data());
  }
  implicit_forces(sc, t);
  sheet_forces(s, cptr(s.position), cptr(s.velocity), ptr(s.force));
  const Real* f[3] = {s.force.x.data(), s.force.y.data(), s.force.z.data()};
  for (int r = 0; r < 3; ++r)
    for (std::size_t q = 0; q < count; ++q)
      sc.other_force[r][q] = double(f[r][q]) - sc.spring_force[r][q] + (damped ? sc.damping[q] * double(v[r][q]) : 0.0);
  for (std::size_t k = 0; k < an.point.size(); ++k) {
    const std::uint32_t q = an.point[k];
    const double target[3] = {double(an.tx[k]), double(an.ty[k]), double(an.tz[k])};
    for (int r = 0; r < 3; ++r) sc.other_force[r][q] -= sc.anchor_stiffness[k] * (target[r] - sc.start[r][q]);
  }
  // M̃ x̂ = M(x + h v) + h C x + h²(f_other + M g)
  for (int r = 0; r < 3; ++r) {
    double* in = sc.inertia[r].data();
    for (std::size_t q = 0; q < count; ++q) {
      const double xq = sc.start[r][q], vq = double(v[r][q]);
      in[q] = sc.mass[q] * (xq + h * vq) + (damped ? h * sc.damping[q] * xq : 0.0) +
              h2 * (sc.other_force[r][q] + sc.mass[q] * g[r]);
    }
  }
  // the first iterate: the inertial prediction x + h v, pins on their targets
  for (int r = 0; r < 3; ++r)
    for (std::size_t q = 0; q < count; ++q) sc.solution[r][Eigen::Index(q)] = sc.start[r][q] + h * double(v[r][q]);
  const auto& pins = s.pins;
  for (std::size_t k = 0; k < pins.point.size(); ++k) {
    const double target[3] = {double(pins.tx[k]), double(pins.ty[k]), double(pins.tz[k])};
    for (int r = 0; r < 3; ++r) sc.solution[r][pins.point[k]] = target[r];
  }
}

template <class Real>
void backward_euler_finish(LocalGlobalScratch& sc, Sheet<Real>& s, const StepParams<Real>& p, int iterations) {
  const double h = static_cast<double>(p.dt), h2 = h * h;
  const auto& t = *s.topology;
  const std::size_t count = s.size();
  Real* v[3] = {s.velocity.x.data(), s.velocity.y.data(), s.velocity.z.data()};
  const double g[3] = {static_cast<double>(p.gx), static_cast<double>(p.gy), static_cast<double>(p.gz)};
  const auto& an = s.anchors;
  const bool damped = !sc.damping.empty();
  // Residual of the backward-Euler equations at the result, over the free points:
  //   M(x − x0 − h v0) + h C (x − x0) − h²(f_spring(x) + f_anchor(x) + f_other + M g),
  // relative to the sizes of its terms: the momentum change, the implicit forces and the
  // held ones. (Relative to the two sides' sums, a sheet at rest, where both vanish while
  // its springs hold its weight, measured 0/0 and reported every step unconverged.)
  implicit_forces(sc, t);
  for (std::size_t k = 0; k < an.point.size(); ++k) {
    const double target[3] = {double(an.tx[k]), double(an.ty[k]), double(an.tz[k])};
    for (int r = 0; r < 3; ++r)
      sc.spring_force[r][an.point[k]] += sc.anchor_stiffness[k] * (target[r] - sc.solution[r][an.point[k]]);
  }
  double residual2 = 0, left2 = 0, implicit2 = 0, held2 = 0;
  for (int r = 0; r < 3; ++r)
    for (std::size_t q = 0; q < count; ++q) {
      if (sc.pinned[q]) continue;
      const double xq = sc.solution[r][Eigen::Index(q)], x0 = sc.start[r][q];
      const double left = sc.mass[q] * (xq - x0 - h * double(v[r][q])) + (damped ? h * sc.damping[q] * (xq - x0) : 0.0);
      const double implicit = h2 * sc.spring_force[r][q], held = h2 * (sc.other_force[r][q] + sc.mass[q] * g[r]);
      const double residual = left - implicit - held;
      residual2 += residual * residual;
      left2 += left * left;
      implicit2 += implicit * implicit;
      held2 += held * held;
    }
  const double scale = std::sqrt(left2) + std::sqrt(implicit2) + std::sqrt(held2);
  const double residual = scale > 0 ? std::sqrt(residual2) / scale : 0.0;
  record_solve(s.last_solve, iterations, residual, residual <= p.cg_tolerance);

  Real* pos[3] = {s.position.x.data(), s.position.y.data(), s.position.z.data()};
  for (int r = 0; r < 3; ++r)
    for (std::size_t q = 0; q < count; ++q) {
      const double xq = sc.solution[r][Eigen::Index(q)];
      v[r][q] = static_cast<Real>((xq - sc.start[r][q]) / h);
      pos[r][q] = static_cast<Real>(xq);
    }
}

template <class Real>
void local_global_step(Sheet<Real>& s, const StepParams<Real>& p) {
  if (!s.local_global_scratch || s.local_global_scratch.use_count() > 1)
    s.local_global_scratch = std::make_shared<LocalGlobalScratch>();
  auto& sc = *s.local_global_scratch;
  backward_euler_begin(sc, s, p, true);
  const double h2 = double(p.dt) * double(p.dt);
  const auto& t = *s.topology;
  const std::uint32_t springs = std::uint32_t(sc.edge_a.size());
  const std::vector<double>& stiffness = sc.stiffness;
  const std::uint32_t* ea = sc.edge_a.data();
  const std::uint32_t* eb = sc.edge_b.data();
  const auto& an = s.anchors;

  // The constant parts of the global step's right-hand side besides M̃ x̂: h²·k·p0 of
  // anchors, and for springs to pinned points h²·k·x_pin (pinned rows hold the target).
  for (std::size_t k = 0; k < an.point.size(); ++k) {
    const double target[3] = {double(an.tx[k]), double(an.ty[k]), double(an.tz[k])};
    for (int r = 0; r < 3; ++r) sc.inertia[r][an.point[k]] += h2 * sc.anchor_stiffness[k] * target[r];
  }
  const auto& pins = s.pins;
  for (std::size_t k = 0; k < pins.point.size(); ++k) {
    const double target[3] = {double(pins.tx[k]), double(pins.ty[k]), double(pins.tz[k])};
    for (int r = 0; r < 3; ++r) sc.inertia[r][pins.point[k]] = target[r];
  }
  for (std::uint32_t e = 0; e < springs; ++e) {
    const std::uint32_t a = ea[e], b = eb[e];
    if (sc.pinned[a] == sc.pinned[b]) continue;
    const std::uint32_t pin = sc.pinned[a] ? a : b, free = sc.pinned[a] ? b : a;
    for (int r = 0; r < 3; ++r) sc.inertia[r][free] += h2 * stiffness[e] * sc.inertia[r][pin];
  }
  if (sc.implicit_bending)  // bending's coupling to pinned points: −h²·K_bend·x_pin = h²·J·x_pin
    bending::add_jacobian(t, [&](std::uint32_t p, std::uint32_t q, const Real (&j)[3][3]) {
      if (sc.pinned[p] || !sc.pinned[q]) return;
      for (int r = 0; r < 3; ++r) sc.inertia[r][p] += h2 * double(j[0][0]) * sc.inertia[r][q];
    });

  const int iterations = std::max(1, p.local_global_iterations);
  for (int it = 0; it < iterations; ++it) {
    local_step(sc, sc.edge_a, sc.edge_b, sc.rest.data(), stiffness.data(), springs, false);
    for (int r = 0; r < 3; ++r) {
      sc.rhs[r] = sc.inertia[r];
      double* rhs = sc.rhs[r].data();
      const double* d = sc.direction[r].data();
      for (std::uint32_t e = 0; e < springs; ++e) {
        const double w = h2 * stiffness[e] * d[e];
        if (!sc.pinned[ea[e]]) rhs[ea[e]] += w;
        if (!sc.pinned[eb[e]]) rhs[eb[e]] -= w;
      }
    }
    global_solve(sc);
  }
  backward_euler_finish(sc, s, p, iterations);
}

template void backward_euler_begin<double>(LocalGlobalScratch&, Sheet<double>&, const StepParams<double>&, bool);
template void backward_euler_begin<float>(LocalGlobalScratch&, Sheet<float>&, const StepParams<float>&, bool);
template void backward_euler_finish<double>(LocalGlobalScratch&, Sheet<double>&, const StepParams<double>&, int);
template void backward_euler_finish<float>(LocalGlobalScratch&, Sheet<float>&, const StepParams<float>&, int);
template void prepare_factor<double>(LocalGlobalScratch&, const Sheet<double>&, double);
template void prepare_factor<float>(LocalGlobalScratch&, const Sheet<float>&, double);
template void prepare_pattern<double>(LocalGlobalScratch&, const Sheet<double>&, double);
template void prepare_pattern<float>(LocalGlobalScratch&, const Sheet<float>&, double);
template void local_global_step<double>(Sheet<double>&, const StepParams<double>&);
template void local_global_step<float>(Sheet<float>&, const StepParams<float>&);

}  // namespace drape::detail
