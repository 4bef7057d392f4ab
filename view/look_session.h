#pragma once
// LookSession: files looked at in the viewer (`incise view MESH|REPORT|RUN_DIR`, docs/view.md),
// nothing simulated. A mesh is drawn with its labels and boundary tags as colours and its worst
// elements highlighted (the quality library's, or the list of a report written by `incise
// quality --json`); a run directory written by `incise simulate -o DIR` is a series of such
// frames (frames.pvd), one shown at a time (InputKind::Frame), with stats.csv's columns in
// /status for the page's curves. It reads only the files it was given and the frames the
// series lists (plain names inside the directory), each when first shown.
#include <map>
#include <mutex>
#include <optional>
#include <string>
#include <vector>

#include "mesh/tet_mesh.h"
#include "view/view_source.h"

namespace incise::view {

// What `incise view ARG` was given, decided from ARG alone.
enum class ViewArgument { Scene, Report, Run, Mesh };
// A directory -> Run (IoError when it has no frames.pvd); a .json whose "schema" is a quality
// report's -> Report, any other .json -> Scene; anything else -> Mesh. Throws IoError for a
// path that does not exist or a .json that does not parse.
ViewArgument classify_view_argument(const std::string& path);

class LookSession : public ViewSource {
public:
  static constexpr int kWorstCount = 10;  // worst elements highlighted when no report names them

  // A mesh file, or a quality report (its "file", as given to `incise quality`, or beside the
  // report; its "worst" list is highlighted). Throws IoError naming the file.
  static std::unique_ptr<LookSession> open_mesh(const std::string& path);
  static std::unique_ptr<LookSession> open_report(const std::string& report);
  // A run directory: frames.pvd's frames, stats.csv's columns. Throws IoError naming the file.
  static std::unique_ptr<LookSession> open_run(const std::string& dir);

  std::string post(const InputMessage& input) override;
  void set_listener(std::function<void()> listener) override;
  std::shared_ptr<const Snapshot> snapshot() const override;
  std::string status_json() const override;

  std::size_t frame_count() const { return frames_.size(); }

private:
  LookSession() = default;
  void show(std::size_t frame);  // builds the snapshot of frame (mutex_ held)
  const TetMesh& mesh_of(std::size_t frame);

  std::string mode_, source_;                // "look" or "run"; what was opened
  std::vector<std::string> frames_;          // mesh files
  std::vector<double> times_;
  std::optional<std::vector<int>> report_worst_;  // tet ids from a report
  std::string report_file_;
  std::string stats_json_ = "null";          // stats.csv as {"columns": [...], "rows": [[...]]}
  std::map<std::size_t, TetMesh> meshes_;    // frames read so far (a run's are read when shown)
  std::map<std::size_t, std::vector<double>> von_mises_;  // their von_mises cell field (run frames), by TetId
  std::size_t current_ = 0;
  std::uint32_t colour_ = 0, generation_ = 0, scalar_version_ = 0;
  mutable std::mutex mutex_;
  std::shared_ptr<const Snapshot> snapshot_;
  std::string status_;
  std::function<void()> listener_;
};

}  // namespace incise::view
