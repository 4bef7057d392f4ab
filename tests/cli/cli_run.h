#pragma once
// Running the incise executable from the CLI tests: stdout, stderr and the exit code.
#include <sys/wait.h>

#include <algorithm>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <catch2/catch.hpp>

namespace incise::testing {

struct Run {
  int code;
  std::string out, err;
};

inline std::string slurp(const std::filesystem::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Runs `incise ARGS` in a shell from `dir`'s point of view for the capture files.
inline Run run_incise(const std::string& args, const std::filesystem::path& dir) {
  const std::filesystem::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string cmd = std::string("'") + INCISE_EXE + "' " + args + " >'" + out.string() + "' 2>'" + err.string() + "'";
  const int status = std::system(cmd.c_str());
  const int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return {code, slurp(out), slurp(err)};
}

// A fresh scratch directory under the build tree.
inline std::filesystem::path scratch_dir(const std::string& name) {
  std::filesystem::path d = std::filesystem::path(INCISE_BINARY_DIR) / "test-scratch" / name;
  std::filesystem::remove_all(d);
  std::filesystem::create_directories(d);
  return d;
}

// Quoted for the shell (appended, not operator+: GCC 12 warns falsely on that, PR105329).
inline std::string q(const std::filesystem::path& p) {
  std::string s(1, '\'');
  s += p.string();
  s += '\'';
  return s;
}

// A failed run: exit 1, one line with the prefix, naming `expect`.
inline void check_failed(const Run& r, const std::string& expect) {
  INFO(r.err);
  CHECK(r.code == 1);
  CHECK(r.err.rfind("incise: error: ", 0) == 0);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  CHECK(r.err.find(expect) != std::string::npos);
}

}  // namespace incise::testing
