#pragma once
// Coarsening by edge contraction: a copy of a body with fewer, larger tets (about twice the
// edge length: 1/4 .. 1/8 of the tets), for comparing a solve across resolutions when the mesh
// is a file and nothing can regenerate it coarser (incise trade's level -1).
//
// Edges shorter than the target length are contracted shortest first (mesh/edge_collapse.h
// checks the link condition, orientation and the star's volume), then the improvement pass
// (quality/improve.h) flips and smooths. What is kept:
//  - Labels: every tet keeps its label. Label interfaces are surfaces like the boundary.
//  - The body: boundary and interface vertices are only contracted into a neighbour on the
//    same surface along a surface edge, so every vertex that stays is an input vertex on the
//    input's surface, and every removed surface vertex stays within max_deviation of the
//    surface faces around the vertex that absorbed it (checked before each contraction, for
//    every input surface vertex that vertex answers for). Feature edges (bent more than
//    feature_angle_deg, or between different tags or label pairs, or shared by more than two
//    surface faces) are contracted only along themselves; their corners and ends never move.
//  - Boundary tags: collapse_edge() gives every retiled face its tag back.
//  - Quality: a contraction may not take its tets' smallest dihedral angle below
//    min(min_dihedral_deg, the star's before), their largest above max(max_dihedral_deg, before),
//    nor their radius ratio below min(radius_ratio_floor, before): no inverted or flat tet.
// Deterministic: the same input and options give the same mesh (no time limit is involved;
// the improvement pass is capped by a work count instead).
// O(mesh log mesh); a whole-mesh operation, not for the frame loop. The result has dead slots
// (compact() it) and a pending TopologyChange (discard it or hand it on).
#include <cstddef>

#include "mesh/tet_mesh.h"
#include "quality/improve.h"

namespace incise {

struct CoarsenOptions {
  double edge_factor = 2;         // target edge length = this x the input's mean edge length
  double target_edge = 0;         // > 0: the target edge length itself (edge_factor ignored)
  double max_edge_factor = 1.5;   // a contraction may not make an edge longer than this x the target
  double max_deviation = 0;       // > 0: bound on the surface's move (input units); 0: 0.1 x target
  double feature_angle_deg = 60;  // surface edges bent more than this are features (60: a box's edges are,
                                  // the bumps of a surface meshed from an image are not)
  double min_dihedral_deg = 10;   // quality floor (see above)
  double max_dihedral_deg = 160;
  double radius_ratio_floor = 0.15;
  int passes = 3;                 // sweeps over the edges (later ones retry what earlier refused)
  bool improve = true;            // run the improvement pass after contracting
  int rounds = 3;                 // contract, improve, and again (improved stars contract further)
};

struct CoarsenReport {
  std::size_t tets_before = 0, tets_after = 0, vertices_before = 0, vertices_after = 0;
  double mean_edge_before = 0, mean_edge_after = 0, target_edge = 0, max_deviation = 0;
  int contractions = 0;
  ImproveReport improve;  // the passes after contracting, summed (zeros when options.improve is off)
};

CoarsenReport coarsen(TetMesh& mesh, const CoarsenOptions& options = {});

// The mean length of the mesh's edges (each once). O(mesh).
double mean_edge_length(const TetMesh& mesh);

}  // namespace incise
