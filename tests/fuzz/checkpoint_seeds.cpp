// Writes a few small valid checkpoints into a directory, as the fuzzer's starting corpus:
// the shapes checkpoint_fuzz applies to, in both precisions, with and without integrator memory.
#include "checkpoint.h"

#include <cstdio>
#include <exception>
#include <filesystem>

namespace {

template <class Real>
drape::BasicWorld<Real> seed_world(int steps) {
  drape::BasicWorld<Real> world;
  drape::SheetDef a, b;
  a.m = a.n = 1;
  a.pins = {0};
  b.m = 2;
  b.n = 3;
  b.anchors = drape::anchors_at(drape::corner_points(2, 3), 40);
  world.add_sheet(a);
  world.add_sheet(b);
  world.step(steps);
  return world;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: checkpoint_seeds DIR\n");
    return 2;
  }
  try {
    const std::filesystem::path dir = argv[1];
    std::filesystem::create_directories(dir);
    drape::save_checkpoint(seed_world<double>(0), dir / "double_start.ckpt");
    drape::save_checkpoint(seed_world<double>(25), dir / "double_25_steps.ckpt");
    drape::save_checkpoint(seed_world<float>(10), dir / "float_10_steps.ckpt");
    auto with_memory = seed_world<double>(5);
    with_memory.set_integrator_memory(with_memory.sheets()[0], std::vector<double>{1.0, -2.0});
    with_memory.set_integrator(drape::Integrator::ForwardEuler);
    drape::save_checkpoint(with_memory, dir / "double_memory.ckpt");
  } catch (const std::exception& e) {
    std::fprintf(stderr, "checkpoint_seeds: %s\n", e.what());
    return 1;
  }
  return 0;
}
