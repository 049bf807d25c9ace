// `drape run --checkpoint-every / --resume`, and output that cannot be written: a run killed
// part-way and resumed writes exactly the frames an uninterrupted run writes; a checkpoint
// that is damaged, of another version or of another scene is refused before anything is
// written; a write that fails stops the run and keeps the frames written before it.
#include <signal.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <thread>
#include <vector>

#include "checkpoint.h"
#include "cli_fixture.h"

namespace {

// Heavy enough per frame (49×49 points, 40 substeps, OBJ + VTU) that a kill after the first
// checkpoint lands well before the last frame, even in an optimised build.
std::string scene_text(double stiffness = 120) {
  return R"({"frames": )" +
#ifdef DRAPE_SANITIZED
         std::string("30") +
#else
         std::string("60") +
#endif
         R"(, "dt": 0.0005, "substeps": 40, "sheets": [{"grid": [48, 48], "size": [1, 1], "stiffness": )" +
         std::to_string(stiffness) + R"(, "mass": 0.4, "damping": 0.02,
    "anchors": [{"at": "corners", "stiffness": 400}]}], "output": {"formats": ["obj", "vtk"]}})";
}

// Name → bytes of every frame file and the .pvd series (not temporaries, not the checkpoint).
std::map<std::string, std::string> frame_files(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::directory_iterator(dir)) {
    const std::string name = e.path().filename().string();
    if ((name.rfind("frame_", 0) == 0 || name == "frames.pvd") && e.path().extension() != ".tmp")
      files[name] = Cli::slurp(e.path());
  }
  return files;
}

// Every file in `dir` with its bytes, to show a refused resume changed nothing.
std::map<std::string, std::string> snapshot(const fs::path& dir) {
  std::map<std::string, std::string> files;
  for (const auto& e : fs::directory_iterator(dir)) files[e.path().filename().string()] = Cli::slurp(e.path());
  return files;
}

// Every frame file of the uninterrupted run in `full` is in `part`, with the same bytes.
void expect_same_frames(const fs::path& full, const fs::path& part) {
  const auto expected = frame_files(full), got = frame_files(part);
  ASSERT_EQ(got.size(), expected.size());
  for (const auto& [name, bytes] : expected) {
    const auto it = got.find(name);
    ASSERT_NE(it, got.end()) << name << " missing after the resume";
    EXPECT_TRUE(it->second == bytes) << name << " differs from the uninterrupted run";
  }
}

// Runs `scene` whole, and again with a checkpoint every `every` of its `frames` frames; deletes
// the frames after the checkpoint, resumes them on 2 threads and compares with the whole run.
void expect_resume_writes_the_same_frames(Cli& cli, const fs::path& scene, int every, int frames) {
  const fs::path full = cli.dir / "full", part = cli.dir / "part";
  ASSERT_EQ(cli.drape("run " + scene.string() + " --out " + full.string()).code, 0);
  ASSERT_EQ(cli.drape("run " + scene.string() + " --out " + part.string() + " --checkpoint-every " +
                      std::to_string(every)).code, 0);
  for (int f = every + 1; f <= frames; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05d.obj", f);
    fs::remove(part / name);
  }
  const Result resumed = cli.drape("run " + scene.string() + " --resume " + part.string() + " --threads 2");
  ASSERT_EQ(resumed.code, 0) << resumed.err;
  expect_same_frames(full, part);
}

pid_t spawn(const std::vector<std::string>& args, const std::string& err = "/dev/null") {
  const pid_t pid = ::fork();
  if (pid == 0) {
    std::vector<char*> argv;
    for (const auto& a : args) argv.push_back(const_cast<char*>(a.c_str()));
    argv.push_back(nullptr);
    std::freopen("/dev/null", "w", stdout);
    std::freopen(err.c_str(), "w", stderr);
    ::execv(argv[0], argv.data());
    std::_Exit(127);
  }
  return pid;
}

// Waits (up to a minute) for `file` to appear, sends `signal` to `pid` and returns its wait status.
int status_after_signal(pid_t pid, const fs::path& file, int signal) {
  const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
  while (!fs::exists(file) && std::chrono::steady_clock::now() < deadline)
    std::this_thread::sleep_for(std::chrono::milliseconds(1));
  EXPECT_EQ(::kill(pid, signal), 0);
  int status = 0;
  ::waitpid(pid, &status, 0);
  return status;
}

