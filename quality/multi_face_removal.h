#pragma once
// Multi-face removal (Shewchuk, "Two discrete optimization algorithms for the topological
// improvement of tetrahedral meshes", 2002), the inverse of edge removal: m faces sandwiched
// between two vertices u and w (each face f has the tets (f,u) and (f,w)) forming a disc are
// removed with their 2m tets, and the m+2 tets (rim edge, u, w) around the new edge u-w replace
// them (TetMesh::remove_faces). Only the new tets depend on the choice of disc, one per rim
// edge, so a dynamic program over the sandwiched faces reachable from a start face finds the
// disc that maximizes their worst angle_quality(): the value beyond a rim edge is the better of
// stopping there (its tet) and growing across it into the next sandwiched face (the worse of
// that face's two other edges' values). Linear in the faces explored.
#include <array>
#include <optional>
#include <vector>

#include "mesh/tet_mesh.h"
#include "quality/improve_scope.h"

namespace incise {

struct MultiFacePlan {
  VertexId u, w;                               // apexes: u on t's side of the start face, w across it
  std::vector<std::array<VertexId, 3>> faces;  // the disc, start face first (as TetMesh::remove_faces takes it)
  std::vector<TetId> removed;                  // the 2m tets
  AngleQuality after;                          // worst of the m+2 new tets
};

// The best disc containing face f of tet t, among the faces sandwiched between t's apex and the
// apex across f that are reachable across edges, exploring at most max_faces faces besides the
// start face. Only tets of t's label inside the scope are taken. nullopt when f is on the
// boundary or the tet across it is not taken. Does not compare with the old tets (the caller
// does) nor run the mesh's check.
std::optional<MultiFacePlan> best_multi_face_removal(const TetMesh& mesh, TetId t, int f, const ImproveScope& scope,
                                                     int max_faces = 16);

}  // namespace incise
