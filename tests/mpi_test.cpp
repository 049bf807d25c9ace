// `mpirun -np 2 drape sweep|batch` against the same command in one process: the same CSV
// (rows, order, every bit of every number; only the wall times differ) and the same frames
// byte for byte. Runs two ranks on this machine (loopback), as CI can.
#include <algorithm>
#include <string>
#include <vector>

#include "cli_fixture.h"

namespace {

class Mpi : public Cli {};

// "mpirun -np 2" with what a CI container needs: OpenMPI refuses root without
// --allow-run-as-root, and more ranks than cores without --oversubscribe.
std::string mpirun(int ranks) {
  return std::string(DRAPE_MPIEXEC) + " -np " + std::to_string(ranks) + " --oversubscribe --allow-run-as-root";
}

std::vector<std::string> lines(const std::string& text) {
  std::vector<std::string> out;
  std::istringstream in(text);
  for (std::string line; std::getline(in, line);) out.push_back(line);
  return out;
}

// The CSV with the named column blanked (the one thing that may differ: time measured).
std::vector<std::string> without_column(const std::string& csv, const std::string& column) {
  auto rows = lines(csv);
  if (rows.empty()) return rows;
  std::vector<std::string> header;
  std::istringstream h(rows[0]);
  for (std::string c; std::getline(h, c, ',');) header.push_back(c);
  const auto at = std::size_t(std::find(header.begin(), header.end(), column) - header.begin());
  EXPECT_LT(at, header.size()) << column;
  for (std::size_t r = 1; r < rows.size(); ++r) {
    std::vector<std::string> cells;
    std::istringstream s(rows[r]);
    for (std::string c; std::getline(s, c, ',');) cells.push_back(c);
    if (!rows[r].empty() && rows[r].back() == ',') cells.push_back("");
    if (at < cells.size()) cells[at] = "*";
    std::string joined;
    for (std::size_t c = 0; c < cells.size(); ++c) joined += (c ? "," : "") + cells[c];
    rows[r] = joined;
  }
  return rows;
}

std::string scene_text(const std::string& extra = "") {
  return R"({"frames": 6, "dt": 0.001, "substeps": 20, )" + extra +
         R"("sheets": [{"grid": [8, 10], "size": [1, 1.2], "stiffness": 50, "mass": 0.2, "damping": 0.02,
           "anchors": [{"at": "corners", "stiffness": 300}]},
           {"grid": [5, 5], "size": [0.5, 0.5], "center": [0, 0, 0.3], "mass": 0.1, "stiffness": 20}]})";
}

// 2 scenes × 3 stiffnesses × 2 integrators = 12 runs, forward Euler ones unstable, so both
// kinds of row travel between ranks; and 5 runs, which 2 ranks do not share evenly.
TEST_F(Mpi, TwoRanksWriteTheCsvOfOneProcess) {
  const fs::path a = write("a.json", scene_text()), b = write("b.json", scene_text(R"("precision": "float32", )"));
  for (const std::string& sets : {std::string(" --set sheets[*].stiffness=20,40,80 --set integrator=semi_implicit_euler,"
                                             "forward_euler"),
                                 std::string(" --set dt=0.001,0.0011,0.0012,0.0013,0.0014")}) {
    const std::string args = "sweep " + a.string() + " " + b.string() + sets + " --threads 1 --out ";
    const Result one = drape(args + (dir / "one.csv").string());
    ASSERT_EQ(one.code, 0) << one.err;
    const std::string cmd = mpirun(2) + " " + DRAPE_BIN + " " + args + (dir / "two.csv").string() + " > " +
                            (dir / "out").string() + " 2> " + (dir / "err").string();
    const int status = std::system(cmd.c_str());
    ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << Cli::slurp(dir / "err");
    EXPECT_NE(Cli::slurp(dir / "err").find("on 2 MPI ranks"), std::string::npos) << Cli::slurp(dir / "err");
    // progress counts rank 0's runs, and says so (its "run 2/2" of a sweep of 3 read as all)
    EXPECT_NE(Cli::slurp(dir / "err").find("rank 0's share of the "), std::string::npos) << Cli::slurp(dir / "err");
    EXPECT_EQ(one.err.find("rank 0's share"), std::string::npos) << one.err;
    const auto serial = without_column(Cli::slurp(dir / "one.csv"), "wall_time_s");
    const auto ranks = without_column(Cli::slurp(dir / "two.csv"), "wall_time_s");
    EXPECT_GE(serial.size(), 6u);
    EXPECT_EQ(serial, ranks);
    fs::remove(dir / "one.csv");
    fs::remove(dir / "two.csv");
  }
}

TEST_F(Mpi, TwoRanksWriteTheBatchOfOneProcess) {
  const std::string scenes = write("a.json", scene_text()).string() + " " +
                             write("b.json", scene_text(R"("precision": "float32", )")).string() + " " +
                             write("c.json", scene_text(R"("integrator": "rk4", )")).string();
  const Result one = drape("batch " + scenes + " --format obj,vtk --threads 1 --out " + (dir / "one").string());
  ASSERT_EQ(one.code, 0) << one.err;
  const std::string cmd = mpirun(2) + " " + DRAPE_BIN + " batch " + scenes + " --format obj,vtk --out " +
                          (dir / "two").string() + " > " + (dir / "out").string() + " 2> " + (dir / "err").string();
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 0) << Cli::slurp(dir / "err");
  std::size_t files = 0;
  for (const auto& e : fs::recursive_directory_iterator(dir / "one")) {
    if (!e.is_regular_file() || e.path().filename() == "batch.csv") continue;
    const fs::path theirs = dir / "two" / fs::relative(e.path(), dir / "one");
    ASSERT_TRUE(fs::exists(theirs)) << theirs;
    EXPECT_EQ(Cli::slurp(theirs), Cli::slurp(e.path())) << theirs;
    ++files;
  }
  EXPECT_EQ(files, 3u * (7 * 2 + 2));
  EXPECT_EQ(without_column(Cli::slurp(dir / "one" / "batch.csv"), "wall_time_s"),
            without_column(Cli::slurp(dir / "two" / "batch.csv"), "wall_time_s"));
}

// Rank 1 starts in a folder without the scene (as on a node that does not share the file
// system): every rank stops with exit code 3 instead of waiting for it, rank 1 says why, and
// no CSV is written.
TEST_F(Mpi, ARankThatCannotReadTheSceneStopsEveryRank) {
  fs::create_directories(dir / "with");
  fs::create_directories(dir / "without");
  write("with/s.json", scene_text());
  const std::string args = std::string(" ") + DRAPE_BIN + " sweep s.json --set dt=0.001,0.0012 --out " +
                           (dir / "r.csv").string();
  const std::string cmd = "timeout 120 " + std::string(DRAPE_MPIEXEC) + " --oversubscribe --allow-run-as-root -np 1 -wdir " +
                          (dir / "with").string() + args + " : -np 1 -wdir " + (dir / "without").string() + args +
                          " > " + (dir / "out").string() + " 2> " + (dir / "err").string();
  const int status = std::system(cmd.c_str());
  ASSERT_TRUE(WIFEXITED(status));
  EXPECT_NE(WEXITSTATUS(status), 124) << "the ranks waited for each other: " << Cli::slurp(dir / "err");
  EXPECT_NE(WEXITSTATUS(status), 0);
  EXPECT_NE(Cli::slurp(dir / "err").find("rank 1: s.json"), std::string::npos) << Cli::slurp(dir / "err");
  EXPECT_FALSE(fs::exists(dir / "r.csv"));
}

}  // namespace
