// Time integrators of one sheet. Each is one step function over the sheet's SoA buffers,
// named in the integrator table (integrate.cpp) with its metadata; integrate() looks the
// row up once per sheet and substep, never per point. Every force evaluation goes through
// sheet_forces(), so a term added there works with every integrator.
#pragma once

#include "forces.h"
#include "sheet_data.h"

namespace drape::detail {

template <class Real>
struct StepParams {
  Real dt;
  Real gx, gy, gz;  // gravity, applied as an acceleration of every point
  // implicit Euler only: conjugate gradient's relative residual target and iteration cap
  double cg_tolerance = 1e-6;
  int cg_max_iterations = 200;
  // local/global and vertex block descent: iterations per step
  int local_global_iterations = 10;
  int vertex_block_iterations = 10;
  Preconditioner cg_preconditioner = Preconditioner::Auto;  // implicit Euler only
};

// One integrator's step of a whole sheet, pins included.
template <class Real>
using StepFunction = void (*)(Sheet<Real>& sheet, const StepParams<Real>& params);

// `bounds`, when given, becomes the sheet's box after the step (sheet_bounds): the per-point
// integrators take it from the update's registers (sheet_forces_by_rows), the others from a
// pass over the points.
template <class Real>
void integrate(Integrator integrator, Sheet<Real>& sheet, const StepParams<Real>& params, Aabb* bounds = nullptr);

// An implicit integrator's solve, into Sheet::last_solve.
void record_solve(SolveStats& stats, int iterations, double relative_residual, bool converged);

// Integrators that evaluate the forces once per substep and then update each point from
// its own force alone (the table's per-point column). Only these let the world split a
// large sheet into row blocks: forces of every block first, then update_points per block.
bool updates_per_point(Integrator integrator);

// Integrators whose substep reads nothing of a sheet but its positions and velocities (the
// table's memoryless column): no factor, guess or solver count kept from one substep to the
// next, so a substep undone by putting x and v back is undone whole. Only these let the world
// try a frame in groups (frames.cpp, frame_may_be_tried), which it may undo that way.
bool remembers_nothing(Integrator integrator);

// Points [begin, end) of such an integrator's update from sheet.force, then the pins among
// them; integrate() is sheet_forces followed by update_points over all points. `box`, when
// given, grows to contain those points after the update and the pins (as integrate's bounds).
template <class Real>
void update_points(Integrator integrator, Sheet<Real>& sheet, const StepParams<Real>& params, std::size_t begin,
                   std::size_t end, simd::Extent<Real>* box = nullptr);

// `levels` substeps of such an integrator on rows [row_begin, row_end) of a wave_ready
// sheet in one sweep (forces.h, sheet_wave): bit-identical to `levels` integrate() calls.
// `swept`, when given, grows to contain those rows at every substep.
template <class Real>
void integrate_wave(Integrator integrator, Sheet<Real>& sheet, const StepParams<Real>& params, std::uint32_t levels,
                    std::uint32_t row_begin, std::uint32_t row_end, WaveScratch<Real>& scratch,
                    Aabb* swept = nullptr);

}  // namespace drape::detail
