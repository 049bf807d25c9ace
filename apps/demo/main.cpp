// drape-demo: the paper's Fig 5 set-up in its simplest form. A square sheet pinned at its
// four corners falls under gravity; every frame prints the sag of its centre and its energies.
#include <drape/drape.h>

#include <cstdio>
#include <cstdlib>
#include <string>

int main(int argc, char** argv) {
  const int frames = argc > 1 ? std::atoi(argv[1]) : 30;
  if (frames <= 0) {
    std::fprintf(stderr, "usage: drape-demo [FRAMES]  (FRAMES: a positive whole number, default 30)\n");
    return 2;
  }
  drape::WorldDef world_def;
  world_def.dt = 1e-3;
  drape::World world(world_def);

  drape::SheetDef sheet;
  sheet.m = sheet.n = 20;
  sheet.width = sheet.height = 1.0;
  sheet.mass = 0.5;
  sheet.stiffness = 200.0;
  sheet.damping = 0.02;
  sheet.pins = drape::corner_points(sheet.m, sheet.n);
  const drape::SheetId id = world.add_sheet(sheet);
  const std::uint32_t centre = drape::center_point(sheet.m, sheet.n);

  const int substeps_per_frame = 1000 / 30;  // 30 frames per simulated second
  std::printf("# %u points, %u springs, dt = %g s, stable step estimate = %.3g s\n",
              drape::point_count(sheet.m, sheet.n), drape::spring_count(sheet.m, sheet.n), world_def.dt,
              world.stable_step_estimate());
  std::printf("%6s %9s %10s %12s %12s %12s %12s %10s\n", "frame", "time_s", "sag_m", "kinetic_J", "spring_J",
              "gravity_J", "total_J", "strain");
  for (int frame = 1; frame <= frames; ++frame) {
    world.step(substeps_per_frame);
    const drape::SheetDiagnostics d = world.diagnostics(id);
    if (!d.finite) {
      std::fprintf(stderr, "drape-demo: the simulation became non-finite at frame %d; lower dt below %.3g s\n", frame,
                   world.stable_step_estimate());
      return 1;
    }
    const double sag = sheet.center.z - world.view(id).z[centre];
    std::printf("%6d %9.4f %10.5f %12.5g %12.5g %12.5g %12.5g %10.4f\n", frame, world.time(), sag, d.energy.kinetic,
                d.energy.spring, d.energy.gravity, d.energy.total(), d.max_strain);
  }
  return 0;
}
