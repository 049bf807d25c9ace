// A ceiling for contacts, as bench_ceiling.cpp is one for springs: issue 13's stack (6
// stacks of 8 sheets of 64×64, 10 mm apart, flat, odd layers a fraction of a cell off the
// even ones) has every point within contact range of the sheet above and of the one below,
// 333,396 point–triangle contacts a substep. This evaluates just those, each with its
// triangle and its point's weights on it given (no search, no walk, no test that the
// triangle is still the nearest: what a contact that persisted between searches would
// cost), by the engine's force law (contacts.cpp `repel`: d = p − Σ wₖ xₖ, a force
// (c/ξ)(e^min((h − |d|)/ξ, cap) − tail) along d on the point and −wₖ times it on corner k),
// with the fewest divisions it needs and fused multiply-adds allowed (no bits to keep),
// compiled for every instruction set and dispatched to the widest. Two layouts:
// - gathered (arg 0): the contacts in the order a kept contact set holds them (by point),
//   positions gathered by index, each contact's force stored, then summed into its four
//   points one contact at a time in that order, as the engine's buffers and gather do;
// - aligned (arg 1): laid out as equal stacked grids allow, a vector's lanes consecutive
//   points over consecutive corners: positions loaded, and the corners' shares summed per
//   corner of the triangle, added to the points once per pair of sheets;
// - aligned with the law in float (arg 2): the same, the differences rounded to float and
//   the square root, exp and division done in float (the figure a contact law in float
//   could reach; the counter says how far its forces stray).
// tools/bench_report.py sets both beside the engine's contact stage on the same stack.
#include "simd/targets.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "bench_contact_ceiling.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <vector>

#include "bench_common.h"
#include "contacts.h"
#include "sheet_data.h"

#include "simd/exp-inl.h"

// The contacts, built once (foreach_target re-includes this file for every target).
#ifndef DRAPE_BENCH_CONTACT_CEILING_SET_
#define DRAPE_BENCH_CONTACT_CEILING_SET_
namespace {

using Array = std::vector<double, drape::detail::CacheAligned<double>>;

// A run of `count` contacts: contact j has point `point + j` and corners `corner[k] + j`
// of the position arrays, and weights w[k][first + j].
struct Run {
  std::uint32_t point, corner[3], count, first;
};

// The runs of one layer's points against one neighbouring layer, whose first point is `sheet`.
struct Group {
  std::uint32_t sheet, begin, end;  // runs [begin, end)
};

struct ContactSet {
  using Stack = drape::bench::Stack;  // its sheets, flat, at the gap of BM_World48SheetsInContact
  static constexpr std::uint32_t side = Stack::side, stacks = Stack::columns, layers = Stack::layers;
  Array x, y, z;                       // every sheet's points, sheet after sheet
  std::vector<Run> runs;
  std::vector<Group> groups;
  Array w[3];                                 // per contact
  std::vector<std::int64_t> point, corner[3];  // per contact (gathered)
  Array fx, fy, fz;                           // per contact: the force on its point (gathered)
  Array sum_x, sum_y, sum_z;                  // per point: the contact forces (both layouts)
  Array part[3][3];  // per point of one sheet and corner of the triangle (aligned)
  // the force's parameters, as the engine derives them from WorldDef's defaults (no cap)
  drape::detail::ContactParams<double> law = [] {
    const drape::WorldDef wd;
    return drape::detail::ContactParams<double>::make(wd.contact_thickness, wd.contact_xi, wd.contact_strength,
                                                      wd.contact_range);
  }();

  std::size_t size() const { return point.size(); }