TEST_F(Cli, KilledRunResumedFromItsCheckpointWritesBitIdenticalFrames) {
  const fs::path scene = write("s.json", scene_text());
  const fs::path full = dir / "full", part = dir / "part";
  const Result whole = drape("run " + scene.string() + " --out " + full.string() + " --threads 2");
  ASSERT_EQ(whole.code, 0) << whole.err;

  // the real thing: start a run, SIGKILL it once its first checkpoint is on disk
  const pid_t pid = spawn({DRAPE_BIN, "run", scene.string(), "--out", part.string(), "--threads", "1",
                           "--checkpoint-every", "5"});
  ASSERT_GT(pid, 0);
  const int status = status_after_signal(pid, part / "checkpoint.drape", SIGKILL);
  ASSERT_TRUE(WIFSIGNALED(status)) << "the run ended before it could be killed";
  const auto last = full / "frame_00030.obj";
  ASSERT_TRUE(fs::exists(last));
  ASSERT_FALSE(fs::exists(part / last.filename())) << "killed too late to test a resume";
  const std::size_t before = frame_files(part).size();

  const Result resumed = drape("run " + scene.string() + " --resume " + part.string() + " --threads 2");
  ASSERT_EQ(resumed.code, 0) << resumed.err;
  EXPECT_NE(resumed.err.find("resuming"), std::string::npos) << resumed.err;

  EXPECT_GT(frame_files(part).size(), before);
  expect_same_frames(full, part);
}

// SIGTERM (or Ctrl-C's SIGINT) asks a run to stop after the frame it is stepping: it exits
// 128 + 15 saying where it stopped, its folder holds frames 0..K of the uninterrupted run
// (no temporaries, the .pvd series listing them all) and, as it keeps checkpoints, one of
// frame K, from which a resume writes the rest of the uninterrupted run byte for byte.
TEST_F(Cli, SignalledRunStopsAfterItsFrameAndResumesBitIdentically) {
  std::string text = scene_text();
  text.replace(text.find("\"frames\": ") + 10, 2, "200");  // far more frames than it takes to signal
  const fs::path scene = write("s.json", text);
  const fs::path full = dir / "full", part = dir / "part", err = dir / "signalled.err";
  ASSERT_EQ(drape("run " + scene.string() + " --out " + full.string()).code, 0);
  const pid_t pid = spawn({DRAPE_BIN, "run", scene.string(), "--out", part.string(), "--threads", "1",
                           "--checkpoint-every", "1000"},
                          err.string());
  ASSERT_GT(pid, 0);
  const int status = status_after_signal(pid, part / "frame_00001.obj", SIGTERM);
  ASSERT_TRUE(WIFEXITED(status)) << "ended by the signal itself, not after its frame";
  const std::string said = slurp(err);
  ASSERT_EQ(WEXITSTATUS(status), 128 + SIGTERM) << said;
  const auto at = said.find("stopped by a signal after frame ");
  ASSERT_NE(at, std::string::npos) << said;
  const int last = std::atoi(said.c_str() + at + 32);
  EXPECT_NE(said.find("frames 0–" + std::to_string(last) + " are written"), std::string::npos) << said;
  EXPECT_NE(said.find("--resume " + part.string() + " continues"), std::string::npos) << said;
  const auto written = frame_files(part), expected = frame_files(full);
  for (const auto& e : fs::directory_iterator(part)) EXPECT_NE(e.path().extension(), ".tmp") << e.path();
  ASSERT_LT(last, 200) << said;
  for (int f = 0; f <= 200; ++f) {
    char name[32];
    std::snprintf(name, sizeof name, "frame_%05d.obj", f);
    const auto it = written.find(name);
    ASSERT_EQ(it != written.end(), f <= last) << name;
    if (it != written.end()) {
      EXPECT_TRUE(it->second == expected.at(name)) << name << " differs from the uninterrupted run";
    }
  }
  EXPECT_EQ(occurrences(written.at("frames.pvd"), "<DataSet "), std::size_t(last) + 1);
  const Result resumed = drape("run " + scene.string() + " --resume " + part.string());
  ASSERT_EQ(resumed.code, 0) << resumed.err;
  expect_same_frames(full, part);
}

