// Force terms of one sheet. Each physical effect is one kernel over SoA arrays; a sheet
// runs only the kernels of the terms it has (chosen per sheet, never per point).
#pragma once

#include "sheet_data.h"

namespace drape::detail {

template <class Real>
struct ConstVec3Ptr {
  const Real* x;
  const Real* y;
  const Real* z;
};

template <class Real>
struct Vec3Ptr {
  Real* x;
  Real* y;
  Real* z;
  operator ConstVec3Ptr<Real>() const { return {x, y, z}; }
};

template <class Real>
ConstVec3Ptr<Real> cptr(const Vec3Array<Real>& a) { return {a.x.data(), a.y.data(), a.z.data()}; }
template <class Real>
Vec3Ptr<Real> ptr(Vec3Array<Real>& a) { return {a.x.data(), a.y.data(), a.z.data()}; }

// eq (6)–(7): writes (not adds) the elastic force of every spring into f, both endpoints.
// `row` is scratch of n+1 values per component.
template <class Real>
void spring_forces(const Topology<Real>& topo, ConstVec3Ptr<Real> x, Vec3Ptr<Real> f, Vec3Ptr<Real> row);

// The same for rows [row_begin, row_end) only: writes f of those rows, reading x of the
// rows next to them. Each row's result is bit-identical to the whole-sheet call, so a
// sheet split into blocks of rows (one per task) gives the same state for any split.
template <class Real>
void spring_forces(const Topology<Real>& topo, ConstVec3Ptr<Real> x, Vec3Ptr<Real> f, Vec3Ptr<Real> row,
                   std::uint32_t row_begin, std::uint32_t row_end);

// Rows [row_begin, row_end) of sheet_forces, with `row` as the block's scratch row; each
// point's terms are added in the same order as in sheet_forces, so a split sheet's forces
// are bit-identical. Never called for a sheet with obstacles near it (they read normals
// across rows): the world keeps such sheets whole.
template <class Real>
void sheet_forces_rows(Sheet<Real>& sheet, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f,
                       Vec3Ptr<Real> row, std::uint32_t row_begin, std::uint32_t row_end);

// f = springs(x) − C·v + contacts + anchors(x) + near obstacles(x): the total force of
// eq (4) without gravity, which the integrators add as an acceleration. Contact forces are
// the ones the host stage gathered from the positions at the start of the substep; a
// multi-stage integrator holds them constant over the substep.
template <class Real>
void sheet_forces(Sheet<Real>& sheet, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f);

// Receives points [first, first + count) of a sheet once their total force is final.
struct RowSink {
  void* context = nullptr;
  void (*done)(void* context, std::size_t first, std::size_t count) = nullptr;

  // Wraps a callable taking (first, count); it must outlive the sink.
  template <class F>
  static RowSink of(F& f) {
    return {&f, [](void* c, std::size_t first, std::size_t count) { (*static_cast<F*>(c))(first, count); }};
  }
};

// sheet_forces, handing each row to `sink` as soon as its force is final, while it is
// still in cache. An explicit integrator may move the row's points (x, v) in the sink: no
// later force of this sweep reads them. This saves the integrator a pass over the whole
// sheet's forces (a sheet beyond the caches streams half the bytes per step).
template <class Real>
void sheet_forces_by_rows(Sheet<Real>& sheet, ConstVec3Ptr<Real> x, ConstVec3Ptr<Real> v, Vec3Ptr<Real> f,
                          RowSink sink);

}  // namespace drape::detail
