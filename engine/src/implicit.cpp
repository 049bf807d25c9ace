// Implicit Euler (Baraff & Witkin 1998): see implicit.h for the system solved.
#include "implicit.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <utility>

#include "diagnostics.h"
#include "forces.h"
#include "local_global.h"
#include "spring_jacobian.h"
#include "terms/terms.h"

namespace drape::detail {

namespace {

// Value offset of entry (row, col) in a compressed row-major matrix; the entry must exist.
template <class Matrix>
int offset_of(const Matrix& a, int row, int col) {
  const int* begin = a.innerIndexPtr() + a.outerIndexPtr()[row];
  const int* end = a.innerIndexPtr() + a.outerIndexPtr()[row + 1];
  return static_cast<int>(std::lower_bound(begin, end, col) - a.innerIndexPtr());
}

// The pattern depends only on the grid and the pins, so it is built once per sheet.
template <class Real>
void build_pattern(ImplicitScratch<Real>& sc, const Sheet<Real>& s) {
  const auto& t = *s.topology;
  const std::size_t count = s.size();
  const int n3 = static_cast<int>(3 * count);
  // Per point p, the points q of its blocks (p, q): itself, its springs' other ends and
  // wherever the other terms' Jacobians reach (terms/terms.h); sorted, each once. Written
  // straight into the compressed rows (a point's three rows have the same columns): Eigen's
  // setFromTriplets, nine triplets per block sorted through a transposed copy, was the
  // dearest part of a sheet's first implicit step. The same pattern, so the same bits.
  std::vector<std::pair<std::uint32_t, std::uint32_t>> pairs;
  pairs.reserve(count + 2 * std::size_t(t.springs()));
  for (std::uint32_t p = 0; p < count; ++p) pairs.emplace_back(p, p);
  for (std::uint32_t e = 0; e < t.springs(); ++e) {
    pairs.emplace_back(t.a[e], t.b[e]);
    pairs.emplace_back(t.b[e], t.a[e]);
  }
  add_term_jacobians(s, cptr(s.position),
                     [&](std::uint32_t p, std::uint32_t q, const Real (&)[3][3]) { pairs.emplace_back(p, q); });
  std::vector<int> start(count + 1, 0), blocks(pairs.size());
  for (const auto& [p, q] : pairs) ++start[p + 1];
  for (std::size_t p = 0; p < count; ++p) start[p + 1] += start[p];
  {
    std::vector<int> at(start.begin(), start.end() - 1);
    for (const auto& [p, q] : pairs) blocks[std::size_t(at[p]++)] = int(q);
  }
  std::vector<int> width(count);  // per point: its distinct blocks, first in its slice of `blocks`
  for (std::size_t p = 0; p < count; ++p) {
    const auto begin = blocks.begin() + start[p], end = blocks.begin() + start[p + 1];
    std::sort(begin, end);
    width[p] = int(std::unique(begin, end) - begin);
  }
  std::size_t nonzeros = 0;
  for (std::size_t p = 0; p < count; ++p) nonzeros += 9 * std::size_t(width[p]);
  sc.system.resize(n3, n3);
  sc.system.resizeNonZeros(Eigen::Index(nonzeros));
  int* outer = sc.system.outerIndexPtr();
  int* inner = sc.system.innerIndexPtr();
  int next = 0;
  for (std::size_t p = 0; p < count; ++p)
    for (int r = 0; r < 3; ++r) {
      outer[3 * p + std::size_t(r)] = next;
      for (int k = start[p]; k < start[p] + width[p]; ++k)
        for (int c = 0; c < 3; ++c) inner[next++] = 3 * blocks[std::size_t(k)] + c;
    }
  outer[n3] = next;
  std::fill(sc.system.valuePtr(), sc.system.valuePtr() + nonzeros, Real(0));

  sc.diagonal.resize(std::size_t(n3));
  for (int row = 0; row < n3; ++row) sc.diagonal[std::size_t(row)] = offset_of(sc.system, row, row - row % 3);
  sc.upper.resize(3 * std::size_t(t.springs()));
  sc.lower.resize(3 * std::size_t(t.springs()));
  for (std::uint32_t e = 0; e < t.springs(); ++e)
    for (int r = 0; r < 3; ++r) {
      sc.upper[3 * e + r] = offset_of(sc.system, int(3 * t.a[e]) + r, int(3 * t.b[e]));
      sc.lower[3 * e + r] = offset_of(sc.system, int(3 * t.b[e]) + r, int(3 * t.a[e]));
    }
  sc.free.assign(s.size(), Real(1));
  for (std::uint32_t p : s.pins.point) sc.free[p] = Real(0);
  sc.rhs.setZero(n3);
  sc.dv.setZero(n3);
  sc.topology = s.topology.get();
  sc.pin_count = s.pins.point.size();
  sc.omega_max = sheet_spring_frequency(s);
  sc.structure = nullptr;  // the Cholesky blocks' offsets into the old pattern are stale
}

struct SolveResult {
  int iterations;
  double relative_residual;
};

// Conjugate gradient on sc.system·dv = sc.rhs from the guess in sc.dv, preconditioned by
// precondition(r, z), z ≈ A⁻¹r (symmetric positive definite). Stops at |r| ≤ tol·|b|.
// In rounding a badly conditioned system (float, mass ratios of 1e6, dt²k/m of 1e10) can
// lose CG's descent: the residual then grows or turns NaN. The solve stops there and
// returns the iterate of smallest residual (the guess, if none was better), reported
// unconverged, so a failed solve never writes NaN into the state.
// A solve may stop early, unconverged, when after `iterations` its relative residual is
// still above `residual` (none: iterations = 0).
struct Probe {
  int iterations = 0;
  double residual = 0;
};

template <class Real, class Precondition>
SolveResult preconditioned_cg(ImplicitScratch<Real>& sc, double tolerance, int max_iterations,
                              Precondition precondition, Probe probe = {}) {
  using Vector = typename ImplicitScratch<Real>::Vector;
  const Eigen::Index n3 = sc.rhs.size();
  Vector& x = sc.dv;
  Vector& r = sc.residual;
  Vector& d = sc.direction;
  Vector& z = sc.preconditioned;
  Vector& ad = sc.product;
  z.resize(n3);
  ad.resize(n3);
  const double b_norm = static_cast<double>(sc.rhs.norm());
  if (b_norm == 0) {
    x.setZero();
    return {0, 0};
  }
  r.noalias() = sc.rhs - sc.system * x;
  double residual = static_cast<double>(r.norm()) / b_norm;
  int it = 0;
  if (residual <= tolerance) return {0, residual};
  double best = std::isfinite(residual) ? residual : std::numeric_limits<double>::infinity();
  sc.best = x;
  if (!std::isfinite(residual)) sc.best.setZero();
  precondition(r, z);
  d = z;
  Real rz = r.dot(z);
  while (it < max_iterations) {
    ad.noalias() = sc.system * d;
    const Real alpha = rz / d.dot(ad);
    x += alpha * d;
    r -= alpha * ad;
    ++it;
    residual = static_cast<double>(r.norm()) / b_norm;
    if (residual <= tolerance || (it == probe.iterations && residual > probe.residual)) break;
    if (!(residual < best)) {
      if (!(residual < 1e3 * best)) {  // diverging, or NaN: back to the best iterate
        x = sc.best;
        return {it, best};
      }
    } else {
      best = residual;
      sc.best = x;
    }
    precondition(r, z);
    const Real rz_next = r.dot(z);
    d = z + (rz_next / rz) * d;
    rz = rz_next;
  }
  if (residual <= tolerance || !(residual > best)) return {it, residual};
  x = sc.best;
  return {it, best};
}

// Block Jacobi: a point's own coupling of its three axes (a spring's u uᵀ) is solved
// exactly, which a scalar diagonal cannot do.
template <class Real>
SolveResult block_jacobi_cg(ImplicitScratch<Real>& sc, double tolerance, int max_iterations) {
  using Vector = typename ImplicitScratch<Real>::Vector;
  const std::size_t count = std::size_t(sc.rhs.size() / 3);
  const Real* a = sc.system.valuePtr();
  sc.block_inverse.resize(9 * count);
  for (std::size_t q = 0; q < count; ++q) {
    Eigen::Matrix<Real, 3, 3> block;
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) block(r, c) = a[sc.diagonal[3 * q + r] + c];
    Eigen::Map<Eigen::Matrix<Real, 3, 3, Eigen::RowMajor>>(sc.block_inverse.data() + 9 * q) = block.inverse();
  }
  return preconditioned_cg(sc, tolerance, max_iterations, [&](const Vector& in, Vector& out) {
    for (std::size_t q = 0; q < count; ++q) {
      const Real* m = sc.block_inverse.data() + 9 * q;
      const Real* v = in.data() + 3 * q;
      Real* o = out.data() + 3 * q;
      for (int r = 0; r < 3; ++r) o[r] = m[3 * r] * v[0] + m[3 * r + 1] * v[1] + m[3 * r + 2] * v[2];
    }
  });
}

// The Cholesky blocks' sources in `system` for local/global's symbolic structure `ms`, and
// the supernodes of that structure (the double factor's only when it is first needed).
template <class Real>
void map_blocks(ImplicitScratch<Real>& sc, const LocalGlobalScratch& ms) {
  const std::size_t count = ms.permutation.size();
  sc.point_of.resize(count);
  for (std::size_t p = 0; p < count; ++p) sc.point_of[std::size_t(ms.permutation[p])] = int(p);
  sc.source.clear();
  for (std::size_t j = 0; j < count; ++j)
    for (int k = ms.column_start[j]; k < ms.column_start[j + 1]; ++k) {
      const int pi = sc.point_of[std::size_t(ms.row_index[std::size_t(k)])], pj = sc.point_of[j];
      const int* begin = sc.system.innerIndexPtr() + sc.system.outerIndexPtr()[3 * pi];
      const int* end = sc.system.innerIndexPtr() + sc.system.outerIndexPtr()[3 * pi + 1];
      if (!std::binary_search(begin, end, 3 * pj)) continue;  // fill
      sc.source.push_back({k, int(j), {}});
      for (int r = 0; r < 3; ++r) sc.source.back().row[std::size_t(r)] = offset_of(sc.system, 3 * pi + r, 3 * pj);
    }
  sc.single.analyse(ms.column_start.data(), ms.row_index.data(), count);
  sc.single_work.resize(3 * count);
  sc.full_analysed = false;
  sc.held = FactorKind::None;  // the panels' layout changed
  sc.structure = &ms;
  sc.structure_factorisations = ms.factorisations;
}

// The step's matrix (its lower blocks) into the supernodes' panels of `factor`, then L.
// False when it is not positive definite in that precision.
template <class Scalar, class Real>
bool block_factor(SupernodalFactor<Scalar>& factor, const ImplicitScratch<Real>& sc) {
  const Real* a = sc.system.valuePtr();
  factor.clear();
  Scalar* value = factor.values();
  for (const auto& src : sc.source) {
    const std::size_t ld = factor.leading(std::size_t(src.column));
    Scalar* block = value + factor.entry_offset(std::size_t(src.entry));
    for (int r = 0; r < 3; ++r)
      for (int c = 0; c < 3; ++c) block[std::size_t(r) + std::size_t(c) * ld] = Scalar(a[src.row[std::size_t(r)] + c]);
  }
  return factor.factor();
}

// z = (L Lᵀ)⁻¹ r through `factor`, permuted, in its precision.
template <class Scalar, class Real>
void block_solve(const SupernodalFactor<Scalar>& factor, typename SupernodalFactor<Scalar>::Aligned& work,
                 const LocalGlobalScratch& ms, const Real* in, Real* out) {
  const std::size_t count = ms.permutation.size();
  Scalar* y = work.data();
  for (std::size_t p = 0; p < count; ++p)
    for (int r = 0; r < 3; ++r) y[3 * std::size_t(ms.permutation[p]) + std::size_t(r)] = Scalar(in[3 * p + std::size_t(r)]);
  factor.solve(y);
  for (std::size_t p = 0; p < count; ++p)
    for (int r = 0; r < 3; ++r) out[3 * p + std::size_t(r)] = Real(y[3 * std::size_t(ms.permutation[p]) + std::size_t(r)]);
}

// How many CG iterations the float factor gets before the step factors in double. Each
// iteration shrinks the residual by the float factor's relative error, far below κ·ε_float
// on these matrices (Cholesky's backward error is small entry by entry): one or two
// iterations to 1e-6 up to k = 1e8 N/m. Where it does not serve (a matrix beyond float's
// range, or one too ill-conditioned), the double factor takes over.
constexpr int single_iterations = 10;

// A factor made at an earlier step (ImplicitMemory) preconditions a later step's solve
// when it brings CG to the tolerance within stale_iterations (and is on pace for that
// after probe_iterations); otherwise the step factors its own matrix
// and CG goes on from the best iterate. An iteration costs a product with
// the matrix and two triangular solves, about a seventh of a factor on a 64×64 sheet, so a
// kept factor pays while it needs no more iterations than that. A kept solve that took
// more than refresh_iterations has the next step make a new factor; an attempt that fails
// (the springs turned too far since the factor: a moving sheet) has the next 1, 2, 4, …
// up to max_backoff steps factor their own matrices without trying, so a sheet in motion
// loses little and a settling one goes back to reuse.
constexpr int stale_iterations = 6;
constexpr int probe_iterations = 1;
constexpr int refresh_iterations = 4;
constexpr int max_backoff = 32;

// Implicit Euler's integrator memory (Sheet::integrator_scratch), which a checkpoint saves:
// [0, 3N) the previous Δv, the next solve's guess; [3N, 6N) the positions, x then y then z,
// at which the kept Cholesky factor was made; then the dt it was made with, its
// FactorKind (None: make one at the next step), the steps left before reuse is tried
// again and the current back-off. From these a resumed run (or a sheet whose scratch was
// dropped) makes the same factor again, so it repeats the same solves bit for bit: which
// factor preconditions a step depends only on the sheet's own history.
template <class Real>
struct ImplicitMemory {
  std::vector<Real>& data;
  std::size_t count;
  static std::size_t size(std::size_t count) { return 6 * count + 4; }
  Real* guess() { return data.data(); }
  Real* position(int axis) { return data.data() + 3 * count + std::size_t(axis) * count; }
  // the factor's key: its positions, dt and kind
  const Real* key() const { return data.data() + 3 * count; }
  static std::size_t key_size(std::size_t count) { return 3 * count + 2; }
  Real& dt() { return data[6 * count]; }
  FactorKind kind() const { return static_cast<FactorKind>(int(data[6 * count + 1])); }
  void set_kind(FactorKind kind) { data[6 * count + 1] = Real(int(kind)); }
  Real& skip() { return data[6 * count + 2]; }
  Real& backoff() { return data[6 * count + 3]; }
};

template <class Real>
void assemble(ImplicitScratch<Real>& sc, const Sheet<Real>& s, Real dt, const Real (&g)[3]);

// The factor of `kind` of the matrix in sc.system into sc's panels; false when it is not
// positive definite in that precision.
template <class Real>
bool make_factor(ImplicitScratch<Real>& sc, const LocalGlobalScratch& ms, FactorKind kind) {
  bool made;
  if (kind == FactorKind::Single) {
    made = block_factor(sc.single, sc);
  } else {
    if (!sc.full_analysed) {
      sc.full.analyse(ms.column_start.data(), ms.row_index.data(), ms.permutation.size());
      sc.full_work.resize(sc.single_work.size());
      sc.full_analysed = true;
    }
    made = block_factor(sc.full, sc);
  }
  sc.held = made ? kind : FactorKind::None;
  return made;
}

// Whether sc holds the memory's factor: the same positions, dt and kind, bit for bit (a
// memory set from outside, a checkpoint loaded into a world that has stepped, may differ).
template <class Real>
bool held_matches(const ImplicitScratch<Real>& sc, const ImplicitMemory<Real>& memory) {
  const std::size_t n = ImplicitMemory<Real>::key_size(memory.count);
  return sc.held != FactorKind::None && sc.held == memory.kind() && sc.held_key.size() == n &&
         std::memcmp(sc.held_key.data(), memory.key(), n * sizeof(Real)) == 0;
}

// The kept factor back into a scratch that lost it (a resumed run, a copied sheet): the
// matrix at the memory's positions and dt, factored in the memory's precision. It runs
// before the step's own assembly, which then overwrites the matrix.
// Whether the memory's policy tries the kept factor at this step (of step size dt): a
// factor for this dt and no back-off left. Only the memory decides, never the scratch.
template <class Real>
bool tries_kept(ImplicitMemory<Real>& memory, double dt) {
  return memory.kind() != FactorKind::None && double(memory.dt()) == dt && memory.skip() == 0;
}

template <class Real>
void restore_factor(ImplicitScratch<Real>& sc, Sheet<Real>& s, const LocalGlobalScratch& ms, ImplicitMemory<Real> memory,
                    double step_dt) {
  if (!tries_kept(memory, step_dt) || held_matches(sc, memory)) return;
  const Real dt = memory.dt();
  Vec3Array<Real> kept = s.position;
  std::copy(memory.position(0), memory.position(0) + memory.count, kept.x.begin());
  std::copy(memory.position(1), memory.position(1) + memory.count, kept.y.begin());
  std::copy(memory.position(2), memory.position(2) + memory.count, kept.z.begin());
  std::swap(kept, s.position);
  const Real g[3] = {0, 0, 0};
  assemble(sc, s, dt, g);  // the right-hand side is not used
  std::swap(kept, s.position);
  if (make_factor(sc, ms, memory.kind()))
    sc.held_key.assign(memory.key(), memory.key() + ImplicitMemory<Real>::key_size(memory.count));
  else
    memory.set_kind(FactorKind::None);
}

// z = (L Lᵀ)⁻¹ r through the factor sc holds.
template <class Real>
SolveResult factor_cg(ImplicitScratch<Real>& sc, const LocalGlobalScratch& ms, double tolerance, int max_iterations,
                      Probe probe = {}) {
  using Vector = typename ImplicitScratch<Real>::Vector;
  if (sc.held == FactorKind::Single)
    return preconditioned_cg(sc, tolerance, max_iterations, [&](const Vector& in, Vector& out) {
      block_solve(sc.single, sc.single_work, ms, in.data(), out.data());
    }, probe);
  return preconditioned_cg(sc, tolerance, max_iterations, [&](const Vector& in, Vector& out) {
    block_solve(sc.full, sc.full_work, ms, in.data(), out.data());
  }, probe);
}

// Cholesky: CG preconditioned by the kept factor (ImplicitMemory) when the policy above
// tries it; otherwise, or when it does not serve, the step's own matrix factored, in float
// first and, when that factor breaks down or CG does not reach the tolerance within
// single_iterations, in double, CG going on from the best iterate; the new factor is kept.
// The matrix is positive definite (masses on the diagonal, every spring block clamped to
// G ⪰ 0), so the double factor exists; if rounding still breaks it, the step falls back to
// block Jacobi and keeps no factor. Which path a step takes depends only on its matrix and
// the memory, so the bits do not depend on threads or a resume.
template <class Real>
SolveResult cholesky_cg(ImplicitScratch<Real>& sc, Sheet<Real>& s, const LocalGlobalScratch& ms, ImplicitMemory<Real> memory,
                        double dt, double tolerance, int max_iterations) {
  int done = 0;
  if (memory.kind() != FactorKind::None && double(memory.dt()) == dt && memory.skip() > 0) {
    memory.skip() -= 1;
  } else if (tries_kept(memory, dt) && held_matches(sc, memory)) {  // (restore_factor made it)
    // the rest of the budget only when its first probe_iterations went at the pace it
    // needs (a relative residual of tolerance^(probe/stale) or less)
    const Probe probe{probe_iterations, std::pow(tolerance, double(probe_iterations) / stale_iterations)};
    const SolveResult kept = factor_cg(sc, ms, tolerance, std::min(stale_iterations, max_iterations), probe);
    if (kept.relative_residual <= tolerance || kept.iterations >= max_iterations) {
      memory.backoff() = 0;
      if (kept.iterations > refresh_iterations) memory.set_kind(FactorKind::None);
      return kept;
    }
    memory.backoff() = std::min(Real(max_backoff), std::max(Real(1), 2 * memory.backoff()));
    memory.skip() = memory.backoff();
    done = kept.iterations;
  }
  // a new factor, made at this step's positions
  std::copy(s.position.x.begin(), s.position.x.end(), memory.position(0));
  std::copy(s.position.y.begin(), s.position.y.end(), memory.position(1));
  std::copy(s.position.z.begin(), s.position.z.end(), memory.position(2));
  memory.dt() = Real(dt);
  memory.set_kind(FactorKind::None);
  auto keep = [&](FactorKind kind) {
    memory.set_kind(kind);
    sc.held_key.assign(memory.key(), memory.key() + ImplicitMemory<Real>::key_size(memory.count));
  };
  if (make_factor(sc, ms, FactorKind::Single)) {
    const SolveResult single = factor_cg(sc, ms, tolerance, std::min(single_iterations, max_iterations - done));
    if (single.relative_residual <= tolerance || done + single.iterations >= max_iterations) {
      keep(FactorKind::Single);
      return {done + single.iterations, single.relative_residual};
    }
    done += single.iterations;
  }
  SolveResult full;
  if (make_factor(sc, ms, FactorKind::Full)) {
    keep(FactorKind::Full);
    full = factor_cg(sc, ms, tolerance, max_iterations - done);
  } else {
    full = block_jacobi_cg(sc, tolerance, max_iterations - done);
  }
  full.iterations += done;
  return full;
}

// Auto: block Jacobi's iterations grow with dt·ω_max (and with the sheet), the factor's
// cost does not: a factor in float and its one or two solves cost about as much as 40
// block-Jacobi iterations on a 64×64 sheet, which block Jacobi needs at dt·ω_max ≈ 8; on
// 128×128 the factor costs more but so do block Jacobi's iterations (about 70, reached
// near dt·ω_max ≈ 12). Block Jacobi up to dt·ω_max = 10, between the two
// (BM_ImplicitEulerStep's dt_omega_max counter, docs/integrators.md).
bool use_cholesky(Preconditioner preconditioner, double dt, double omega_max) {
  switch (preconditioner) {
    case Preconditioner::BlockJacobi: return false;
    case Preconditioner::Cholesky: return true;
    default: return dt * omega_max > 10.0;
  }
}

// Springs (eq 6, spring_jacobian.h): −dt²·∂f/∂x = dt²·G into the matrix and dt²·∂f/∂x·v
// into the right-hand side. Every spring term's Jacobian enters the system here.
template <class Real>
void add_spring_terms(ImplicitScratch<Real>& sc, const Sheet<Real>& s, Real dt2) {
  const auto& t = *s.topology;
  const auto& x = s.position;
  const auto& v = s.velocity;
  Real* a = sc.system.valuePtr();
  Real* b = sc.rhs.data();
  // The square roots and divisions of all springs first, out of the way of the stores
  // below, so that many springs' latencies overlap; the same arithmetic, so the same bits.
  sc.spring_direction.resize(4 * std::size_t(t.springs()));
  Real* direction = sc.spring_direction.data();
  for (std::uint32_t e = 0; e < t.springs(); ++e) {
    const std::uint32_t pa = t.a[e], pb = t.b[e];
    const Real d[3] = {x.x[pa] - x.x[pb], x.y[pa] - x.y[pb], x.z[pa] - x.z[pb]};
    spring_direction(d, t.rest_length[e], direction + 4 * e, direction[4 * e + 3]);
  }
  for (std::uint32_t e = 0; e < t.springs(); ++e) {
    const std::uint32_t pa = t.a[e], pb = t.b[e];
    Real gm[3][3];
    spring_block(t.stiffness[e], direction + 4 * e, direction[4 * e + 3], gm);
    const Real fa = sc.free[pa], fb = sc.free[pb];
    const Real dv[3] = {v.x[pa] - v.x[pb], v.y[pa] - v.y[pb], v.z[pa] - v.z[pb]};
    for (int r = 0; r < 3; ++r) {
      Real* da = a + sc.diagonal[3 * pa + r];
      Real* db = a + sc.diagonal[3 * pb + r];
      Real* ab = a + sc.upper[3 * e + r];
      Real* ba = a + sc.lower[3 * e + r];
      Real jv = 0;  // (G·(va − vb))_r
      for (int c = 0; c < 3; ++c) {
        const Real h = dt2 * gm[r][c];
        da[c] += fa * h;
        db[c] += fb * h;
        ab[c] -= fa * fb * h;
        ba[c] -= fa * fb * h;
        jv += gm[r][c] * dv[c];
      }
      // dt²·∂f/∂x·v: −G(va − vb) on a, +G(va − vb) on b
      b[3 * pa + r] -= fa * dt2 * jv;
      b[3 * pb + r] += fb * dt2 * jv;
    }
  }
}

// The step's matrix and right-hand side (implicit.h) at the sheet's positions, with s.force
// the forces there.
template <class Real>
void assemble(ImplicitScratch<Real>& sc, const Sheet<Real>& s, Real dt, const Real (&g)[3]) {
  const std::size_t count = s.size();
  const Real dt2 = dt * dt;
  const auto& v = s.velocity;
  Real* a = sc.system.valuePtr();
  std::fill(a, a + sc.system.nonZeros(), Real(0));
  Real* b = sc.rhs.data();
  const Real* f[3] = {s.force.x.data(), s.force.y.data(), s.force.z.data()};
  // M − dt·∂f/∂v with ∂f/∂v = −C; b = dt·(f + M g) so far.
  for (std::size_t q = 0; q < count; ++q) {
    const Real diag = s.mass[q] + (s.damping.empty() ? Real(0) : dt * s.damping[q]);
    for (int r = 0; r < 3; ++r) {
      a[sc.diagonal[3 * q + r] + r] = diag;
      b[3 * q + r] = dt * (f[r][q] + s.mass[q] * g[r]);
    }
  }
  // Anchors (eq 8): ∂f/∂x = −k·I at the anchored point.
  const auto& an = s.anchors;
  for (std::size_t k = 0; k < an.point.size(); ++k) {
    const std::uint32_t q = an.point[k];
    const Real kk = an.stiffness[k] * sc.free[q];
    const Real vq[3] = {v.x[q], v.y[q], v.z[q]};
    for (int r = 0; r < 3; ++r) {
      a[sc.diagonal[3 * q + r] + r] += dt2 * kk;
      b[3 * q + r] -= dt2 * kk * vq[r];
    }
  }
  // Springs (eq 6): ∂fa/∂xa = −G (spring_jacobian.h, clamped where compressed). That only
  // drops a destabilising part of the linearisation; the force itself on the right-hand
  // side stays exact.
  add_spring_terms(sc, s, dt2);
  // The other terms (terms/terms.h): M − dt²·J on their blocks, dt²·J·v on the right-hand
  // side, with pinned points' rows and columns dropped as above.
  add_term_jacobians(s, cptr(s.position), [&](std::uint32_t p, std::uint32_t q, const Real (&j)[3][3]) {
    const Real mask = p == q ? sc.free[p] : sc.free[p] * sc.free[q];
    const Real vq[3] = {v.x[q], v.y[q], v.z[q]};
    for (int r = 0; r < 3; ++r) {
      Real* row = a + offset_of(sc.system, int(3 * p) + r, int(3 * q));
      Real jv = 0;
      for (int c = 0; c < 3; ++c) {
        row[c] -= mask * dt2 * j[r][c];
        jv += j[r][c] * vq[c];
      }
      b[3 * p + r] += sc.free[p] * dt2 * jv;
    }
  });
  // Pinned points: their rows keep only M (their columns are already dropped above) and
  // their right-hand side is zero, so Δv = 0 there.
  for (std::uint32_t q : s.pins.point)
    for (int r = 0; r < 3; ++r) b[3 * q + r] = Real(0);

}

}  // namespace

