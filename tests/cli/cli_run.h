#pragma once
// Runs the incise executable as a user would (shell, captured stdout/stderr, exit code) in a
// scratch directory under the build tree. Shared by the CLI tests.
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include <sys/wait.h>

namespace fs = std::filesystem;

inline namespace cli_run {

struct Run {
  int code;
  std::string out, err;
};

inline std::string slurp(const fs::path& p) {
  std::ifstream in(p, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// Runs `incise ARGS` in a shell, capturing stdout, stderr and the exit code.
inline Run run_incise(const std::string& args, const fs::path& dir) {
  const fs::path out = dir / "stdout.txt", err = dir / "stderr.txt";
  const std::string cmd = std::string("'") + INCISE_EXE + "' " + args + " >'" + out.string() + "' 2>'" + err.string() + "'";
  int status = std::system(cmd.c_str());
  int code = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  return {code, slurp(out), slurp(err)};
}

inline fs::path scratch_dir(const std::string& name) {
  fs::path d = fs::path(INCISE_BINARY_DIR) / "test-scratch" / name;
  fs::remove_all(d);
  fs::create_directories(d);
  return d;
}

}  // namespace cli_run
