// Vertex Block Descent (Chen et al. 2024): see vertex_block.h.
#include "vertex_block.h"

#include "spring_jacobian.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <Eigen/Dense>
#include <algorithm>
#include <cmath>

namespace drape::detail {

namespace {

// Springs per point (the step's springs, shear diagonals included: LocalGlobalScratch), a
// greedy colouring in point order (two colours on a 4-neighbour grid, four with diagonals),
// and anchors per point.
template <class Real>
void build_adjacency(VertexBlockScratch& sc, const Sheet<Real>& s) {
  const std::vector<std::uint32_t>& ea = sc.step.edge_a;
  const std::vector<std::uint32_t>& eb = sc.step.edge_b;
  const std::uint32_t springs = std::uint32_t(ea.size());
  const std::size_t count = s.size();
  sc.topology = s.topology;
  sc.neighbour_start.assign(count + 1, 0);
  for (std::uint32_t e = 0; e < springs; ++e) {
    ++sc.neighbour_start[ea[e] + 1];
    ++sc.neighbour_start[eb[e] + 1];
  }
  for (std::size_t p = 0; p < count; ++p) sc.neighbour_start[p + 1] += sc.neighbour_start[p];
  sc.neighbour.resize(sc.neighbour_start[count]);
  sc.neighbour_spring.resize(sc.neighbour_start[count]);
  std::vector<std::uint32_t> fill(sc.neighbour_start.begin(), sc.neighbour_start.end() - 1);
  for (std::uint32_t e = 0; e < springs; ++e) {
    sc.neighbour[fill[ea[e]]] = eb[e];
    sc.neighbour_spring[fill[ea[e]]++] = e;
    sc.neighbour[fill[eb[e]]] = ea[e];
    sc.neighbour_spring[fill[eb[e]]++] = e;
  }
  std::vector<std::uint32_t> colour(count, 0);
  sc.colours.clear();
  for (std::size_t p = 0; p < count; ++p) {
    std::uint32_t c = 0;
    for (bool taken = true; taken; ++c) {
      taken = false;
      for (std::uint32_t k = sc.neighbour_start[p]; k < sc.neighbour_start[p + 1]; ++k)
        if (sc.neighbour[k] < p && colour[sc.neighbour[k]] == c) taken = true;
      if (!taken) break;
    }
    colour[p] = c;
    if (sc.colours.size() <= c) sc.colours.resize(c + 1);
    sc.colours[c].push_back(std::uint32_t(p));
  }
}

template <class Real>
void build_anchors(VertexBlockScratch& sc, const Sheet<Real>& s) {
  const std::size_t count = s.size();
  const auto& points = s.anchors.point;
  sc.anchor_key = points;
  sc.anchor_start.assign(count + 1, 0);
  for (std::uint32_t q : points) ++sc.anchor_start[q + 1];
  for (std::size_t p = 0; p < count; ++p) sc.anchor_start[p + 1] += sc.anchor_start[p];
  sc.anchor_index.resize(points.size());
  std::vector<std::uint32_t> fill(sc.anchor_start.begin(), sc.anchor_start.end() - 1);
  for (std::size_t k = 0; k < points.size(); ++k) sc.anchor_index[fill[points[k]]++] = std::uint32_t(k);
}

}  // namespace

template <class Real>
void vertex_block_step(Sheet<Real>& s, const StepParams<Real>& p) {
  if (!s.vertex_block_scratch || s.vertex_block_scratch.use_count() > 1)
    s.vertex_block_scratch = std::make_shared<VertexBlockScratch>();
  auto& vb = *s.vertex_block_scratch;
  LocalGlobalScratch& sc = vb.step;
  backward_euler_begin(sc, s, p, false);  // the springs' list first: the adjacency reads it
  if (vb.topology != s.topology || vb.neighbour_start.size() != s.size() + 1) build_adjacency(vb, s);
  if (vb.anchor_key != s.anchors.point || vb.anchor_start.size() != s.size() + 1) build_anchors(vb, s);

  const double h = static_cast<double>(p.dt), inv_h2 = 1.0 / (h * h);
  const auto& an = s.anchors;
  const bool damped = !sc.damping.empty();
  double* x[3] = {sc.solution[0].data(), sc.solution[1].data(), sc.solution[2].data()};

  // One Newton step of point q's own energy, the other points held (eq 6 springs, eq 8 anchors).
  auto update = [&](std::uint32_t q) {
    if (sc.pinned[q]) return;
    const double w = (sc.mass[q] + (damped ? h * sc.damping[q] : 0.0)) * inv_h2;
    const double xq[3] = {x[0][q], x[1][q], x[2][q]};
    Eigen::Vector3d grad;
    Eigen::Matrix3d hess = w * Eigen::Matrix3d::Identity();
    for (int r = 0; r < 3; ++r) grad[r] = w * xq[r] - sc.inertia[r][Eigen::Index(q)] * inv_h2;
    for (std::uint32_t k = vb.anchor_start[q]; k < vb.anchor_start[q + 1]; ++k) {
      const std::uint32_t a = vb.anchor_index[k];
      const double ka = sc.anchor_stiffness[a];
      const double target[3] = {double(an.tx[a]), double(an.ty[a]), double(an.tz[a])};
      for (int r = 0; r < 3; ++r) grad[r] += ka * (xq[r] - target[r]);
      hess.diagonal().array() += ka;
    }
    for (std::uint32_t k = vb.neighbour_start[q]; k < vb.neighbour_start[q + 1]; ++k) {
      const std::uint32_t o = vb.neighbour[k], e = vb.neighbour_spring[k];
      const double ke = sc.stiffness[e], rest = sc.rest[e];
      const double d[3] = {xq[0] - x[0][o], xq[1] - x[1][o], xq[2] - x[2][o]};
      const double len = std::sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]);
      if (len > 0)  // eq (6): a zero-length spring applies no force
        for (int r = 0; r < 3; ++r) grad[r] += ke * (len - rest) * d[r] / len;
      double g[3][3];
      spring_stiffness_block(d, ke, rest, g);
      for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) hess(r, c) += g[r][c];
    }
    const Eigen::Vector3d step = hess.llt().solve(grad);
    for (int r = 0; r < 3; ++r) x[r][q] -= step[r];
  };

  const int iterations = std::max(1, p.vertex_block_iterations);
  for (int it = 0; it < iterations; ++it)
    for (const auto& points : vb.colours)
      tbb::parallel_for(tbb::blocked_range<std::size_t>(0, points.size(), 1024), [&](const auto& range) {
        for (std::size_t k = range.begin(); k < range.end(); ++k) update(points[k]);
      });
  backward_euler_finish(sc, s, p, iterations);
}

template void vertex_block_step<double>(Sheet<double>&, const StepParams<double>&);
template void vertex_block_step<float>(Sheet<float>&, const StepParams<float>&);

}  // namespace drape::detail
