#pragma once
// Internal to incise trade (scene/trade.cpp, scene/trade_convergence.cpp): the scene's body at
// each mesh level, the converged reference solved on one of them with its error bar, and reading
// a reference at another mesh's vertices. See scene/trade.h for what the reference is.
#include <chrono>
#include <map>
#include <memory>
#include <ostream>
#include <string>
#include <vector>

#include <Eigen/Core>

#include "mesh/clock.h"
#include "mesh/point_locator.h"
#include "scene/trade.h"

namespace incise::trade_detail {

const char* model_name(SceneModel m);
std::string fmt(double v);  // 4 significant digits

// The scene's body at mesh level `level` (see TradeOptions::resolutions), compacted; `how`
// (level -1) says how the coarser mesh was made.
TetMesh body_at(const Scene& s, int level, std::string* how);

// A reference solution read at another mesh's vertices.
struct Probe {
  std::vector<PointLocation> at;  // by vertex slot of the run's mesh (invalid tet: dead slot)
};
Probe locate(const TetMesh& run, const PointLocator& loc);
// The reference displacement at the run's vertices (3 per vertex slot).
Eigen::VectorXd sample(const TetMesh& ref, const Probe& p, const Eigen::VectorXd& u_ref);

struct Errors {
  double l2 = 0, max_disp = 0;
};
Errors compare(const Eigen::VectorXd& u, const Eigen::VectorXd& ref);

// The bodies per level and the reference solved on one of them, with its error bar: what the
// grid (run_trade) and the convergence study (run_convergence) measure against.
struct Basis {
  Scene scene;  // uncut
  int frames = 0;
  std::vector<int> levels;
  std::map<int, std::unique_ptr<TetMesh>> meshes;
  std::string coarser;
  TradeReference reference;
  std::vector<Eigen::VectorXd> ref;  // per frame, at the reference mesh's vertex slots
  std::unique_ptr<PointLocator> locator;
  std::map<int, Probe> probes;
  const TetMesh& mesh(int level, std::ostream* progress);
  const TetMesh& ref_mesh() const { return *meshes.at(reference.level); }
  const Probe& probe(int level);  // the level's mesh must have been made (mesh())
};

// Makes the scene's bodies and solves the reference one level above the finest of `levels`
// (empty: TradeOptions' default), and the same one level coarser for its error bar.
void prepare(Basis& b, const Scene& cut_scene, const TradeOptions& opt, std::vector<int> levels);

}  // namespace incise::trade_detail
