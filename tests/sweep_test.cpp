// `drape sweep`: one CSV row per run in grid order, each row the outcome of exactly the run
// `drape run` makes with that value, unstable runs reported as such and never as NaN, a run
// that fails reported in its row without losing the others. `drape batch`: each scene's
// frames exactly those of `drape run`, a bad scene reported in its row.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include "cli_fixture.h"
#include "run.h"
#include "sweep.h"

namespace {

class Batch : public Cli {};

std::vector<std::vector<std::string>> read_csv(const fs::path& p) {
  std::vector<std::vector<std::string>> rows;
  std::istringstream in(Cli::slurp(p));
  std::string line;
  while (std::getline(in, line)) {
    std::vector<std::string> cells;
    std::string cell;
    std::istringstream s(line);
    while (std::getline(s, cell, ',')) cells.push_back(cell);
    if (!line.empty() && line.back() == ',') cells.push_back("");
    rows.push_back(cells);
  }
  return rows;
}

std::string sheet_scene(const std::string& extra = "") {
  return R"({"frames": 8, "dt": 0.001, "substeps": 25, )" + extra +
         R"("sheets": [{"grid": [8, 8], "size": [1, 1], "stiffness": 50, "mass": 0.2, "damping": 0.02,
           "anchors": [{"at": "corners", "stiffness": 300}]}]})";
}

// z of every vertex ("v x y z" lines) of an OBJ frame
std::vector<double> obj_z(const fs::path& p) {
  std::vector<double> z;
  std::istringstream in(Cli::slurp(p));
  std::string line;
  while (std::getline(in, line))
    if (line.rfind("v ", 0) == 0) {
      std::istringstream s(line.substr(2));
      std::string a, b, c;
      s >> a >> b >> c;
      z.push_back(std::strtod(c.c_str(), nullptr));
    }
  return z;
}

TEST(Sweep, SetValuesSplitAtTopLevelCommasOnly) {
  const auto p = drape::app::parse_sweep_parameter("gravity=[0,0,-9.81],[0,0,-1.62]");
  ASSERT_TRUE(p);
  EXPECT_EQ(p->path, "gravity");
  EXPECT_EQ(p->values, (std::vector<std::string>{"[0,0,-9.81]", "[0,0,-1.62]"}));
  const auto q = drape::app::parse_sweep_parameter("sheets[*].stiffness=10,100,1000");
  ASSERT_TRUE(q);
  EXPECT_EQ(q->values.size(), 3u);
  for (const char* bad : {"stiffness", "=1,2", "dt=", "dt=1,,2", "gravity=[0,0"})
    EXPECT_FALSE(drape::app::parse_sweep_parameter(bad)) << bad;
}