  ContactSet() {
    const std::uint32_t n = side * side;
    const double cell = Stack::width / (side - 1);
    const std::size_t points = std::size_t(stacks) * layers * n;
    for (Array* a : {&x, &y, &z, &sum_x, &sum_y, &sum_z}) a->assign(points, 0.0);
    for (auto& role : part)
      for (Array& a : role) a.assign(n, 0.0);
    // Odd layers sit a fraction of a cell off the even ones, so a point's nearest point on
    // the sheet above or below is inside a triangle, not on a corner.
    const double shift_x = 0.3 * cell, shift_y = 0.2 * cell;
    for (std::uint32_t s = 0; s < stacks * layers; ++s) {
      const std::uint32_t layer = s % layers;
      const double ox = Stack::column_pitch * (s / layers) + (layer % 2 ? shift_x : 0.0);
      const double oy = layer % 2 ? shift_y : 0.0;
      for (std::uint32_t i = 0; i < side; ++i)
        for (std::uint32_t j = 0; j < side; ++j) {
          const std::size_t p = std::size_t(s) * n + i * side + j;
          x[p] = ox + j * cell;
          y[p] = oy + i * cell;
          z[p] = layer * Stack::contact_gap;
        }
    }
    // Each layer's points against the triangles of the layer above and below: over a
    // shifted layer, point (i, j) is inside cell (i, j) at (0.3, 0.2) of it, triangle
    // (00, 01, 11); under one, inside cell (i − 1, j − 1) at (0.7, 0.8), triangle
    // (00, 11, 10). The weights are those of the point's projection on the triangle.
    for (std::uint32_t stack = 0; stack < stacks; ++stack)
      for (std::uint32_t layer = 0; layer < layers; ++layer)
        for (int other : {-1, 1}) {
          if ((other < 0 && layer == 0) || (other > 0 && layer + 1 == layers)) continue;
          const std::uint32_t q = stack * layers + layer, s = q + std::uint32_t(other);
          const bool over_shifted = layer % 2 == 0;  // the other layer is the shifted one
          groups.push_back({s * n, std::uint32_t(runs.size()), 0});
          for (std::uint32_t i = 0; i < side; ++i) {
            if ((over_shifted && i == 0) || (!over_shifted && i + 1 == side)) continue;
            Run r{};
            const std::uint32_t j0 = over_shifted ? 1 : 0;
            r.point = q * n + i * side + j0;
            // the cell's first corner (00) under point (i, j0)
            const std::uint32_t c00 = s * n + (over_shifted ? (i - 1) * side + (j0 - 1) : i * side + j0);
            r.count = side - 1;
            r.first = std::uint32_t(point.size());
            double wk[3];
            if (over_shifted) {  // at (0.7, 0.8) of the cell: triangle (00, 11, 10)
              r.corner[0] = c00, r.corner[1] = c00 + side + 1, r.corner[2] = c00 + side;
              wk[0] = 1 - 0.8, wk[1] = 0.7, wk[2] = 0.8 - 0.7;
            } else {  // at (0.3, 0.2): triangle (00, 01, 11)
              r.corner[0] = c00, r.corner[1] = c00 + 1, r.corner[2] = c00 + side + 1;
              wk[0] = 1 - 0.3, wk[1] = 0.3 - 0.2, wk[2] = 0.2;
            }
            for (std::uint32_t j = 0; j < r.count; ++j) {
              point.push_back(r.point + j);
              for (int k = 0; k < 3; ++k) {
                corner[k].push_back(r.corner[k] + j);
                w[k].push_back(wk[k]);
              }
            }
            runs.push_back(r);
          }
          groups.back().end = std::uint32_t(runs.size());
        }
    for (Array* a : {&fx, &fy, &fz}) a->assign(size(), 0.0);
  }
};

}  // namespace
#endif  // DRAPE_BENCH_CONTACT_CEILING_SET_

