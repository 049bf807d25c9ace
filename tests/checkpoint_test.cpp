// Checkpoints (apps/common/checkpoint.h): a saved world comes back bit for bit, a resumed
// run equals an uninterrupted one, and every damaged or foreign file is refused whole.
#include "checkpoint.h"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstring>
#include <filesystem>
#include <fstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

template <class Real>
drape::BasicWorld<Real> make_world(std::uint32_t m1 = 6, std::uint32_t n1 = 5) {
  drape::BasicWorld<Real> world(drape::WorldDef{.dt = 1e-3, .threads = 1});
  drape::SheetDef pinned;
  pinned.m = m1;
  pinned.n = n1;
  pinned.stiffness = 300;
  pinned.damping = 0.05;
  pinned.pins = drape::corner_points(pinned.m, pinned.n);
  world.add_sheet(pinned);
  drape::SheetDef anchored;
  anchored.m = 2;
  anchored.n = 3;
  anchored.center = {2, 0, 0};
  anchored.orientation = drape::quat_from_axis_angle({1, 0, 0}, 0.3);
  anchored.anchors = drape::anchors_at(drape::corner_points(2, 3), 50);
  anchored.initial_velocity = {0.1, -0.2, 0.3};
  world.add_sheet(anchored);
  return world;
}

// The whole evolving state as raw bytes, so "equal" means bit for bit (NaN and -0 included).
template <class Real>
std::vector<unsigned char> state_bytes(const drape::BasicWorld<Real>& world) {
  std::vector<unsigned char> out;
  auto append = [&](const void* p, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    out.insert(out.end(), b, b + n);
  };
  const std::uint64_t steps = world.step_count();
  append(&steps, sizeof steps);
  for (drape::SheetId id : world.sheets()) {
    const auto v = world.view(id);
    for (auto s : {v.x, v.y, v.z, v.vx, v.vy, v.vz}) append(s.data(), s.size_bytes());
    const auto memory = world.integrator_memory(id);
    append(memory.data(), memory.size_bytes());
  }
  return out;
}

class TempDir {
 public:
  TempDir() {
    const auto* info = testing::UnitTest::GetInstance()->current_test_info();
    path_ = fs::temp_directory_path() /
            ("drape_checkpoint_" + std::string(info->name()) + "_" + std::to_string(::getpid()));
    fs::remove_all(path_);
    fs::create_directories(path_);
  }
  ~TempDir() { fs::remove_all(path_); }
  const fs::path& path() const { return path_; }
  std::vector<fs::path> entries() const {
    std::vector<fs::path> e;
    for (const auto& d : fs::recursive_directory_iterator(path_)) e.push_back(d.path());
    return e;
  }

 private:
  fs::path path_;
};

std::vector<unsigned char> read_bytes(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const fs::path& p, const std::vector<unsigned char>& bytes) {
  std::ofstream out(p, std::ios::binary);
  out.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
}

// The message must name the file and say something; returns it for further checks.
template <class F>
std::string refusal(F&& f, const std::string& source) {
  try {
    f();
  } catch (const std::runtime_error& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find(source), std::string::npos) << what;
    return what;
  }
  ADD_FAILURE() << "accepted a bad checkpoint " << source;
  return {};
}

std::vector<unsigned char> small_checkpoint() {
  auto world = make_world<double>(1, 1);
  world.step(3);
  return drape::encode_checkpoint(drape::capture_checkpoint(world));
}

}  // namespace

TEST(Checkpoint, ChecksumIsFnv1a64OfTheStandard) {
  // Published FNV-1a 64 test vectors.
  EXPECT_EQ(drape::fnv1a64({}), 0xcbf29ce484222325ull);
  const unsigned char a[] = {'a'};
  EXPECT_EQ(drape::fnv1a64(a), 0xaf63dc4c8601ec8cull);
  const unsigned char foobar[] = {'f', 'o', 'o', 'b', 'a', 'r'};
  EXPECT_EQ(drape::fnv1a64(foobar), 0x85944171f73967e8ull);
}