// Ctrl-C during drape sweep or batch stops it at once (the signal's own status), saying that
// what finished is kept in the journal; the same command again runs only the rest: a sweep
// then writes the CSV of an uninterrupted one (wall times aside), a batch every scene's row.
TEST_F(Cli, InterruptedSweepAndBatchSayWhatIsKeptAndTheSameCommandFinishes) {
  const fs::path scene = write("s.json", R"({"frames": 200, "dt": 0.001, "substeps": 20, "sheets": [{"grid": [40, 40],
    "size": [1, 1], "stiffness": 20, "mass": 1, "pins": "corners", "damping": 0.01}]})");
  // waits for the journal's first finished run, interrupts, returns the wait status
  auto interrupted = [&](const std::vector<std::string>& args, const fs::path& journal, const fs::path& err) {
    const pid_t pid = spawn(args, err.string());
    const auto deadline = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    auto recorded = [&] {
      std::error_code ec;
      for (const auto& e : fs::directory_iterator(journal, ec))
        if (fs::file_size(e.path(), ec) > 0) return true;
      return false;
    };
    while (!recorded() && std::chrono::steady_clock::now() < deadline)
      std::this_thread::sleep_for(std::chrono::milliseconds(1));
    EXPECT_EQ(::kill(pid, SIGINT), 0);
    int status = 0;
    ::waitpid(pid, &status, 0);
    return status;
  };
  auto without_wall_times = [](const std::string& csv) {
    std::istringstream in(csv);
    std::string out;
    std::ptrdiff_t column = -1;  // wall_time_s's, from the header
    for (std::string line; std::getline(in, line);) {
      std::vector<std::string> fields;
      std::istringstream cells(line);
      for (std::string cell; std::getline(cells, cell, ',');) fields.push_back(cell);
      if (column < 0) column = std::find(fields.begin(), fields.end(), "wall_time_s") - fields.begin();
      if (std::size_t(column) < fields.size()) fields.erase(fields.begin() + column);
      for (const auto& f : fields) out += f + ',';
      out += '\n';
    }
    return out;
  };

  const fs::path csv = dir / "r.csv", err = dir / "sweep.err";
  const std::string set = "sheets[*].stiffness=1,2,3,4,5,6";
  const int status = interrupted({DRAPE_BIN, "sweep", scene.string(), "--set", set, "--out", csv.string(), "--threads", "1"},
                                 dir / "r.csv.journal", err);
  ASSERT_TRUE(WIFSIGNALED(status) && WTERMSIG(status) == SIGINT) << "ended before it could be interrupted: " << slurp(err);
  EXPECT_NE(slurp(err).find("drape sweep: interrupted; the runs already finished are kept in " + csv.string() +
                            ".journal: the same command again runs only the others"),
            std::string::npos)
      << slurp(err);
  EXPECT_FALSE(fs::exists(csv));
  const std::string args = "sweep " + scene.string() + " --set " + set + " --threads 1 --out ";
  const Result again = drape(args + csv.string());
  ASSERT_EQ(again.code, 0) << again.err;
  EXPECT_NE(again.err.find("already done by an earlier attempt"), std::string::npos) << again.err;
  ASSERT_EQ(drape(args + (dir / "fresh.csv").string()).code, 0);
  EXPECT_EQ(without_wall_times(slurp(csv)), without_wall_times(slurp(dir / "fresh.csv")));

  const fs::path a = write("a.json", slurp(scene)), b = write("b.json", slurp(scene)), c = write("c.json", slurp(scene)),
                 d = write("d.json", slurp(scene));
  const fs::path out = dir / "o", batch_err = dir / "batch.err";
  const int batch_status = interrupted({DRAPE_BIN, "batch", a.string(), b.string(), c.string(), d.string(), "--threads", "1",
                                        "--format", "vtk", "--out", out.string()},
                                       out / "batch.csv.journal", batch_err);
  ASSERT_TRUE(WIFSIGNALED(batch_status) && WTERMSIG(batch_status) == SIGINT) << slurp(batch_err);
  EXPECT_NE(slurp(batch_err).find("drape batch: interrupted; the scenes already finished are kept in " +
                                  (out / "batch.csv.journal").string()),
            std::string::npos)
      << slurp(batch_err);
  const Result finished = drape("batch " + a.string() + " " + b.string() + " " + c.string() + " " + d.string() +
                                " --threads 1 --format vtk --out " + out.string());
  ASSERT_EQ(finished.code, 0) << finished.err;
  EXPECT_NE(finished.err.find("already done by an earlier attempt"), std::string::npos) << finished.err;
  EXPECT_EQ(occurrences(slurp(out / "batch.csv"), ",ok,"), 4u) << slurp(out / "batch.csv");
}