HWY_BEFORE_NAMESPACE();
namespace drape::bench::contact_ceiling {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

// e^x in float for x in [−80, 80], as exp_lanes does it in double, to float's precision: a
// polynomial of degree 6 on |r| ≤ ln2/2 (its Taylor series; the next term is under 2·10⁻⁷ of e^r).
template <class DF, class VF>
HWY_INLINE VF exp_float(DF df, VF x) {
  const hn::RebindToSigned<DF> di;
  x = hn::Min(hn::Max(x, hn::Set(df, -80.0f)), hn::Set(df, 80.0f));
  const VF kf = hn::Round(hn::Mul(x, hn::Set(df, 1.44269504f)));
  const VF r = hn::Sub(hn::Sub(x, hn::Mul(kf, hn::Set(df, 0.693359375f))), hn::Mul(kf, hn::Set(df, -2.12194440e-4f)));
  VF p = hn::Set(df, 1.0f / 720);
  for (float c : {1.0f / 120, 1.0f / 24, 1.0f / 6, 0.5f, 1.0f, 1.0f}) p = hn::Add(hn::Mul(p, r), hn::Set(df, c));
  const auto k = hn::ConvertTo(di, kf);
  return hn::BitCast(df, hn::Add(hn::BitCast(di, p), hn::ShiftLeft<23>(k)));
}

// The force on the point of each lane, its corners at c[k] with weights w[k], along d: the
// differences in double, the law (the square root, the exp and the division) in double or,
// InFloat, in float on the differences rounded to float.
template <bool InFloat = false, class D, class V>
HWY_INLINE void force(D d, const ContactSet& s, V px, V py, V pz, const V (&cx)[3], const V (&cy)[3], const V (&cz)[3],
                      const V (&w)[3], V& Fx, V& Fy, V& Fz) {
  const V dx = hn::Sub(px, hn::Add(hn::Add(hn::Mul(w[0], cx[0]), hn::Mul(w[1], cx[1])), hn::Mul(w[2], cx[2])));
  const V dy = hn::Sub(py, hn::Add(hn::Add(hn::Mul(w[0], cy[0]), hn::Mul(w[1], cy[1])), hn::Mul(w[2], cy[2])));
  const V dz = hn::Sub(pz, hn::Add(hn::Add(hn::Mul(w[0], cz[0]), hn::Mul(w[1], cz[1])), hn::Mul(w[2], cz[2])));
  const V dist2 = hn::Add(hn::Add(hn::Mul(dx, dx), hn::Mul(dy, dy)), hn::Mul(dz, dz));
  // (h − |d|)/ξ as a product: one division per contact, the fewest its force needs
  const auto scale_of = [&](auto dl, auto d2) HWY_ATTR {
    using T = hn::TFromD<decltype(dl)>;
    const auto dist = hn::Sqrt(d2);
    const auto gap = hn::Sub(hn::Set(dl, T(s.law.thickness)), dist);
    const auto cap = hn::Set(dl, T(std::min(s.law.exponent_cap, 80.0)));  // (float's exp: up to 80)
    const auto e = hn::Min(hn::Mul(gap, hn::Set(dl, T(1.0 / s.law.xi))), cap);
    const auto ex = [&]() HWY_ATTR {
      if constexpr (sizeof(T) == 4)
        return exp_float(dl, e);
      else
        return drape::detail::simd::HWY_NAMESPACE::exp_lanes(dl, e);
    }();
    const auto f = hn::Mul(hn::Set(dl, T(s.law.strength / s.law.xi)), hn::Sub(ex, hn::Set(dl, T(s.law.tail))));
    return hn::Div(f, dist);
  };
  V scale;
  if constexpr (InFloat) {
    const hn::Rebind<float, D> df;
    scale = hn::PromoteTo(d, scale_of(df, hn::DemoteTo(df, dist2)));
  } else {
    scale = scale_of(d, dist2);
  }
  Fx = hn::Mul(scale, dx), Fy = hn::Mul(scale, dy), Fz = hn::Mul(scale, dz);
}

// Contacts [e, e + lanes of d) by index.
template <class D>
HWY_INLINE void gathered_at(D d, ContactSet& s, std::size_t e) {
  const hn::RebindToSigned<D> di;
  using V = hn::Vec<D>;
  const auto ip = hn::LoadU(di, s.point.data() + e);
  V cx[3], cy[3], cz[3], w[3];
  for (int k = 0; k < 3; ++k) {
    const auto ic = hn::LoadU(di, s.corner[k].data() + e);
    cx[k] = hn::GatherIndex(d, s.x.data(), ic);
    cy[k] = hn::GatherIndex(d, s.y.data(), ic);
    cz[k] = hn::GatherIndex(d, s.z.data(), ic);
    w[k] = hn::LoadU(d, s.w[k].data() + e);
  }
  V Fx, Fy, Fz;
  const V px = hn::GatherIndex(d, s.x.data(), ip), py = hn::GatherIndex(d, s.y.data(), ip),
          pz = hn::GatherIndex(d, s.z.data(), ip);
  force(d, s, px, py, pz, cx, cy, cz, w, Fx, Fy, Fz);
  hn::StoreU(Fx, d, s.fx.data() + e);
  hn::StoreU(Fy, d, s.fy.data() + e);
  hn::StoreU(Fz, d, s.fz.data() + e);
}

void Gathered(ContactSet& s) {
  const hn::ScalableTag<double> d;
  const std::size_t lanes = hn::Lanes(d), count = s.size();
  std::size_t e = 0;
  for (; e + lanes <= count; e += lanes) gathered_at(d, s, e);
  for (; e < count; ++e) gathered_at(hn::CappedTag<double, 1>(), s, e);
  // each contact's four shares into its points, in contact order
  std::fill(s.sum_x.begin(), s.sum_x.end(), 0.0);
  std::fill(s.sum_y.begin(), s.sum_y.end(), 0.0);
  std::fill(s.sum_z.begin(), s.sum_z.end(), 0.0);
  for (std::size_t c = 0; c < count; ++c) {
    const double Fx = s.fx[c], Fy = s.fy[c], Fz = s.fz[c];
    const std::size_t p = std::size_t(s.point[c]);
    s.sum_x[p] += Fx, s.sum_y[p] += Fy, s.sum_z[p] += Fz;
    for (int k = 0; k < 3; ++k) {
      const std::size_t q = std::size_t(s.corner[k][c]);
      const double wk = s.w[k][c];
      s.sum_x[q] -= wk * Fx, s.sum_y[q] -= wk * Fy, s.sum_z[q] -= wk * Fz;
    }
  }
}

// Contacts j, j + 1, ... of run r: loads, and each corner's share into its own sums.
// Whole vectors load and store plainly; a run's last part vector through its mask m.
template <bool Whole, bool InFloat, class D, class M>
HWY_INLINE void aligned_at(D d, M m, ContactSet& s, const Run& r, std::size_t j, std::uint32_t sheet) {
  using V = hn::Vec<D>;
  const auto load = [&](const double* a) HWY_ATTR {
    if constexpr (Whole) return hn::LoadU(d, a);
    return hn::MaskedLoad(m, d, a);
  };
  const auto store = [&](V v, double* a) HWY_ATTR {
    if constexpr (Whole) return hn::StoreU(v, d, a);
    hn::BlendedStore(v, m, d, a);
  };
  const std::size_t p = r.point + j;
  V cx[3], cy[3], cz[3], w[3];
  for (int k = 0; k < 3; ++k) {
    const std::size_t c = r.corner[k] + j;
    cx[k] = load(s.x.data() + c), cy[k] = load(s.y.data() + c), cz[k] = load(s.z.data() + c);
    w[k] = load(s.w[k].data() + r.first + j);
    if constexpr (!Whole) w[k] = hn::IfThenElse(m, w[k], hn::Set(d, 1.0));  // masked lanes: a finite force
  }
  V Fx, Fy, Fz;
  V pz = load(s.z.data() + p);
  if constexpr (!Whole) pz = hn::IfThenElse(m, pz, hn::Set(d, 1.0));
  force<InFloat>(d, s, load(s.x.data() + p), load(s.y.data() + p), pz, cx, cy, cz, w, Fx, Fy, Fz);
  auto add = [&](double* a, std::size_t at, V v) HWY_ATTR { store(hn::Add(load(a + at), v), a + at); };
  add(s.sum_x.data(), p, Fx), add(s.sum_y.data(), p, Fy), add(s.sum_z.data(), p, Fz);
  for (int k = 0; k < 3; ++k) {
    const std::size_t c = r.corner[k] + j - sheet;
    add(s.part[k][0].data(), c, hn::Neg(hn::Mul(w[k], Fx)));
    add(s.part[k][1].data(), c, hn::Neg(hn::Mul(w[k], Fy)));
    add(s.part[k][2].data(), c, hn::Neg(hn::Mul(w[k], Fz)));
  }
}

// the shares of one sheet's corners (a, b, c) into its points' sums, a, b and c left zero
// for the next group
HWY_INLINE void fold(std::size_t n, double* __restrict a, double* __restrict b, double* __restrict c,
                     double* __restrict sum) {
  const hn::ScalableTag<double> d;
  const auto zero = hn::Zero(d);
  for (std::size_t p = 0; p < n; p += hn::Lanes(d)) {
    const auto corners = hn::Add(hn::Add(hn::LoadU(d, a + p), hn::LoadU(d, b + p)), hn::LoadU(d, c + p));
    hn::StoreU(hn::Add(hn::LoadU(d, sum + p), corners), d, sum + p);
    hn::StoreU(zero, d, a + p), hn::StoreU(zero, d, b + p), hn::StoreU(zero, d, c + p);
  }
}

template <bool InFloat>
void aligned(ContactSet& s) {
  const hn::ScalableTag<double> d;
  const std::size_t lanes = hn::Lanes(d), n = s.part[0][0].size();
  for (Array* a : {&s.sum_x, &s.sum_y, &s.sum_z}) std::fill(a->begin(), a->end(), 0.0);
  for (const Group& g : s.groups) {  // the other sheet's shares held apart while its runs go
    for (std::uint32_t k = g.begin; k < g.end; ++k) {
      const Run& r = s.runs[k];
      std::size_t j = 0;
      for (; j + lanes <= r.count; j += lanes) aligned_at<true, InFloat>(d, hn::FirstN(d, lanes), s, r, j, g.sheet);
#if HWY_TARGET <= HWY_AVX2  // masked loads and stores that touch nothing past the mask
      if (j < r.count) aligned_at<false, InFloat>(d, hn::FirstN(d, r.count - j), s, r, j, g.sheet);
#else  // elsewhere Highway's masked load reads the whole vector: one lane at a time
      const hn::CappedTag<double, 1> one;
      for (; j < r.count; ++j) aligned_at<true, InFloat>(one, hn::FirstN(one, 1), s, r, j, g.sheet);
#endif
    }
    // the corners' sums into the other sheet's points (an engine's gather would take them)
    fold(n, s.part[0][0].data(), s.part[1][0].data(), s.part[2][0].data(), s.sum_x.data() + g.sheet);
    fold(n, s.part[0][1].data(), s.part[1][1].data(), s.part[2][1].data(), s.sum_y.data() + g.sheet);
    fold(n, s.part[0][2].data(), s.part[1][2].data(), s.part[2][2].data(), s.sum_z.data() + g.sheet);
  }
}

void Aligned(ContactSet& s) { aligned<false>(s); }
void AlignedInFloat(ContactSet& s) { aligned<true>(s); }

}  // namespace HWY_NAMESPACE
}  // namespace drape::bench::contact_ceiling
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
#include "simd/kernels.h"