TEST(Checkpoint, HeaderIsTheDocumentedLittleEndianLayout) {
  auto world = make_world<float>();
  world.step(7);
  const auto bytes = drape::encode_checkpoint(drape::capture_checkpoint(world));
  EXPECT_EQ(std::string(bytes.begin(), bytes.begin() + 8), "DRAPECKP");
  EXPECT_EQ(bytes[8], 3);   // format version, low byte first
  EXPECT_EQ(bytes[9], 0);
  EXPECT_EQ(bytes[12], 4);  // float world: 4 bytes per value
  EXPECT_EQ(bytes[24], 7);  // step count, after the (zero) fingerprint
  // magic..sheet count, 19-byte integrator name, then per sheet 16 bytes + 6 arrays of floats
  // + 24 bytes of solve counters (u64, u32, f64, u32), an empty contact memory (its u64
  // count: no sheets touch), checksum
  const std::size_t expected =
      8 + 4 + 4 + 8 + 8 + 8 + 24 + 4 + 19 + 4 + (16 + 6 * 4 * 7 * 6 + 24) + (16 + 6 * 4 * 3 * 4 + 24) + 8 + 8;
  EXPECT_EQ(bytes.size(), expected);
}

template <class Real>
void round_trip_is_bit_identical() {
  TempDir dir;
  auto world = make_world<Real>();
  world.step(40);
  const std::vector<Real> memory{Real(1.5), Real(-0.0), Real(3e-7)};
  world.set_integrator_memory(world.sheets()[1], memory);
  drape::save_checkpoint(world, dir.path() / "a.ckpt");

  auto restored = make_world<Real>();
  drape::load_checkpoint(dir.path() / "a.ckpt", restored);
  EXPECT_EQ(state_bytes(restored), state_bytes(world));
  EXPECT_EQ(restored.time(), world.time());
  EXPECT_EQ(restored.step_count(), 40u);
}

TEST(Checkpoint, RoundTripIsBitIdenticalDouble) { round_trip_is_bit_identical<double>(); }
TEST(Checkpoint, RoundTripIsBitIdenticalFloat) { round_trip_is_bit_identical<float>(); }

TEST(Checkpoint, ResumedRunEqualsUninterruptedRunBitForBit) {
  TempDir dir;
  auto uninterrupted = make_world<double>();
  uninterrupted.step(60);
  drape::save_checkpoint(uninterrupted, dir.path() / "mid.ckpt");
  uninterrupted.step(90);

  auto resumed = make_world<double>();  // a fresh process: built from the same definitions
  drape::load_checkpoint(dir.path() / "mid.ckpt", resumed);
  resumed.step(90);
  EXPECT_EQ(state_bytes(resumed), state_bytes(uninterrupted));
  EXPECT_EQ(resumed.time(), uninterrupted.time());
}

// Sheets in contact carry kept contact sets from one substep to the next (each point
// walks from the cell it had, contacts.h), so a resumed run equals an uninterrupted one
// only if the checkpoint holds them: three pinned sheets dropped onto each other and a
// sheet folded onto itself, checkpointed after 5 frames of 10 substeps (not a multiple of
// the 64 substeps between full searches; the fold's halves are still in range), restored into fresh worlds and run on.
drape::World contact_scene(bool fold) {
  drape::World world(drape::WorldDef{.dt = fold ? 2e-4 : 1e-3, .threads = 1});
  drape::SheetDef sd;
  if (fold) {
    sd.m = 21;
    sd.n = 9;
    sd.width = 0.15;
    sd.height = 0.3;
    sd.mass = 0.1;
    sd.stiffness = 50;
    sd.damping = 1e-3;
    sd.self_collision = true;
    const drape::SheetId id = world.add_sheet(sd);
    auto s = world.state(id);
    for (std::uint32_t i = 11; i <= sd.m; ++i)
      for (std::uint32_t j = 0; j <= sd.n; ++j) {
        const std::uint32_t p = drape::point_index(sd.n, i, j), mirror = drape::point_index(sd.n, sd.m - i, j);
        s.y[p] = s.y[mirror];
        s.z[p] = 0.012;
      }
    return world;
  }
  sd.m = sd.n = 12;
  sd.width = sd.height = 0.3;
  sd.stiffness = 50;
  sd.damping = 0.05;
  sd.pins = drape::corner_points(sd.m, sd.n);
  for (int layer = 0; layer < 3; ++layer) {
    sd.center = {0.01 * layer, 0.0, 0.008 * layer};
    world.add_sheet(sd);
  }
  return world;
}

