#pragma once
// A run's output directory (`incise simulate -o DIR`, Python's run_scene(path, DIR)): DIR is
// always one run's output. The run is written into a fresh hidden directory beside DIR (in
// DIR's nearest existing ancestor, so the final rename stays on one file system) and replaces
// DIR only at the end; a shorter re-run leaves no stale frames, a failed run leaves an earlier
// run as it was. A run directory carries a marker file (kRunMarker): an existing DIR that is
// not empty must carry it and hold nothing but a run's files, so a user's stats.csv or
// frames.pvd is never overwritten. Hidden run directories left by processes that are gone (a
// run killed by a signal) are removed when the next run starts beside them.
#include <filesystem>
#include <string>

#include "scene/run_scene.h"

namespace incise {

inline constexpr const char* kRunMarker = ".incise-run";

class RunDirectory {
public:
  // Checks DIR (IoError naming it when it holds anything a run did not write) and makes the
  // hidden directory the run writes into.
  explicit RunDirectory(const std::string& out);
  ~RunDirectory();
  RunDirectory(const RunDirectory&) = delete;
  RunDirectory& operator=(const RunDirectory&) = delete;

  std::string path() const { return tmp_.string(); }
  // Whether DIR holds an earlier run (which a failed run must not replace).
  bool holds_earlier_run() const { return had_run_; }
  // Whether the run wrote anything yet (a frame, the stats).
  bool holds_output() const;
  // Puts the run in DIR: an atomic exchange when DIR exists, the earlier run then removed.
  void commit();

private:
  std::string out_;
  std::filesystem::path dir_, tmp_;
  bool existed_ = false, had_run_ = false;
};

// run_scene into DIR through a RunDirectory: a run that fails keeps the frames it wrote unless
// DIR held an earlier run, which is then kept (the error says so); one that fails before
// writing anything (a scene's mesh refused) leaves DIR as it was.
SceneRunSummary run_scene_into(const Scene& scene, SceneRunOptions options, const std::string& out);

}  // namespace incise