TEST_F(Cli, SweepWritesOneRowPerRunScenesThenFirstParameterSlowest) {
  const fs::path a = write("a.json", sheet_scene()), b = write("b.json", sheet_scene(R"("precision": "float32", )"));
  const fs::path csv = dir / "sub" / "r.csv";
  const Result r = drape("sweep " + a.string() + " " + b.string() +
                         " --set sheets[*].stiffness=20,40,80 --set integrator=semi_implicit_euler,forward_euler"
                         " --threads 2 --out " + csv.string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto rows = read_csv(csv);
  ASSERT_EQ(rows.size(), 1u + 2 * 3 * 2);
  EXPECT_EQ(rows[0], (std::vector<std::string>{"scene", "sheets[*].stiffness", "integrator", "stable", "frames",
                                               "max_sag_m", "max_strain", "total_energy_J", "wall_time_s",
                                               "error"}));
  std::size_t k = 1;
  for (const fs::path& scene : {a, b})
    for (const char* stiffness : {"20", "40", "80"})
      for (const char* integrator : {"semi_implicit_euler", "forward_euler"}) {
        ASSERT_EQ(rows[k].size(), 10u) << k;
        EXPECT_EQ(rows[k][9], "") << "a run that ran has no error";
        EXPECT_EQ(rows[k][0], scene.string());
        EXPECT_EQ(rows[k][1], stiffness);
        EXPECT_EQ(rows[k][2], integrator);
        ++k;
      }
  for (const fs::path& e : fs::directory_iterator(csv.parent_path())) EXPECT_NE(e.extension(), ".tmp");
}

// The row of stiffness 80 is the run of a scene file that says 80: the sag in the CSV equals
// the one recomputed from that run's first and last exported frames, bit for bit.
TEST_F(Cli, SweepRowEqualsTheSingleRunWithThatValue) {
  const fs::path scene = write("s.json", sheet_scene());
  const fs::path csv = dir / "r.csv";
  ASSERT_EQ(drape("sweep " + scene.string() + " --set sheets[*].stiffness=30,80 --out " + csv.string()).code, 0);
  const auto rows = read_csv(csv);
  ASSERT_EQ(rows.size(), 3u);
  ASSERT_EQ(rows[2][1], "80");
  ASSERT_EQ(rows[2][2], "true");

  std::string text = sheet_scene();
  text.replace(text.find("\"stiffness\": 50"), 15, "\"stiffness\": 80");
  const fs::path single = write("k80.json", text);
  const Result r = drape("run " + single.string() + " --format obj --threads 2 --out " + (dir / "out").string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto z0 = obj_z(dir / "out" / "frame_00000.obj"), z = obj_z(dir / "out" / "frame_00008.obj");
  ASSERT_EQ(z0.size(), 81u);
  ASSERT_EQ(z.size(), 81u);
  double sag = -1e300;
  for (std::size_t p = 0; p < z.size(); ++p) sag = std::max(sag, z0[p] - z[p]);
  EXPECT_GT(sag, 0.0);
  EXPECT_EQ(std::strtod(rows[2][4].c_str(), nullptr), sag);  // scene, stiffness, stable, frames, max_sag_m
  EXPECT_NE(rows[1][4], rows[2][4]) << "stiffness 30 and 80 gave the same sag: the override did nothing";
}

// Forward Euler without enough damping grows every oscillation (its amplification factor is
// above 1 for an undamped spring); a dt far above 2/ω_max blows up semi-implicit Euler too.
// Both are rows with stable = false and empty metrics; the sound run keeps its numbers.
// A run the engine's guard halts is unstable in the sweep too, with the frames before the
// halt, even where the state stays within the sweep's own energy bound: forward Euler gains
// energy slowly, and a guard limit of 1.05 halts it long before that bound. The reference is
// the scene's world stepped frame by frame until the guard fails.
TEST(Sweep, ARunTheGuardHaltsIsUnstableWithTheFramesBeforeTheHalt) {
  const drape::app::Scene scene = drape::app::parse_scene(
      sheet_scene(R"("integrator": "forward_euler", "guard_energy_growth": 1.05, )"), "s.json");
  std::vector<drape::SheetId> ids;
  drape::World world = drape::app::build_world<double>(scene, 1, ids);
  int before_halt = 0;
  while (before_halt < scene.frames && world.step(scene.substeps).ok()) ++before_halt;
  ASSERT_LT(before_halt, scene.frames) << "the guard must halt this run";
  const drape::app::SweepOutcome outcome = drape::app::simulate(scene);
  EXPECT_FALSE(outcome.stable);
  EXPECT_EQ(outcome.frames_run, before_halt);
}

TEST_F(Cli, UnstableCombinationIsReportedUnstableNotNaN) {
  const fs::path scene = write("s.json", sheet_scene());
  const fs::path csv = dir / "r.csv";
  const Result r = drape("sweep " + scene.string() +
                         " --set dt=0.001,0.05 --set integrator=semi_implicit_euler,forward_euler --frames 40 --out " +
                         csv.string());
  ASSERT_EQ(r.code, 0) << r.err;
  const auto rows = read_csv(csv);
  ASSERT_EQ(rows.size(), 5u);
  EXPECT_EQ(rows[1][3], "true");   // dt 0.001, semi-implicit: below its stable step
  EXPECT_EQ(rows[2][3], "false");  // dt 0.001, forward Euler, damping 0.02 N·s/m: too little
  EXPECT_EQ(rows[3][3], "false");  // dt 0.05: far above 2/ω_max
  EXPECT_EQ(rows[4][3], "false");
  for (std::size_t k = 2; k <= 4; ++k) {
    EXPECT_LT(std::stoi(rows[k][4]), 40) << "frames completed before going unstable";
    for (std::size_t c = 5; c <= 7; ++c) EXPECT_EQ(rows[k][c], "") << k;
  }
  EXPECT_EQ(std::stoi(rows[1][4]), 40);
  // every number cell is empty or a finite number, written in full
  for (std::size_t k = 1; k < rows.size(); ++k)
    for (std::size_t c = 5; c < rows[k].size(); ++c) {
      if (rows[k][c].empty()) continue;
      char* end = nullptr;
      const double v = std::strtod(rows[k][c].c_str(), &end);
      EXPECT_TRUE(std::isfinite(v) && *end == '\0') << "row " << k << " column " << c << ": " << rows[k][c];
    }
}

TEST_F(Cli, SweepWithABadValueRunsNothingAndWritesNoCsv) {
  const fs::path scene = write("s.json", sheet_scene());
  const fs::path csv = dir / "r.csv";
  const Result bad_value = drape("sweep " + scene.string() + " --set sheets[*].stiffness=10,-5 --out " + csv.string());
  EXPECT_EQ(bad_value.code, 3);
  EXPECT_NE(bad_value.err.find("sheets[0].stiffness: must be positive"), std::string::npos) << bad_value.err;
  const Result bad_path = drape("sweep " + scene.string() + " --set sheets[2].damping=1 --out " + csv.string());
  EXPECT_EQ(bad_path.code, 3);
  EXPECT_NE(bad_path.err.find("--set sheets[2].damping: index 2 is past the end"), std::string::npos) << bad_path.err;
  const Result bad_syntax = drape("sweep " + scene.string() + " --set stiffness --out " + csv.string());
  EXPECT_EQ(bad_syntax.code, 2);
  // a field set twice ran one of its values under two columns
  const Result twice = drape("sweep " + scene.string() + " --set dt=0.001 --set dt=0.002 --out " + csv.string());
  EXPECT_EQ(twice.code, 2);
  EXPECT_NE(twice.err.find("--set dt is given twice"), std::string::npos) << twice.err;
  EXPECT_FALSE(fs::exists(csv));
}

// A run the engine refuses at run time (here a definition made invalid after planning, as a
// scene would that passed the loader but not the engine) becomes its own row's error; the
// runs before and after it keep exactly the results they have when run alone.
TEST_F(Cli, SweepRunThatFailsIsReportedInItsRowAndTheOthersKeepTheirResults) {
  drape::app::SweepOptions options;
  options.scenes = {write("s.json", sheet_scene())};
  options.parameters = {*drape::app::parse_sweep_parameter("sheets[*].stiffness=20,40,80")};
  auto cases = drape::app::plan_sweep(options);
  ASSERT_EQ(cases.size(), 3u);
  cases[1].scene.sheets[0].stiffness = -1;
  const auto outcomes = drape::app::run_sweep_cases(cases, 4, 2);
  EXPECT_FALSE(outcomes[1].stable);
  EXPECT_NE(outcomes[1].error.find("stiffness must be positive"), std::string::npos) << outcomes[1].error;
  for (std::size_t k : {0u, 2u}) {
    const auto alone = drape::app::simulate(cases[k].scene, 4);
    EXPECT_TRUE(outcomes[k].stable && outcomes[k].error.empty()) << k;
    EXPECT_EQ(outcomes[k].max_sag, alone.max_sag) << k;
    EXPECT_EQ(outcomes[k].total_energy, alone.total_energy) << k;
  }
  std::ostringstream csv;
  drape::app::write_sweep_csv(csv, options, cases, outcomes);
  const fs::path file = write("r.csv", csv.str());
  const auto rows = read_csv(file);
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[2][2], "false");
  EXPECT_EQ(rows[2][3], "0");
  ASSERT_EQ(rows[2].size(), 9u);
  EXPECT_NE(rows[2][8].find("stiffness must be positive"), std::string::npos);
  EXPECT_EQ(rows[1][8], "");
}

// Every finished run is kept in FILE.journal as it finishes: a sweep whose CSV cannot be
// written (here FILE is a folder) keeps them, and the same command then writes the CSV of an
// uninterrupted sweep without running them again; a journal of other runs is not used.
TEST_F(Cli, SweepKeepsFinishedRunsForTheNextAttempt) {
  const fs::path scene = write("s.json", sheet_scene());
  const std::string args = "sweep " + scene.string() + " --set sheets[*].stiffness=20,40,80 --set dt=0.001,0.0005 --out ";
  const fs::path csv = dir / "r.csv", journal = dir / "r.csv.journal";
  fs::create_directories(csv);  // the CSV cannot be renamed into place
  const Result failed = drape(args + csv.string());
  EXPECT_EQ(failed.code, 4) << failed.err;
  EXPECT_NE(failed.err.find("r.csv.journal"), std::string::npos) << failed.err;
  ASSERT_TRUE(fs::is_directory(journal));
  std::size_t lines = 0;
  for (const auto& e : fs::directory_iterator(journal)) {
    std::istringstream in(Cli::slurp(e.path()));
    for (std::string line; std::getline(in, line);) ++lines;
  }
  EXPECT_EQ(lines, 6u);

  fs::remove(csv);
  const Result again = drape(args + csv.string());
  ASSERT_EQ(again.code, 0) << again.err;
  EXPECT_NE(again.err.find("6 run(s) already done"), std::string::npos) << again.err;
  EXPECT_FALSE(fs::exists(journal)) << "removed once the CSV is written";
  const Result fresh = drape(args + (dir / "fresh.csv").string());
  ASSERT_EQ(fresh.code, 0);
  auto rows = read_csv(csv), expected = read_csv(dir / "fresh.csv");
  ASSERT_EQ(rows.size(), 7u);
  for (auto* table : {&rows, &expected})
    for (auto& row : *table) row.at(8) = "";  // wall_time_s
  EXPECT_EQ(rows, expected);

  // a journal left by other runs (another --set) is not taken for these
  fs::create_directories(csv.string() + "x");
  EXPECT_EQ(drape("sweep " + scene.string() + " --set sheets[*].stiffness=20,40 --out " + csv.string() + "x").code, 4);
  fs::remove(csv.string() + "x");
  fs::rename(csv.string() + "x.journal", journal);
  const Result other = drape(args + (dir / "r.csv").string());
  ASSERT_EQ(other.code, 0) << other.err;
  EXPECT_EQ(other.err.find("already done"), std::string::npos) << other.err;
}

TEST_F(Batch, WritesEachSceneExactlyAsDrapeRunDoes) {
  const fs::path a = write("a.json", sheet_scene());
  const fs::path b = write("b.json", sheet_scene(R"("precision": "float32", )"));
  const Result r = drape("batch " + a.string() + " " + b.string() +
                         " --frames 4 --format obj,vtk,glb --threads 2 --out " + (dir / "batch").string());
  ASSERT_EQ(r.code, 0) << r.err;
  for (const char* name : {"a", "b"}) {
    const fs::path single = dir / (std::string("single_") + name);
    ASSERT_EQ(drape("run " + (dir / (std::string(name) + ".json")).string() +
                    " --frames 4 --format obj,vtk,glb --out " + single.string()).code,
              0);
    std::size_t files = 0;
    for (const auto& e : fs::directory_iterator(single)) {
      const fs::path mine = dir / "batch" / name / e.path().filename();
      ASSERT_TRUE(fs::exists(mine)) << mine;
      EXPECT_EQ(Cli::slurp(mine), Cli::slurp(e.path())) << mine;
      ++files;
    }
    EXPECT_EQ(files, 5u * 2 + 3) << "frames 0-4 as obj and vtu, frames.pvd, run.glb, scene.json";
  }
  const auto rows = read_csv(dir / "batch" / "batch.csv");
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0], (std::vector<std::string>{"scene", "output", "status", "frames", "wall_time_s", "message"}));
  EXPECT_EQ(rows[1][0], a.string());
  EXPECT_EQ(rows[1][1], "a");
  EXPECT_EQ(rows[1][2], "ok");
  EXPECT_EQ(rows[1][3], "4");
  EXPECT_EQ(rows[2][2], "ok");
}

