#pragma once
// The surfaces around a vertex, read from its star: what contracting a surface vertex along its
// surface needs (quality/coarsen.h over a whole mesh, quality/collapse.h after a cut). A
// surface is the boundary or an interface between two labels; all of it is read from the tets
// around the vertices involved (O(star)), never from the whole mesh.
#include <algorithm>
#include <array>
#include <cstdint>
#include <vector>

#include "mesh/tet_mesh.h"

namespace incise {

// A face on a surface: the boundary (outside the mesh) or a label interface.
bool is_surface_face(const TetMesh& m, TetId t, int f);

// Which sheet a face is on for deviation bounds: the boundary (whatever its tags: they only
// partition it: kBoundarySheet), or the interface between a pair of labels.
inline constexpr std::uint64_t kBoundarySheet = std::uint64_t(1) << 63;
std::uint64_t sheet_of(const TetMesh& m, TetId t, int f);

// Which patch a face is on: a boundary tag, or the pair of labels it separates. An edge
// between two patches is a feature (it may never be flattened away).
std::uint64_t patch_of(const TetMesh& m, TetId t, int f);

// Unit normal of a surface face, oriented the same way across its patch: outward on the
// boundary, from the smaller label to the larger on an interface.
Vec3 patch_normal(const TetMesh& m, TetId t, int f);

struct SurfaceFace {
  std::array<VertexId, 3> v;
  std::uint64_t sheet;
};

// The surface faces around v once `remove` is contracted into `keep` (faces read through that
// mapping; faces holding both vanish), each once. With keep == remove invalid: as they are.
std::vector<SurfaceFace> surface_faces_after(const TetMesh& m, VertexId v, VertexId keep, VertexId remove);

// The sheets v is on, each once (empty: v is inside one label).
std::vector<std::uint64_t> surface_sheets(const TetMesh& m, VertexId v);

// Vertices joined to v by an edge of a surface face, sorted.
std::vector<std::uint32_t> surface_neighbours(const TetMesh& m, VertexId v);

// The surface stays a surface when `remove` goes into `keep`: (keep, remove) is a surface edge
// and the vertices both ends see along surface edges are exactly the apexes of the surface
// faces on that edge (else the contraction glues two sheets or pinches one).
bool surface_link_ok(const TetMesh& m, VertexId keep, VertexId remove);

// The surface faces on one edge, tallied one at a time: the edge is a feature when it is on
// other than two surface faces, between two patches, or bent more than the angle whose cosine
// is given.
struct EdgeFaceTally {
  int count = 0;
  std::uint64_t patch = 0;
  bool mixed = false;
  Vec3 n = Vec3::Zero();
  double min_dot = 1;
  void add(std::uint64_t face_patch, const Vec3& face_normal) {
    if (count == 0) {
      patch = face_patch;
      n = face_normal;
    } else {
      mixed = mixed || patch != face_patch;
      min_dot = std::min(min_dot, n.dot(face_normal));
    }
    ++count;
  }
  bool feature(double cos_feature) const { return count != 2 || mixed || min_dot < cos_feature; }
};

// The surface edges at v that are features: on other than two surface faces, between two
// patches, or bent more than the angle whose cosine is `cos_feature`. Returns the far ends.
std::vector<std::uint32_t> feature_neighbours(const TetMesh& m, VertexId v, double cos_feature);

}  // namespace incise