TEST(Checkpoint, ResumedRunWithSheetsInContactEqualsUninterruptedRunBitForBit) {
  for (bool fold : {false, true}) {
    drape::World uninterrupted = contact_scene(fold);
    for (int frame = 0; frame < 5; ++frame) uninterrupted.step(10);
    const auto bytes = drape::encode_checkpoint(drape::capture_checkpoint(uninterrupted));
    ASSERT_FALSE(drape::decode_checkpoint(bytes, "c.ckpt").contact_memory.empty()) << "fold " << fold;
    for (int frame = 5; frame < 30; ++frame) uninterrupted.step(10);

    drape::World resumed = contact_scene(fold);
    drape::apply_checkpoint(drape::decode_checkpoint(bytes, "c.ckpt"), resumed, "c.ckpt");
    for (int frame = 5; frame < 30; ++frame) resumed.step(10);
    EXPECT_EQ(state_bytes(resumed), state_bytes(uninterrupted)) << "fold " << fold;

    // The memory is what makes them equal: resumed with it forgotten (a fresh search, as
    // from a format 2 checkpoint), the same run ends elsewhere.
    drape::World searched = contact_scene(fold);
    drape::apply_checkpoint(drape::decode_checkpoint(bytes, "c.ckpt"), searched, "c.ckpt");
    searched.set_contact_memory({});
    for (int frame = 5; frame < 30; ++frame) searched.step(10);
    EXPECT_NE(state_bytes(searched), state_bytes(uninterrupted)) << "fold " << fold;
  }
}

// A sheet removed mid-run (the first of three layers in contact): the pairs' kept work is
// renumbered with the sheets after it, so a checkpoint taken later resumes into a world
// built and cut the same way and runs on bit for bit. (The memory named the removed
// sheet's place and was refused as naming "a pair of sheets the world lacks".)
TEST(Checkpoint, ResumedRunAfterASheetWasRemovedEqualsUninterruptedRun) {
  const auto cut = [](drape::World& w) { w.remove_sheet(w.sheets()[0]); };
  drape::World uninterrupted = contact_scene(false);
  uninterrupted.step(20);
  ASSERT_GT(uninterrupted.contact_pair_count(), 1u);
  cut(uninterrupted);
  uninterrupted.step(20);
  const auto bytes = drape::encode_checkpoint(drape::capture_checkpoint(uninterrupted));
  ASSERT_FALSE(drape::decode_checkpoint(bytes, "c.ckpt").contact_memory.empty());
  uninterrupted.step(100);

  drape::World resumed = contact_scene(false);
  cut(resumed);
  drape::apply_checkpoint(drape::decode_checkpoint(bytes, "c.ckpt"), resumed, "c.ckpt");
  resumed.step(100);
  EXPECT_EQ(state_bytes(resumed), state_bytes(uninterrupted));
}

