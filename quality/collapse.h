#pragma once
// Edge contraction in the improvement pass: where a tet below the targets has an edge much
// shorter than its longest (needles, caps with a short edge, the slivers a cut leaves where it
// passed close to a vertex), contract that edge (mesh/edge_collapse.h) in the direction whose
// rebuilt tets are best, when they better() the star they replace. Flips and smoothing cannot
// repair those tets: every configuration of the tiny edge's star stays tiny.
#include <cstdint>
#include <optional>
#include <unordered_set>
#include <vector>

#include "mesh/edge_collapse.h"
#include "mesh/id_set.h"
#include "mesh/tet_mesh.h"
#include "quality/improve_scope.h"

namespace incise {

struct CollapseOptions {
  double edge_ratio = 0.2;  // try edges shorter than this times the tet's longest edge
  const IdSet* frozen = nullptr;  // never removed
  double tolerance = 0;  // check_collapse's: tiny edges may contract on curved boundary and interfaces
  bool remove_boundary = true;  // false: boundary vertices stay (ImproveOptions::move_surface / move_cut off)
  // > 0: where check_collapse refuses a surface vertex (its surface is curved or bent there), it
  // may still be contracted along its surface: not across a feature (an edge between two tags
  // or label pairs, or bent more than feature_angle_deg: along it only; corners stay), keeping
  // the surface a surface (surface_link_ok), with the removed vertex within this times its mean
  // surface edge of the surface after the contraction. The cut leaves short edges on bent cut
  // sheets and rims that nothing else removes (ImproveOptions::collapse_deviation).
  double surface_deviation = 0;
  double feature_angle_deg = 30;
  // With tolerance or surface_deviation: a contraction that moves the surface is taken only
  // with the kept vertex moved by what gives its label back exactly the volume the contraction
  // moved (ImproveOptions::collapse_restores_volume): along the gradient of the volume, within
  // every cut plane at the two vertices, by at most surface_deviation (or tolerance) times the
  // mean surface edge at the kept vertex; refused where the two stars hold more than one label
  // or the cut planes leave no direction.
  bool restore_volume = false;
};

struct CollapseOutcome {
  VertexId kept, removed_vertex;
  bool kept_moved = false;     // restore_volume moved `kept` (its tets are in removed and rebuilt)
  std::vector<TetId> removed;  // every tet of the removed vertex before the collapse
  std::vector<TetId> rebuilt;  // the ones still alive (same ids, rebuilt on `kept`)
  double volume_change = 0;    // sum over labels of |volume change| (tolerance mode only)
};

// The contraction of surface (boundary or interface) vertex `remove` into `keep` along its
// surface, as opt.surface_deviation allows (see there): a plan of check_collapse's tolerant
// mode, or a refusal (Boundary when the surface checks refuse). O(the two stars).
CollapseCheck check_surface_contraction(const TetMesh& mesh, VertexId keep, VertexId remove,
                                        const CollapseOptions& opt);

std::optional<CollapseOutcome> improve_by_collapse(TetMesh& mesh, TetId t, const ImproveScope& scope,
                                                   const CollapseOptions& opt);

}  // namespace incise
