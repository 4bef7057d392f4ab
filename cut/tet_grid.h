#pragma once
// TetGrid: where a new cut first touches the mesh, without scanning it.
//
// A uniform grid over the REST positions: each cell lists the tets whose rest bounding box
// overlaps it. Rest positions change only through edits, and every edit is in a
// TopologyChange, so update() keeps the grid exact in time proportional to the change (added
// tets are inserted; removed ones are dropped lazily, when a query visits their cell).
//
// Cuts act on the current (deformed) shape. A vertex is at most `max_displacement` away from
// its rest position, so a tet whose current box meets a region has a rest box that meets the
// region grown by that distance: query() returns a superset of the tets that may touch, and
// the cutter's exact tests decide. The cost of a query is the number of tets listed in the
// cells of the grown region, which depends on the blade and the deformation, not on the
// mesh's size.
#include <array>
#include <cstdint>
#include <vector>

#include "mesh/tet_mesh.h"

namespace incise {

class TetGrid {
public:
  // Sizes the grid from the mesh's rest box and mean tet size and inserts every tet: O(mesh),
  // once per cutter (or after edits the grid was not told about).
  void build(const TetMesh& mesh);
  bool built() const { return !cells_.empty(); }
  // Takes one batch of edits (O(change)).
  void update(const TetMesh& mesh, const TopologyChange& change);
  // Live tets whose rest box meets [lo - grow, hi + grow] (each listed once).
  std::vector<TetId> query(const TetMesh& mesh, const Vec3& lo, const Vec3& hi, double grow);

  std::size_t cells() const { return cells_.size(); }
  double cell_size() const { return cell_; }

private:
  void insert(const TetMesh& mesh, TetId t);
  void rest_box(const TetMesh& mesh, TetId t, Vec3& lo, Vec3& hi) const;
  std::array<std::int64_t, 3> cell_of(const Vec3& x) const;
  std::size_t index(std::int64_t i, std::int64_t j, std::int64_t k) const {
    return std::size_t((k * dims_[1] + j) * dims_[0] + i);
  }

  std::vector<std::vector<std::uint32_t>> cells_;
  std::array<std::int64_t, 3> dims_{0, 0, 0};
  Vec3 origin_ = Vec3::Zero();
  double cell_ = 1;
  // By tet id, stamps that dedupe without a hash set: within one cell (cleaning) and within
  // one query (a tet spans several cells).
  std::vector<std::uint32_t> in_cell_, in_query_;
  // By tet id, the cells its rest box covered when it was last inserted (lo i, j, k, hi i, j,
  // k): a query drops a listing outside them (the id's tet was removed or re-inserted since)
  // with no look at the mesh, and computes a tet's box once, not once per cell it lists.
  std::vector<std::array<std::int32_t, 6>> range_;
  // By tet id, its rest box when it was last inserted (lo, hi): a query reads it instead of
  // the tet's four rest positions. Exact while the tet is as inserted, which range_ assumes too.
  std::vector<std::array<double, 6>> box_;
  std::uint32_t cell_stamp_ = 0, query_stamp_ = 0;
};

}  // namespace incise