// One unreadable scene and one that blows up: each is its row's status and message, the exit
// code says some scenes did not finish, and the good scene's frames are all there.
TEST_F(Batch, ReportsEachFailedSceneAndRunsTheRest) {
  const fs::path good = write("good.json", sheet_scene());
  const fs::path bad = write("bad.json", R"({"frames": 4, "sheets": [{"grid": [4, 4], "size": [1, 1], "stiffness": -5}]})");
  std::string text = sheet_scene();
  text.replace(text.find("\"dt\": 0.001"), 11, "\"dt\": 0.050");
  const fs::path wild = write("wild.json", text);
  const Result r = drape("batch " + bad.string() + " " + good.string() + " " + wild.string() + " --frames 40 --out " +
                         (dir / "o").string());
  EXPECT_EQ(r.code, 6) << r.err;
  EXPECT_NE(r.err.find("bad.json: bad_scene"), std::string::npos) << r.err;
  const auto rows = read_csv(dir / "o" / "batch.csv");
  ASSERT_EQ(rows.size(), 4u);
  EXPECT_EQ(rows[1][2], "bad_scene");
  EXPECT_NE(rows[1][5].find("sheets[0].stiffness: must be positive"), std::string::npos) << rows[1][5];
  EXPECT_EQ(rows[2][2], "ok");
  EXPECT_TRUE(fs::exists(dir / "o" / "good" / "frame_00040.obj"));
  EXPECT_EQ(rows[3][2], "unstable");
  EXPECT_NE(rows[3][5].find("unstable"), std::string::npos) << rows[3][5];
  EXPECT_FALSE(fs::exists(dir / "o" / "bad"));
}