// A format 2 checkpoint (before contact memory) still resumes: the same bytes without the
// contact memory's count, its run searching afresh.
TEST(Checkpoint, FormatTwoCheckpointStillResumes) {
  drape::World world = contact_scene(false);
  world.step(20);
  auto c = drape::capture_checkpoint(world);
  c.contact_memory.clear();
  auto bytes = drape::encode_checkpoint(c);
  bytes.erase(bytes.end() - 16, bytes.end() - 8);  // the contact memory's u64 count
  bytes[8] = 2;
  const std::uint64_t sum = drape::fnv1a64(std::span(bytes).first(bytes.size() - 8));
  for (int i = 0; i < 8; ++i) bytes[bytes.size() - 8 + i] = static_cast<unsigned char>(sum >> (8 * i));
  drape::World resumed = contact_scene(false);
  drape::apply_checkpoint(drape::decode_checkpoint(bytes, "v2.ckpt"), resumed, "v2.ckpt");
  EXPECT_EQ(resumed.step_count(), 20u);
  drape::World searched = contact_scene(false);
  drape::apply_checkpoint(c, searched, "c.ckpt");
  resumed.step(30);
  searched.step(30);
  EXPECT_EQ(state_bytes(resumed), state_bytes(searched));
}

// Contact memory that does not fit the world (cut short, or naming a point a sheet lacks)
// is refused with a message, and the world goes on as if it had never been offered.
TEST(Checkpoint, ContactMemoryThatDoesNotFitIsRefusedAndLeavesTheWorldUntouched) {
  drape::World world = contact_scene(false), twin = contact_scene(false);
  world.step(35);
  twin.step(35);
  const std::vector<std::uint64_t> memory = world.contact_memory();
  ASSERT_GT(memory.size(), 8u);
  auto cut = memory;
  cut.pop_back();
  EXPECT_THROW(world.set_contact_memory(cut), std::invalid_argument);
  auto foreign = memory;
  foreign[2] = 5;  // written for five sheets
  EXPECT_THROW(world.set_contact_memory(foreign), std::invalid_argument);
  drape::World other = contact_scene(true);  // one sheet: the memory names sheets it lacks
  EXPECT_THROW(other.set_contact_memory(memory), std::invalid_argument);
  auto c = drape::capture_checkpoint(world);
  c.contact_memory = cut;
  const std::string what = refusal([&] { drape::apply_checkpoint(c, world, "cut.ckpt"); }, "cut.ckpt");
  EXPECT_NE(what.find("contact memory"), std::string::npos) << what;
  world.step(25);
  twin.step(25);
  EXPECT_EQ(state_bytes(world), state_bytes(twin));
}

TEST(Checkpoint, TruncatedAtEveryByteIsRefused) {
  const auto bytes = small_checkpoint();
  for (std::size_t size = 0; size < bytes.size(); ++size) {
    const std::string what = refusal(
        [&] { drape::decode_checkpoint(std::span(bytes).first(size), "cut.ckpt"); }, "cut.ckpt");
    if (size >= 8) {
      EXPECT_NE(what.find("truncated"), std::string::npos) << "size " << size << ": " << what;
    }
  }
  EXPECT_NO_THROW(drape::decode_checkpoint(bytes, "whole.ckpt"));
}

TEST(Checkpoint, EveryFlippedByteIsRefused) {
  const auto bytes = small_checkpoint();
  for (std::size_t i = 0; i < bytes.size(); ++i)
    for (unsigned char mask : {0x01, 0x80, 0xff}) {
      auto bad = bytes;
      bad[i] ^= mask;
      refusal([&] { drape::decode_checkpoint(bad, "flip.ckpt"); }, "flip.ckpt");
    }
}

TEST(Checkpoint, ExtraTrailingBytesAreRefused) {
  auto bytes = small_checkpoint();
  bytes.push_back(0);
  refusal([&] { drape::decode_checkpoint(bytes, "long.ckpt"); }, "long.ckpt");
}

