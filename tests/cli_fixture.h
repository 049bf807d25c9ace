// Runs the built drape program as a user does, in a fresh temporary folder per test.
// Shared by the CLI tests (cli_test.cpp, resume_test.cpp, sweep_test.cpp).
#pragma once

#include <gtest/gtest.h>
#include <sys/wait.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

namespace fs = std::filesystem;

struct Result {
  int code;
  std::string out, err;
};

class Cli : public ::testing::Test {
 public:
  fs::path dir;
  void SetUp() override {
    dir = fs::temp_directory_path() /
          ("drape_cli_" + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name()) + "_" +
           std::to_string(::getpid()));
    fs::remove_all(dir);
    fs::create_directories(dir);
  }
  void TearDown() override { fs::remove_all(dir); }

  fs::path write(const std::string& name, const std::string& text) {
    std::ofstream(dir / name) << text;
    return dir / name;
  }
  static std::string slurp(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }
  // How many times `needle` occurs in `text` (overlapping occurrences too).
  static std::size_t occurrences(const std::string& text, const std::string& needle) {
    std::size_t count = 0;
    for (std::size_t at = text.find(needle); at != std::string::npos; at = text.find(needle, at + 1)) ++count;
    return count;
  }
  // `shell` runs first in the same shell (e.g. a ulimit the program then runs under)
  Result drape(const std::string& args, const std::string& shell = "") {
    const std::string cmd = shell + std::string(DRAPE_BIN) + " " + args + " > " + (dir / "stdout").string() + " 2> " +
                            (dir / "stderr").string();
    const int status = std::system(cmd.c_str());
    return {WIFEXITED(status) ? WEXITSTATUS(status) : -1, slurp(dir / "stdout"), slurp(dir / "stderr")};
  }
};