// A batch whose batch.csv cannot be written (here it is a folder) keeps its finished scenes in
// batch.csv.journal; the same command again runs none of them (their frames stay untouched)
// and writes the table.
TEST_F(Batch, KeepsFinishedScenesForTheNextAttempt) {
  const fs::path a = write("a.json", sheet_scene()), b = write("b.json", sheet_scene(R"("integrator": "rk4", )"));
  const fs::path out = dir / "o";
  fs::create_directories(out / "batch.csv");
  const std::string args = "batch " + a.string() + " " + b.string() + " --frames 3 --out " + out.string();
  const Result failed = drape(args);
  EXPECT_EQ(failed.code, 4) << failed.err;
  EXPECT_NE(failed.err.find("batch.csv.journal"), std::string::npos) << failed.err;
  ASSERT_TRUE(fs::exists(out / "b" / "frame_00003.obj"));
  const auto written = fs::last_write_time(out / "b" / "frame_00003.obj");
  std::error_code ec;
  fs::last_write_time(out / "b" / "frame_00003.obj", written - std::chrono::hours(1), ec);  // any rewrite shows

  fs::remove(out / "batch.csv");
  const Result again = drape(args);
  ASSERT_EQ(again.code, 0) << again.err;
  EXPECT_NE(again.err.find("2 scene(s) already done"), std::string::npos) << again.err;
  EXPECT_EQ(fs::last_write_time(out / "b" / "frame_00003.obj"), written - std::chrono::hours(1)) << "b was run again";
  const auto rows = read_csv(out / "batch.csv");
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[1][2], "ok");
  EXPECT_EQ(rows[2][2], "ok");
  EXPECT_FALSE(fs::exists(out / "batch.csv.journal"));
}