namespace drape::bench::contact_ceiling {

HWY_EXPORT(Gathered);
HWY_EXPORT(Aligned);
HWY_EXPORT(AlignedInFloat);

// One substep's contacts of the stack per iteration, in layout 0 (gathered), 1 (aligned)
// or 2 (aligned, the law in float). The counters check what was timed: net_over_total, the
// net force on the stack over the sum of its magnitudes (zero up to rounding: every share
// is taken from the point it pushes), and difference, the largest difference between the
// forces on a point and those of another layout (the gathered one, or for it the aligned
// one) over the largest force: rounding in double (both evaluate the same contacts), or
// what the law in float changes.
void BM_CeilingContacts(benchmark::State& state) {
  const int layout = int(state.range(0));
  ContactSet set;
  auto run = [&](int in_layout) {
    if (in_layout == 2)
      HWY_DYNAMIC_DISPATCH(AlignedInFloat)(set);
    else if (in_layout == 1)
      HWY_DYNAMIC_DISPATCH(Aligned)(set);
    else
      HWY_DYNAMIC_DISPATCH(Gathered)(set);
  };
  for (auto _ : state) {
    run(layout);
    benchmark::DoNotOptimize(set.sum_z.data());
    benchmark::ClobberMemory();
  }
  double push = 0, net = 0, largest = 0, differ = 0;
  for (std::size_t p = 0; p < set.sum_z.size(); ++p) {
    net += set.sum_z[p];
    push += std::abs(set.sum_z[p]);
  }
  const Array x = set.sum_x, y = set.sum_y, z = set.sum_z;
  run(layout == 0 ? 1 : 0);
  for (std::size_t p = 0; p < z.size(); ++p) {
    largest = std::max({largest, std::abs(x[p]), std::abs(y[p]), std::abs(z[p])});
    differ = std::max(
        {differ, std::abs(x[p] - set.sum_x[p]), std::abs(y[p] - set.sum_y[p]), std::abs(z[p] - set.sum_z[p])});
  }
  state.counters["contacts"] = double(set.size());
  state.counters["net_over_total"] = push > 0 ? std::abs(net) / push : 0.0;
  state.counters["difference"] = largest > 0 ? differ / largest : 0.0;
  state.counters["contacts_per_s"] =
      benchmark::Counter(double(set.size()) * double(state.iterations()), benchmark::Counter::kIsRate);
  state.SetLabel(drape::detail::simd::target_name());
}
BENCHMARK(BM_CeilingContacts)->ArgName("layout")->Arg(0)->Arg(1)->Arg(2);

}  // namespace drape::bench::contact_ceiling
#endif  // HWY_ONCE