// Sheets in contact walk their kept contact sets between searches: the checkpoint holds
// those sets, so a run resumed at frame 7 (70 substeps, between two full searches) writes
// the frames of the uninterrupted run, byte for byte.
TEST_F(Cli, ResumedRunWithSheetsInContactWritesTheSameFrames) {
  const fs::path scene = write("stack.json", R"({"frames": 10, "dt": 0.001, "substeps": 10,
    "sheets": [
      {"name": "a", "grid": [12, 12], "size": [0.3, 0.3], "center": [0, 0, 0], "stiffness": 50, "mass": 1, "damping": 0.05, "pins": "corners"},
      {"name": "b", "grid": [12, 12], "size": [0.3, 0.3], "center": [0.01, 0, 0.008], "stiffness": 50, "mass": 1, "damping": 0.05, "pins": "corners"},
      {"name": "c", "grid": [12, 12], "size": [0.3, 0.3], "center": [0.02, 0, 0.016], "stiffness": 50, "mass": 1, "damping": 0.05, "pins": "corners"}]})");
  expect_resume_writes_the_same_frames(*this, scene, 7, 10);
}

// Constraints and a moving obstacle take their targets and pose from the time of each
// substep: a run resumed at a checkpoint continues them exactly (issue 14).
TEST_F(Cli, ResumedRunWithConstraintsAndAMovingObstacleWritesTheSameFrames) {
  const fs::path scene = write("c.json", R"({"frames": 10, "dt": 0.0005, "substeps": 20,
    "sheets": [{"name": "a", "grid": [8, 8], "size": [0.4, 0.4], "stiffness": 100, "mass": 0.1},
               {"name": "b", "grid": [8, 8], "size": [0.4, 0.4], "center": [0.42, 0, 0], "stiffness": 100, "mass": 0.1}],
    "obstacles": [{"type": "sphere", "center": [0, 0, -0.3], "radius": 0.1, "c": 0.01, "xi": 0.01,
                   "motion": {"keyframes": [{"time": 0}, {"time": 0.1, "translation": [0.2, 0, 0.1]}]}}],
    "constraints": [
      {"type": "point_to_point", "sheet": "a", "points": {"column": 8}, "other_sheet": "b",
       "other_points": {"column": 0}, "stiffness": 500, "rest_length": 0.02},
      {"type": "path", "sheet": "a", "points": [0], "stiffness": 500,
       "motion": {"circle": {"center": [-0.3, -0.2, 0], "start": [-0.2, -0.2, 0], "period": 0.05}}},
      {"type": "frame", "sheet": "b", "points": "corners", "stiffness": 500, "obstacle": 0},
      {"type": "rail", "sheet": "a", "points": {"row": 8}, "stiffness": 500, "rail": [[-1, 0.2, 0], [1, 0.2, 0]]}]})");
  expect_resume_writes_the_same_frames(*this, scene, 5, 10);
}

