#pragma once
// Greedy aggregation of a tet mesh's vertex graph (two vertices are neighbours when they share
// a live tet), the coarse "nodes" of the aggregation multigrid (sim/fem/aggregation_amg.h).
//
// The classic three phases of Vanek, Mandel & Brezina (1996), on the mesh's current
// connectivity, so that the two copies of a vertex a cut duplicated, which share no tet, fall
// in different aggregates unless the material still joins them around the blade's edge:
//  1. a root whose neighbours are all unaggregated takes them and the unaggregated vertices
//     up to `ring` edges away (ring 1: the root's star; ring 2: the star's stars);
//  2. each vertex left joins the phase-1 aggregate of the neighbour that shares most tets with it;
//  3. what is still left (no aggregated neighbour) forms aggregates with its free neighbours.
// Only `eligible` vertices (per vertex; the free ones) are aggregated, and only through
// eligible neighbours: a fixed vertex neither joins nor links aggregates.
// O(vertices x ring-neighbourhood); vertex ids in increasing order (deterministic).
#include <cstdint>
#include <span>
#include <vector>

#include "mesh/tet_mesh.h"

namespace incise {

struct VertexAggregates {
  std::vector<std::int32_t> of;                   // per vertex slot: its aggregate, -1 if none
  std::vector<std::vector<std::uint32_t>> members;  // per aggregate, increasing ids
  std::size_t count() const { return members.size(); }
};

// `eligible` has one entry per vertex slot (at least mesh.vertex_capacity(); more are ignored).
VertexAggregates aggregate_vertices(const TetMesh& mesh, const std::vector<std::uint8_t>& eligible, int ring = 1);

// The same three phases over the unaggregated vertices of `pool` only (distinct ids), adding
// aggregates to `agg` and leaving the existing ones as they are: the local re-aggregation
// after a cut dissolves the aggregates the cut touched and calls this on their vertices and
// the new ones. Aggregates grow only over pool vertices. O(pool x neighbourhood).
void aggregate_more(const TetMesh& mesh, const std::vector<std::uint8_t>& eligible, int ring,
                    std::span<const std::uint32_t> pool, VertexAggregates& agg);

}  // namespace incise
