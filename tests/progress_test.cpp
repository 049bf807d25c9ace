// Progress of long commands (apps/common/progress.h): the rate and time left against hand
// arithmetic, the plain form a log gets, and `drape run` / `drape sweep` writing it to a pipe.
#include <gtest/gtest.h>

#include <progress.h>

#include <algorithm>
#include <regex>
#include <sstream>

#include "cli_fixture.h"

namespace {

using drape::app::Progress;
using drape::app::progress_text;

TEST(Progress, TimeLeftIsTheRemainingItemsAtTheMeasuredRate) {
  // 30 frames in 15 s: 2 frames/s; 270 left take 135 s.
  EXPECT_EQ(progress_text("frame", 30, 300, 0, 15.0, false), "frame 30/300 (10%), 2.00 frames/s, 2 min 15 s left");
  // A resumed run counts only what it did itself: 50 frames (100 → 150) in 10 s, 150 left.
  EXPECT_EQ(progress_text("frame", 150, 300, 100, 10.0, false), "frame 150/300 (50%), 5.00 frames/s, 30 s left");
  // 7200 runs left at 1 run/s: two hours.
  EXPECT_EQ(progress_text("run", 1, 7201, 0, 1.0, false), "run 1/7201 (0%), 1.00 runs/s, 2 h 00 min left");
  EXPECT_EQ(progress_text("frame", 0, 10, 0, 0.0, false), "frame 0/10 (0%), ? s left");
}

TEST(Progress, TheBarIsFilledInProportion) {
  const std::string line = progress_text("frame", 15, 30, 0, 3.0, true);
  EXPECT_EQ(line.substr(0, 33), "[" + std::string(15, '#') + std::string(15, '.') + "] ");
}

TEST(Progress, APipeGetsAPlainLineEveryTenthAndTheLast) {
  std::ostringstream out;
  Progress p(out, "frame", 95, false);
  for (int k = 1; k <= 95; ++k) p.update(k, "t = 1 s");
  p.finish();
  const std::string text = out.str();
  EXPECT_EQ(text.find('\r'), std::string::npos);
  EXPECT_EQ(text.find('['), std::string::npos);
  // a line at 9, 18, …, 90 (95/10 = 9 frames apart) and at 95
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 11) << text;
  EXPECT_NE(text.find("drape: frame 95/95 (100%), "), std::string::npos) << text;
  EXPECT_NE(text.find(" left, t = 1 s\n"), std::string::npos) << text;
}

// A long run's log gets a line at least every `every` while items get done, not only at its
// tenths (a run of 10⁶ frames went quiet for its first 10⁵).
TEST(Progress, APipeGetsALineWhenItsIntervalPassedBetweenTenths) {
  std::ostringstream quiet, timed;
  Progress slow(quiet, "frame", 1000, false);  // every half minute: these updates come sooner
  Progress fast(timed, "frame", 1000, false, 0, std::chrono::steady_clock::duration::zero());
  for (int k = 1; k <= 5; ++k) {
    slow.update(k);
    fast.update(k);
    fast.update(k);  // nothing new done: no line
  }
  EXPECT_EQ(quiet.str(), "");
  const std::string text = timed.str();
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 5) << text;
  EXPECT_NE(text.find("drape: frame 5/1000 (0%), "), std::string::npos) << text;
}

TEST(Progress, ATerminalGetsOneRedrawnLineEndedByFinish) {
  std::ostringstream out;
  Progress p(out, "frame", 4, true);
  for (int k = 1; k <= 4; ++k) p.update(k);
  p.finish();
  const std::string text = out.str();
  EXPECT_EQ(text.front(), '\r');
  EXPECT_EQ(std::count(text.begin(), text.end(), '\n'), 1);
  EXPECT_EQ(text.back(), '\n');
  EXPECT_NE(text.find("[" + std::string(30, '#') + "] frame 4/4 (100%)"), std::string::npos) << text;
}

const std::string small_scene = R"({"frames": 20, "dt": 0.001, "fps": 100,
  "sheets": [{"grid": [4, 4], "size": [1, 1], "stiffness": 50, "pins": "corners"}]})";

TEST_F(Cli, RunAndSweepPrintPlainProgressLinesToAPipe) {
  const fs::path scene = write("s.json", small_scene);
  const Result r = drape("run " + scene.string() + " --out " + (dir / "out").string());
  ASSERT_EQ(r.code, 0) << r.err;
  const std::regex line(R"(drape: frame (\d+)/20 \(\d+%\), [0-9.]+ frames/s, [0-9. a-z]+ left, t = [0-9.e-]+ s)");
  int lines = 0;
  std::istringstream in(r.err);
  for (std::string l; std::getline(in, l);) lines += std::regex_match(l, line);
  EXPECT_EQ(lines, 10) << r.err;  // every second frame of 20
  EXPECT_EQ(r.err.find('\r'), std::string::npos);

  const Result s = drape("sweep " + scene.string() + " --set sheets[*].stiffness=10,20,30 --out " + (dir / "s.csv").string());
  ASSERT_EQ(s.code, 0) << s.err;
  EXPECT_NE(s.err.find("drape: run 3/3 (100%), "), std::string::npos) << s.err;
}

}  // namespace
