// The embedding API of BasicWorld: the per-frame loop and the full state a caller can
// copy out and back in (the engine side of checkpoints).
#include <drape/drape.h>
#include <gtest/gtest.h>

#include <cstring>
#include <stdexcept>
#include <vector>

namespace {

drape::World hanging_world() {
  drape::World world(drape::WorldDef{.dt = 5e-4, .threads = 1});
  drape::SheetDef cloth;
  cloth.m = 5;
  cloth.n = 7;
  cloth.stiffness = 250;
  cloth.damping = 0.02;
  cloth.pins = drape::corner_points(cloth.m, cloth.n);
  world.add_sheet(cloth);
  drape::SheetDef loose;
  loose.m = loose.n = 2;
  loose.center = {3, 0, 1};
  loose.initial_velocity = {0.5, 0, 2};
  world.add_sheet(loose);
  return world;
}

bool same_bits(std::span<const double> a, std::span<const double> b) {
  return a.size() == b.size() && std::memcmp(a.data(), b.data(), a.size_bytes()) == 0;
}

void expect_same_state(const drape::World& a, const drape::World& b) {
  ASSERT_EQ(a.sheet_count(), b.sheet_count());
  for (std::size_t k = 0; k < a.sheet_count(); ++k) {
    const auto va = a.view(a.sheets()[k]), vb = b.view(b.sheets()[k]);
    EXPECT_TRUE(same_bits(va.x, vb.x) && same_bits(va.y, vb.y) && same_bits(va.z, vb.z)) << "sheet " << k;
    EXPECT_TRUE(same_bits(va.vx, vb.vx) && same_bits(va.vy, vb.vy) && same_bits(va.vz, vb.vz)) << "sheet " << k;
  }
  EXPECT_EQ(a.step_count(), b.step_count());
  EXPECT_EQ(a.time(), b.time());
}

}  // namespace

TEST(Embedding, RunFramesCallsBackAfterEverySubstepBlock) {
  auto world = hanging_world();
  std::vector<std::uint64_t> steps_seen;
  const int run = world.run_frames(4, 25, [&](int frame) {
    EXPECT_EQ(frame, static_cast<int>(steps_seen.size()) + 1);
    steps_seen.push_back(world.step_count());
  });
  EXPECT_EQ(run, 4);
  EXPECT_EQ(steps_seen, (std::vector<std::uint64_t>{25, 50, 75, 100}));
}

TEST(Embedding, RunFramesStopsWhenTheCallbackReturnsFalse) {
  auto world = hanging_world();
  int calls = 0;
  const int run = world.run_frames(10, 3, [&](int frame) {
    ++calls;
    return frame < 3;
  });
  EXPECT_EQ(run, 3);
  EXPECT_EQ(calls, 3);
  EXPECT_EQ(world.step_count(), 9u);
}

// A frame the guard fails ends the run before its callback: every frame handed over is
// finite, and the count returned is those frames (forward Euler at 0.05 s on a stiff
// undamped sheet grows geometrically within a few frames).
TEST(Embedding, RunFramesStopsWhenTheWorldHalts) {
  drape::WorldDef wd;
  wd.integrator = drape::Integrator::ForwardEuler;
  wd.dt = 0.05;
  drape::World world(wd);
  drape::SheetDef d;
  d.m = d.n = 4;
  d.stiffness = 1000;
  world.state(world.add_sheet(d)).vz[12] = 1;  // a kick sets the springs vibrating
  int calls = 0;
  bool all_finite = true;
  const int run = world.run_frames(100, 10, [&](int) {
    ++calls;
    all_finite = all_finite && world.all_finite();
  });
  EXPECT_TRUE(world.halted());
  EXPECT_LT(run, 100);
  EXPECT_EQ(run, calls);
  EXPECT_TRUE(all_finite);
  EXPECT_EQ(world.step_count(), std::uint64_t(10 * (run + 1)));
  EXPECT_THROW(world.step(-1), std::invalid_argument);
}

TEST(Embedding, RunFramesEqualsPlainStepping) {
  auto framed = hanging_world();
  auto plain = hanging_world();
  framed.run_frames(6, 17, [](int) {});
  plain.step(6 * 17);
  expect_same_state(framed, plain);
}

TEST(Embedding, CopiedFullStateContinuesBitForBit) {
  // An uninterrupted run against a second world that gets the first one's state halfway,
  // through spans only, as a checkpoint reader would do it.
  auto original = hanging_world();
  original.step(300);
  auto copy = hanging_world();
  for (std::size_t k = 0; k < original.sheet_count(); ++k) {
    const drape::SheetId from = original.sheets()[k], to = copy.sheets()[k];
    const auto v = original.view(from);
    const std::vector<double> x(v.x.begin(), v.x.end()), y(v.y.begin(), v.y.end()), z(v.z.begin(), v.z.end());
    const std::vector<double> vx(v.vx.begin(), v.vx.end()), vy(v.vy.begin(), v.vy.end()), vz(v.vz.begin(), v.vz.end());
    copy.set_state(to, {v.m, v.n, x, y, z, vx, vy, vz});
    const auto memory = original.integrator_memory(from);
    copy.set_integrator_memory(to, std::vector<double>(memory.begin(), memory.end()));
  }
  copy.set_step_count(original.step_count());
  expect_same_state(copy, original);
  original.step(400);
  copy.step(400);
  expect_same_state(copy, original);
}

TEST(Embedding, SetStateRefusesSpansOfTheWrongSize) {
  auto world = hanging_world();
  const drape::SheetId id = world.sheets()[0];
  const auto before = world.view(id);
  const std::vector<double> before_z(before.z.begin(), before.z.end());
  const std::vector<double> good(before.size(), 0.0), short_one(before.size() - 1, 0.0);
  EXPECT_THROW(world.set_state(id, {0, 0, good, good, short_one, good, good, good}), std::invalid_argument);
  const auto after = world.view(id);
  EXPECT_TRUE(same_bits(after.z, before_z));
}

TEST(Embedding, IntegratorMemoryIsStoredAsGiven) {
  auto world = hanging_world();
  const drape::SheetId id = world.sheets()[1];
  const std::vector<double> memory{1.0, -0.0, 2.5e-300};
  world.set_integrator_memory(id, memory);
  EXPECT_TRUE(same_bits(world.integrator_memory(id), memory));
  world.set_integrator_memory(id, {});
  EXPECT_TRUE(world.integrator_memory(id).empty());
}

TEST(Embedding, StepCountSetsTheClock) {
  auto world = hanging_world();
  world.set_step_count(1234);
  EXPECT_EQ(world.step_count(), 1234u);
  EXPECT_DOUBLE_EQ(world.time(), 1234 * 5e-4);
  world.step(6);
  EXPECT_EQ(world.step_count(), 1240u);
}
