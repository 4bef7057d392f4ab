#include "scene/run_directory.h"

#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <unistd.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <regex>

#include "mesh/errors.h"
#include "mesh/io/atomic_file.h"

namespace incise {

namespace fs = std::filesystem;

namespace {

// What a run writes into DIR; anything else there is the user's and makes the run refuse DIR.
bool is_run_output(const std::string& name) {
  static const std::regex kRun(R"(frame_\d+\.(vtu|vtk)|frames\.pvd|stats\.csv)");
  return name == kRunMarker || std::regex_match(name, kRun);
}

// Hidden run directories beside DIR (".DIR.run<pid>_<n>", and their ".old") whose process is
// gone: a run killed by a signal leaves its directory behind.
void remove_stale_runs(const fs::path& base, const std::string& name) {
  const std::regex kHidden("\\." + std::regex_replace(name, std::regex(R"([.^$|()\[\]{}*+?\\])"), R"(\$&)") +
                           R"(\.run(\d+)_\d+(\.old)?)");
  std::error_code ec;
  for (fs::directory_iterator it(base, ec), end; !ec && it != end; it.increment(ec)) {
    std::smatch m;
    const std::string f = it->path().filename().string();
    if (!std::regex_match(f, m, kHidden)) continue;
    const long pid = std::stol(m[1].str());
    if (pid <= 0 || pid == long(::getpid())) continue;
    if (::kill(pid_t(pid), 0) == 0 || errno != ESRCH) continue;  // alive (or not ours to know)
    std::error_code rm;
    fs::remove_all(it->path(), rm);
  }
}

}  // namespace

RunDirectory::RunDirectory(const std::string& out) : out_(out), dir_(fs::absolute(out).lexically_normal()) {
  if (!dir_.has_filename()) dir_ = dir_.parent_path();  // "out/" -> "out"
  check_output_dir(out);
  std::error_code ec;
  existed_ = fs::is_directory(dir_, ec);
  if (existed_) {
    bool marked = false, any = false;
    for (const auto& e : fs::directory_iterator(dir_)) {
      const std::string name = e.path().filename().string();
      if (!is_run_output(name))
        throw IoError(out, 0, "holds " + name + ", which incise simulate did not write; give a new or empty directory");
      marked = marked || name == kRunMarker;
      any = true;
    }
    // Files named like a run's, without the marker: the user's (or a run of an older incise).
    if (any && !marked)
      throw IoError(out, 0, std::string("holds files incise simulate did not write (no ") + kRunMarker +
                                "); give a new or empty directory");
    had_run_ = any;
  }
  fs::path base = dir_.parent_path();
  while (!fs::exists(base, ec)) base = base.parent_path();
  remove_stale_runs(base, dir_.filename().string());
  for (int attempt = 0;; ++attempt) {
    // Appended piece by piece: GCC 12 warns falsely on "." + string (-Wrestrict, PR105329).
    std::string name(".");
    name += dir_.filename().string();
    name += ".run";
    name += std::to_string(::getpid());
    name += "_";
    name += std::to_string(attempt);
    tmp_ = base / name;
    if (fs::create_directory(tmp_, ec)) break;
    if (ec || attempt > 100) throw IoError(out, 0, "cannot create a run directory beside it: " + tmp_.string());
  }
  std::ofstream(tmp_ / kRunMarker) << "incise run directory\n";
}

RunDirectory::~RunDirectory() {
  std::error_code ec;
  if (!tmp_.empty()) fs::remove_all(tmp_, ec);
}

void RunDirectory::commit() {
  std::error_code ec;
  fs::create_directories(dir_.parent_path(), ec);
  if (ec) throw IoError(out_, 0, "cannot create output directory: " + ec.message());
  if (existed_ && fs::is_directory(dir_, ec)) {
    if (::renameat2(AT_FDCWD, tmp_.c_str(), AT_FDCWD, dir_.c_str(), RENAME_EXCHANGE) != 0) {
      // No RENAME_EXCHANGE on this file system: DIR is missing only between two renames.
      const fs::path old = tmp_.string() + ".old";
      if (std::rename(dir_.c_str(), old.c_str()) != 0 || std::rename(tmp_.c_str(), dir_.c_str()) != 0) {
        const int err = errno;
        if (!fs::exists(dir_, ec)) std::rename(old.c_str(), dir_.c_str());
        throw IoError(out_, 0, std::string("cannot replace the directory: ") + std::strerror(err));
      }
      fs::remove_all(old, ec);
      tmp_.clear();
      return;
    }
    // Exchanged: tmp_ now holds the earlier run, which the destructor removes.
  } else if (std::rename(tmp_.c_str(), dir_.c_str()) != 0) {
    throw IoError(out_, 0, std::string("cannot move the run into place: ") + std::strerror(errno));
  } else {
    tmp_.clear();
  }
}

bool RunDirectory::holds_output() const {
  std::error_code ec;
  for (const auto& e : std::filesystem::directory_iterator(tmp_, ec))
    if (e.path().filename() != kRunMarker) return true;
  return false;
}

SceneRunSummary run_scene_into(const Scene& scene, SceneRunOptions options, const std::string& out) {
  RunDirectory run(out);
  options.out_dir = run.path();
  SceneRunSummary s;
  try {
    s = run_scene(scene, options);
  } catch (const Error& e) {
    // The frames computed before the failure are kept (docs/scene.md) unless DIR holds an
    // earlier run: that one is not replaced by a broken one.
    if (run.holds_earlier_run()) throw Error(std::string(e.what()) + " (" + out + " keeps the earlier run)");
    if (run.holds_output()) run.commit();  // a run that failed before its first frame leaves no DIR
    throw;
  }
  run.commit();
  return s;
}

}  // namespace incise