TEST(Checkpoint, OtherFormatVersionIsRefusedByName) {
  auto bytes = small_checkpoint();
  for (unsigned char version : {1, 4}) {  // with a checksum that is right for it
    bytes[8] = version;
    const std::uint64_t sum = drape::fnv1a64(std::span(bytes).first(bytes.size() - 8));
    for (int i = 0; i < 8; ++i) bytes[bytes.size() - 8 + i] = static_cast<unsigned char>(sum >> (8 * i));
    const std::string what = refusal([&] { drape::decode_checkpoint(bytes, "old.ckpt"); }, "old.ckpt");
    EXPECT_NE(what.find("format version " + std::to_string(version)), std::string::npos) << what;
  }
}

// The implicit solves' counters (World::solver_stats) go through a checkpoint: a resumed
// run reports every solve that stopped short, not only those after the resume.
TEST(Checkpoint, SolverCountersSurviveACheckpoint) {
  drape::WorldDef wd;
  wd.integrator = drape::Integrator::ImplicitEuler;
  wd.dt = 1.0 / 60;
  wd.cg_max_iterations = 1;  // every solve stops at the cap
  wd.cg_preconditioner = drape::Preconditioner::BlockJacobi;
  auto build = [&] {
    drape::World w(wd);
    drape::SheetDef d;
    d.m = d.n = 6;
    d.stiffness = 1e4;
    d.pins = drape::corner_points(d.m, d.n);
    w.add_sheet(d);
    return w;
  };
  drape::World first = build();
  first.step(5);
  const auto before = first.solver_stats(first.sheets()[0]);
  ASSERT_GT(before.unconverged_solves, 0u);  // the first step, from rest, converges in one
  const auto bytes = drape::encode_checkpoint(drape::capture_checkpoint(first));
  drape::World resumed = build();
  drape::apply_checkpoint(drape::decode_checkpoint(bytes, "solver.ckpt"), resumed, "solver.ckpt");
  const auto after = resumed.solver_stats(resumed.sheets()[0]);
  EXPECT_EQ(after.unconverged_solves, before.unconverged_solves);
  EXPECT_EQ(after.iterations, before.iterations);
  EXPECT_EQ(after.relative_residual, before.relative_residual);
  EXPECT_EQ(after.converged, before.converged);
  resumed.step(2);
  EXPECT_EQ(resumed.solver_stats(resumed.sheets()[0]).unconverged_solves, before.unconverged_solves + 2);
}

TEST(Checkpoint, ForeignFileIsRefused) {
  const std::string text = "{\"scene\": \"not a checkpoint\"}";
  const std::vector<unsigned char> bytes(text.begin(), text.end());
  const std::string what = refusal([&] { drape::decode_checkpoint(bytes, "scene.json"); }, "scene.json");
  EXPECT_NE(what.find("not a drape checkpoint"), std::string::npos) << what;
}

TEST(Checkpoint, DamagedFileLeavesTheWorldUntouched) {
  TempDir dir;
  auto source = make_world<double>();
  source.step(20);
  drape::save_checkpoint(source, dir.path() / "good.ckpt");
  auto bytes = read_bytes(dir.path() / "good.ckpt");
  bytes[bytes.size() / 2] ^= 0x10;
  write_bytes(dir.path() / "bad.ckpt", bytes);

  auto world = make_world<double>();
  world.step(5);
  const auto before = state_bytes(world);
  const std::string bad = (dir.path() / "bad.ckpt").string();
  refusal([&] { drape::load_checkpoint(bad, world); }, bad);
  EXPECT_EQ(state_bytes(world), before);
}

