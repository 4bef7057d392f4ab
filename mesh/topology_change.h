#pragma once
// The one record by which everything outside mesh/ learns about edits. A batch of edits
// (one cut, one improvement pass) yields one TopologyChange; consumers (sim backends,
// spatial indices) update their per-element data from it alone, without a global rebuild.
#include <array>
#include <cstdint>
#include <vector>

#include "mesh/handles.h"

namespace incise {

// A vertex created by an edit. Its rest position is sum_k weights[k] * rest(parents[k]);
// consumers derive any other per-vertex quantity (current position, displacement,
// velocity) with the same weights. Unused parent slots are invalid with weight 0.
// A duplicated vertex (cut) has one parent with weight 1.
struct VertexOrigin {
  VertexId vertex;
  std::array<VertexId, 4> parents;
  std::array<double, 4> weights{0, 0, 0, 0};
};

// sum_k weights[k] * value(parents[k]) over o's parents (unused slots skipped): how a consumer
// carries any per-vertex quantity (displacement, velocity, pressure) to an added or moved
// vertex. `zero` is the quantity's zero (Vec3::Zero(), 0.0).
template <class T, class Value>
T interpolate_origin(const VertexOrigin& o, const T& zero, Value&& value) {
  T s = zero;
  for (int k = 0; k < 4; ++k)
    if (o.parents[k].is_valid() && o.weights[k] != 0) s += o.weights[k] * value(o.parents[k]);
  return s;
}

// Whether o has a parent (a plain new vertex has none).
inline bool has_parents(const VertexOrigin& o) {
  for (int k = 0; k < 4; ++k)
    if (o.parents[k].is_valid() && o.weights[k] != 0) return true;
  return false;
}

struct TopologyChange {
  // Tets alive before the batch and dead after it (ids may have been reused: a reused id
  // appears in both lists, removed first).
  std::vector<TetId> removed_tets;
  // Tets alive after the batch that did not exist before it.
  std::vector<TetId> added_tets;
  // In creation order: parents always precede their children.
  std::vector<VertexOrigin> added_vertices;
  // Vertices whose rest position an edit moved (smoothing), in the order of the moves. The
  // record's parents and weights give the new rest position as a point of the mesh *before*
  // the move (parents may include the vertex itself, with its old value). Consumers apply
  // added_vertices first, then these, each in order, interpolating every per-vertex field
  // (displacement, current position, velocity): the deformed shape then stays where it was.
  // The tets around a moved vertex are listed as removed and added (their rest shape changed).
  // A vertex inserted after moves in the same batch is recorded by TetMesh at the positions
  // the batch started from, so the order above stays exact.
  std::vector<VertexOrigin> moved_vertices;
  // Isolated vertices deleted by the batch. One the batch itself added (an improvement pass
  // contracting a cut's new vertex) is in added_vertices too, since later records may name
  // it as a parent: consumers apply removals after added and moved vertices.
  std::vector<VertexId> removed_vertices;
  // Vertices (old or new) whose set of incident tets changed, each listed once.
  std::vector<VertexId> touched_vertices;
  // Which mesh made it and its place among that mesh's changes (1, 2, ...), stamped by
  // TetMesh::take_change() on every change that is not empty; 0: made by hand. Consumers apply
  // a mesh's changes in order, each once (mesh/change_follower.h).
  std::uint64_t mesh = 0, serial = 0;

  bool empty() const {
    return removed_tets.empty() && added_tets.empty() && added_vertices.empty() &&
           moved_vertices.empty() && removed_vertices.empty() && touched_vertices.empty();
  }
};

} // namespace incise