TEST_F(Batch, RefusesTwoScenesThatWouldShareAFolder) {
  fs::create_directories(dir / "x");
  fs::create_directories(dir / "y");
  const fs::path a = write("x/s.json", sheet_scene()), b = write("y/s.json", sheet_scene());
  const Result r = drape("batch " + a.string() + " " + b.string() + " --out " + (dir / "o").string());
  EXPECT_EQ(r.code, 2);
  EXPECT_NE(r.err.find("two scenes are named s"), std::string::npos) << r.err;
  EXPECT_FALSE(fs::exists(dir / "o"));
}

#ifndef DRAPE_HAVE_MPI
// Built without MPI, a drape started by mpirun would run every case on every rank: it says so.
TEST_F(Cli, SweepWithoutMpiStartedAsManyRanksRefuses) {
  const fs::path scene = write("s.json", sheet_scene());
  const std::string cmd = "OMPI_COMM_WORLD_SIZE=2 " + std::string(DRAPE_BIN) + " sweep " + scene.string() + " --out " +
                          (dir / "m.csv").string() + " 2> " + (dir / "err").string();
  const int status = std::system(cmd.c_str());
  EXPECT_EQ(WEXITSTATUS(status), 2);
  EXPECT_NE(Cli::slurp(dir / "err").find("built without MPI"), std::string::npos);
  EXPECT_FALSE(fs::exists(dir / "m.csv"));
}
#endif

}  // namespace