TEST(Checkpoint, WrongShapeOrPrecisionIsRefusedAndLeavesTheWorldUntouched) {
  TempDir dir;
  const fs::path file = dir.path() / "w.ckpt";
  auto source = make_world<double>();
  source.step(10);
  drape::save_checkpoint(source, file);

  auto other_grid = make_world<double>(6, 6);
  const auto before = state_bytes(other_grid);
  EXPECT_NE(refusal([&] { drape::load_checkpoint(file, other_grid); }, file.string()).find("sheet 0 is 6x5"),
            std::string::npos);
  EXPECT_EQ(state_bytes(other_grid), before);

  drape::World fewer;
  fewer.add_sheet({});
  refusal([&] { drape::load_checkpoint(file, fewer); }, file.string());

  auto single = make_world<float>();
  EXPECT_NE(refusal([&] { drape::load_checkpoint(file, single); }, file.string()).find("64-bit"), std::string::npos);

  drape::World other_gravity(drape::WorldDef{.gravity = {0, 0, -1.62}});
  drape::SheetDef a, b;
  a.m = 6;
  a.n = 5;
  b.m = 2;
  b.n = 3;
  other_gravity.add_sheet(a);
  other_gravity.add_sheet(b);
  refusal([&] { drape::load_checkpoint(file, other_gravity); }, file.string());
}

TEST(Checkpoint, CheckpointOfOtherDefinitionsIsRefusedByFingerprint) {
  TempDir dir;
  const fs::path file = dir.path() / "f.ckpt";
  auto world = make_world<double>();
  world.step(3);
  drape::save_checkpoint(world, file, 0x1234);
  auto same_grid = make_world<double>();
  const auto before = state_bytes(same_grid);
  const std::string what = refusal([&] { drape::load_checkpoint(file, same_grid, 0x9999); }, file.string());
  EXPECT_NE(what.find("another scene"), std::string::npos) << what;
  EXPECT_EQ(state_bytes(same_grid), before);
  drape::load_checkpoint(file, same_grid, 0x1234);
  EXPECT_EQ(state_bytes(same_grid), state_bytes(world));
}

TEST(Checkpoint, MissingDirectoryFailsClearlyAndLeavesNothing) {
  TempDir dir;
  auto world = make_world<double>();
  const fs::path file = dir.path() / "no_such_dir" / "x.ckpt";
  const std::string what = refusal([&] { drape::save_checkpoint(world, file); }, file.string());
  EXPECT_NE(what.find("No such file or directory"), std::string::npos) << what;
  EXPECT_TRUE(dir.entries().empty());
}

TEST(Checkpoint, PathThatIsADirectoryFailsClearlyAndLeavesNothing) {
  TempDir dir;
  auto world = make_world<double>();
  const fs::path target = dir.path() / "out";
  fs::create_directory(target);
  const std::string what = refusal([&] { drape::save_checkpoint(world, target); }, target.string());
  EXPECT_NE(what.find("directory"), std::string::npos) << what;
  EXPECT_EQ(dir.entries(), std::vector<fs::path>{target});
  refusal([&] { drape::load_checkpoint(target, world); }, target.string());
}

TEST(Checkpoint, OverwriteReplacesTheWholeFileAndLeavesNoTemporary) {
  TempDir dir;
  const fs::path file = dir.path() / "c.ckpt";
  auto big = make_world<double>(20, 20);
  drape::save_checkpoint(big, file);
  auto small = make_world<double>(1, 1);
  small.step(2);
  drape::save_checkpoint(small, file);
  EXPECT_EQ(read_bytes(file), drape::encode_checkpoint(drape::capture_checkpoint(small)));
  EXPECT_EQ(dir.entries(), std::vector<fs::path>{file});
}

TEST(Checkpoint, FuzzRegressionInputsAreRefusedOrReadCleanly) {
  // Each file once crashed or nearly crashed the reader; now it must be refused with a
  // message or, if it is a valid checkpoint, decoded. Sanitizer builds check memory safety.
  std::size_t count = 0;
  for (const auto& entry : fs::directory_iterator(DRAPE_CHECKPOINT_REGRESSIONS)) {
    if (!entry.is_regular_file() || entry.path().extension() == ".md") continue;
    ++count;
    const auto bytes = read_bytes(entry.path());
    try {
      drape::decode_checkpoint(bytes, entry.path().string());
    } catch (const std::runtime_error& e) {
      EXPECT_NE(std::string(e.what()).find(entry.path().string()), std::string::npos);
    }
  }
  EXPECT_GT(count, 0u);
}