template <class Real>
void implicit_euler_step(Sheet<Real>& s, const StepParams<Real>& p) {
  if (!s.implicit_scratch || s.implicit_scratch.use_count() > 1)
    s.implicit_scratch = std::make_shared<ImplicitScratch<Real>>();
  auto& sc = *s.implicit_scratch;
  if (sc.topology != s.topology.get() || sc.pin_count != s.pins.point.size()) build_pattern(sc, s);

  const std::size_t count = s.size();
  const Real dt = p.dt;

  // The integrator memory (ImplicitMemory); a shorter one (a checkpoint from before the
  // kept factor) keeps its guess and holds no factor, any other is started afresh.
  const std::size_t n3 = 3 * count;
  if (s.integrator_scratch.size() != ImplicitMemory<Real>::size(count)) {
    if (s.integrator_scratch.size() != n3) s.integrator_scratch.assign(n3, Real(0));
    s.integrator_scratch.resize(ImplicitMemory<Real>::size(count), Real(0));
  }
  ImplicitMemory<Real> memory{s.integrator_scratch, count};
  const bool cholesky = use_cholesky(p.cg_preconditioner, double(dt), sc.omega_max);
  LocalGlobalScratch* ms = nullptr;
  if (cholesky) {
    if (!s.local_global_scratch || s.local_global_scratch.use_count() > 1)
      s.local_global_scratch = std::make_shared<LocalGlobalScratch>();
    ms = s.local_global_scratch.get();
    prepare_pattern(*ms, s, double(dt));
    if (sc.structure != ms || sc.structure_factorisations != ms->factorisations) map_blocks(sc, *ms);
    restore_factor(sc, s, *ms, memory, double(dt));
  }

  // f(x, v) of every term, including those without a Jacobian (obstacles, contacts): they
  // enter the right-hand side only, i.e. are treated explicitly.
  sheet_forces(s, cptr(s.position), cptr(s.velocity), ptr(s.force));
  const Real g[3] = {p.gx, p.gy, p.gz};
  assemble(sc, s, dt, g);

  // The previous Δv is the initial guess, from the memory, so a resumed run repeats the
  // same solves bit for bit.
  Eigen::Map<typename ImplicitScratch<Real>::Vector> guess(s.integrator_scratch.data(), Eigen::Index(n3));
  sc.dv = guess;
  const SolveResult result = cholesky ? cholesky_cg(sc, s, *ms, memory, double(dt), p.cg_tolerance, p.cg_max_iterations)
                                      : block_jacobi_cg(sc, p.cg_tolerance, p.cg_max_iterations);
  guess = sc.dv;
  record_solve(s.last_solve, result.iterations, result.relative_residual, result.relative_residual <= p.cg_tolerance);

  const Real* dvp = sc.dv.data();
  Real* vel[3] = {s.velocity.x.data(), s.velocity.y.data(), s.velocity.z.data()};
  Real* pos[3] = {s.position.x.data(), s.position.y.data(), s.position.z.data()};
  for (int r = 0; r < 3; ++r)
    for (std::size_t q = 0; q < count; ++q) {
      vel[r][q] += dvp[3 * q + r];
      pos[r][q] += dt * vel[r][q];
    }
}

template void implicit_euler_step<double>(Sheet<double>&, const StepParams<double>&);
template void implicit_euler_step<float>(Sheet<float>&, const StepParams<float>&);

}  // namespace drape::detail

namespace drape {

namespace {
constexpr std::pair<Preconditioner, std::string_view> preconditioner_names[] = {
    {Preconditioner::Auto, "auto"}, {Preconditioner::BlockJacobi, "block_jacobi"}, {Preconditioner::Cholesky, "cholesky"}};
}

std::string_view preconditioner_name(Preconditioner preconditioner) {
  for (const auto& [value, name] : preconditioner_names)
    if (value == preconditioner) return name;
  return "unknown";
}

std::optional<Preconditioner> preconditioner_from_name(std::string_view name) {
  for (const auto& [value, known] : preconditioner_names)
    if (known == name) return value;
  return std::nullopt;
}

}  // namespace drape
