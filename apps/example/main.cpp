// drape-example: the smallest complete program that embeds drape (docs/api.md walks
// through it). It builds a world from code, adds two sheets, runs frames with its own
// per-frame callback, and reads positions through zero-copy spans.
//
// Sheet 1 hangs from its four corners (the paper's Fig 5 set-up). Sheet 2 starts flat and
// unstressed far away, so no spring acts on it and it falls freely: after k substeps of
// semi-implicit Euler its drop is g·dt²·k(k+1)/2, which the program checks at every frame.
#include <drape/drape.h>

#include <algorithm>
#include <cmath>
#include <cstdio>

int main() {
  drape::WorldDef world_def;
  world_def.dt = 1e-3;      // s per substep
  world_def.threads = 2;    // results are the same for any thread count
  drape::World world(world_def);

  drape::SheetDef cloth;
  cloth.m = cloth.n = 16;
  cloth.mass = 0.3;
  cloth.stiffness = 150.0;
  cloth.damping = 0.01;
  cloth.pins = drape::corner_points(cloth.m, cloth.n);
  const drape::SheetId hanging = world.add_sheet(cloth);

  drape::SheetDef free_sheet;
  free_sheet.m = free_sheet.n = 4;
  free_sheet.center = {5.0, 0.0, 10.0};
  const drape::SheetId falling = world.add_sheet(free_sheet);

  const double g = -world_def.gravity.z;
  const int substeps_per_frame = 40;
  bool free_fall_ok = true;

  std::printf("%5s %8s %12s %12s %12s\n", "frame", "time_s", "cloth_sag_m", "fall_m", "expected_m");
  world.run_frames(10, substeps_per_frame, [&](int frame) {
    // Views are spans over the world's own buffers: nothing is copied.
    const drape::SheetView<double> c = world.view(hanging);
    const double lowest = *std::min_element(c.z.begin(), c.z.end());
    const drape::SheetView<double> f = world.view(falling);
    const double fall = free_sheet.center.z - f.z[0];

    const double k = static_cast<double>(world.step_count());
    const double expected = g * world_def.dt * world_def.dt * k * (k + 1) / 2;
    if (std::abs(fall - expected) > 1e-9 * std::max(1.0, expected)) free_fall_ok = false;
    std::printf("%5d %8.3f %12.6f %12.6f %12.6f\n", frame, world.time(), cloth.center.z - lowest, fall, expected);
    return free_fall_ok;  // returning false would stop the run early
  });

  std::printf("free fall %s\n", free_fall_ok ? "matches g*dt^2*k(k+1)/2" : "DOES NOT MATCH");
  return free_fall_ok ? 0 : 1;
}
