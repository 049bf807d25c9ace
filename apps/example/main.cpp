// drape-example: the smallest complete program that embeds drape (docs/api.md walks
// through it). It builds a world from code, adds two sheets and an obstacle, runs frames
// with its own per-frame callback, and reads positions through zero-copy spans.
//
// Sheet 1 hangs from its four corners (the paper's Fig 5 set-up) and sags onto a sphere
// below its centre, whose repulsion (eq 9) keeps every point outside it. Sheet 2 starts flat
// and unstressed far away, so no spring or obstacle acts on it and it falls freely: after k
// substeps of semi-implicit Euler its drop is g·dt²·k(k+1)/2, checked at every frame.
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

  drape::ObstacleDef ball;  // a plain value, copied by the world
  ball.shape = drape::ObstacleShape::Sphere;
  ball.center = {0.0, 0.0, -0.2};
  ball.size = {0.15, 0.15, 0.15};  // radius = size.x, m
  ball.c = 0.5;                    // J, strength of E = c·exp(−f/ξ)
  ball.xi = 0.005;                 // m
  world.add_obstacle(ball);

  drape::SheetDef free_sheet;
  free_sheet.m = free_sheet.n = 4;
  free_sheet.center = {5.0, 0.0, 10.0};
  const drape::SheetId falling = world.add_sheet(free_sheet);

  const double g = -world_def.gravity.z;
  const int substeps_per_frame = 40;
  bool free_fall_ok = true;
  double closest = 1e9;  // m, nearest any cloth point came to the sphere's centre

  std::printf("%5s %8s %12s %12s %12s\n", "frame", "time_s", "cloth_sag_m", "fall_m", "expected_m");
  world.run_frames(10, substeps_per_frame, [&](int frame) {
    // Views are spans over the world's own buffers: nothing is copied.
    const drape::SheetView<double> c = world.view(hanging);
    const double lowest = *std::min_element(c.z.begin(), c.z.end());
    for (std::size_t p = 0; p < c.size(); ++p)
      closest = std::min(closest, std::hypot(c.x[p] - ball.center.x, c.y[p] - ball.center.y, c.z[p] - ball.center.z));
    const drape::SheetView<double> f = world.view(falling);
    const double fall = free_sheet.center.z - f.z[0];

    const double k = static_cast<double>(world.step_count());
    const double expected = g * world_def.dt * world_def.dt * k * (k + 1) / 2;
    if (std::abs(fall - expected) > 1e-9 * std::max(1.0, expected)) free_fall_ok = false;
    std::printf("%5d %8.3f %12.6f %12.6f %12.6f\n", frame, world.time(), cloth.center.z - lowest, fall, expected);
    return free_fall_ok;  // returning false would stop the run early
  });

  const bool outside = closest > ball.size.x;
  std::printf("cloth came within %.4f m of the sphere's centre (radius %.2f m): %s\n", closest, ball.size.x,
              outside ? "stayed outside" : "WENT INSIDE");
  std::printf("free fall %s\n", free_fall_ok ? "matches g*dt^2*k(k+1)/2" : "DOES NOT MATCH");
  return free_fall_ok && outside ? 0 : 1;
}