TEST_F(Cli, DamagedForeignOrMissingCheckpointIsRefusedWithExitFiveAndNothingWritten) {
  const fs::path scene = write("s.json", scene_text());
  const fs::path out = dir / "out";
  ASSERT_EQ(drape("run " + scene.string() + " --out " + out.string() + " --frames 10 --checkpoint-every 5").code, 0);
  for (int f = 6; f <= 10; ++f)
    for (const char* ext : {".obj", ".vtu"}) {
      char name[32];
      std::snprintf(name, sizeof name, "frame_%05d%s", f, ext);
      fs::remove(out / name);
    }
  const fs::path ckp = out / "checkpoint.drape";
  const std::string good = slurp(ckp);
  ASSERT_GT(good.size(), 100u);

  auto put = [&](const std::string& bytes) { std::ofstream(ckp, std::ios::binary | std::ios::trunc) << bytes; };
  std::string flipped = good;
  flipped[good.size() / 2] = char(flipped[good.size() / 2] ^ 0x10);
  std::string other_version = good;
  other_version[8] = 4;  // u32 little-endian format version after the 8-byte magic
  const std::pair<std::string, std::string> cases[] = {
      {good.substr(0, good.size() / 2), "checksum mismatch"},  // truncated: the checksum read is other bytes
      {good.substr(0, 20), "truncated"},
      {flipped, "checksum mismatch"},
      {other_version, "format version 4"},
      {"not a checkpoint at all, just text", "not a drape checkpoint"},
  };
  for (const auto& [bytes, message] : cases) {
    put(bytes);
    const auto before = snapshot(out);
    const Result r = drape("run " + scene.string() + " --resume " + out.string());
    EXPECT_EQ(r.code, 5) << message;
    EXPECT_NE(r.err.find(message), std::string::npos) << r.err;
    EXPECT_NE(r.err.find(ckp.string()), std::string::npos) << r.err;
    EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;
    EXPECT_TRUE(snapshot(out) == before) << "a refused resume changed " << out << " (" << message << ")";
  }

  // the intact checkpoint, resumed with another scene (stiffer springs, same grid): refused
  put(good);
  const fs::path other = write("other.json", scene_text(121));
  const auto before = snapshot(out);
  const Result r = drape("run " + other.string() + " --resume " + out.string());
  EXPECT_EQ(r.code, 5);
  EXPECT_NE(r.err.find("another scene"), std::string::npos) << r.err;
  EXPECT_TRUE(snapshot(out) == before);

  fs::remove(ckp);
  const Result missing = drape("run " + scene.string() + " --resume " + out.string());
  EXPECT_EQ(missing.code, 5);
  EXPECT_NE(missing.err.find("no checkpoint"), std::string::npos) << missing.err;

  // and the intact one with its own scene resumes
  put(good);
  EXPECT_EQ(drape("run " + scene.string() + " --resume " + out.string() + " --frames 10").code, 0);
  EXPECT_TRUE(fs::exists(out / "frame_00010.obj"));
}

TEST_F(Cli, OutputPathThatIsAFileOrUnderAFileExitsFourAndKeepsTheFile) {
  const fs::path scene = write("s.json", scene_text());
  const fs::path file = write("taken", "precious");
  for (const fs::path& out : {file, file / "sub"}) {
    const Result r = drape("run " + scene.string() + " --frames 2 --out " + out.string());
    EXPECT_EQ(r.code, 4) << out;
    EXPECT_NE(r.err.find("cannot create the output folder " + out.string()), std::string::npos) << r.err;
    EXPECT_EQ(slurp(file), "precious");
  }
  const Result sweep = drape("sweep " + scene.string() + " --frames 1 --out " + (file / "r.csv").string());
  EXPECT_EQ(sweep.code, 4) << sweep.err;
  EXPECT_EQ(slurp(file), "precious");
}

// Disk full, simulated without privileges: the temporary name of frame 3 is a symbolic
// link to /dev/full, where every write fails with ENOSPC. (A full tmpfs behaves the same
// but needs mount rights; permission denied cannot be provoked as root, which CI runs as.)
TEST_F(Cli, DiskFullStopsTheRunWithExitFourAndKeepsEarlierFramesIntact) {
  if (!fs::exists("/dev/full")) GTEST_SKIP() << "no /dev/full on this system";
  const fs::path scene = write("s.json", scene_text());
  const fs::path full = dir / "full", out = dir / "out";
  ASSERT_EQ(drape("run " + scene.string() + " --frames 6 --out " + full.string()).code, 0);
  fs::create_directories(out);
  fs::create_symlink("/dev/full", out / "frame_00003.obj.tmp");
  const Result r = drape("run " + scene.string() + " --frames 6 --out " + out.string());
  EXPECT_EQ(r.code, 4) << r.err;
  EXPECT_NE(r.err.find("frame_00003.obj.tmp: No space left on device"), std::string::npos) << r.err;
  for (const char* name : {"frame_00000.obj", "frame_00001.obj", "frame_00002.obj", "frame_00002.vtu"})
    EXPECT_TRUE(slurp(out / name) == slurp(full / name)) << name << " was not kept intact";
  for (const char* name : {"frame_00003.obj", "frame_00003.obj.tmp", "frame_00003.vtu", "frame_00004.obj"})
    EXPECT_FALSE(fs::exists(fs::symlink_status(out / name))) << name;
}

}  // namespace
