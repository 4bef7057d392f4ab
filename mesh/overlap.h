#pragma once
// Whether any two tets of a mesh overlap: their interiors share volume. A mesh whose face
// neighbours lie on opposite sides of their shared faces can still overlap where tets meet
// at an edge or a vertex only, or not at all (a tet spanning a body, two copies of a part).
// Readers refuse such meshes (mesh/io/tet_io.cpp); nothing downstream is defined on them.
//
// Broad phase: a bounding-box tree over the tets; narrow phase: the separating-axis test of
// two tets (their 8 face normals and 36 edge-edge directions). Tets count as overlapping
// only where they intersect deeper than `relative_tolerance` times the longer of their
// longest edges, so tets that touch, meet along a cut or are degenerate (zero volume) never
// do. Complexity: O(T log T) for a mesh whose tets' boxes each meet O(1) others.
#include <optional>
#include <utility>

#include "mesh/tet_mesh.h"

namespace incise {

struct OverlapOptions {
  // 2%: what an overlap must exceed to be one. The quality improvement can leave tets pressed
  // a fraction of a percent into each other near a curved boundary (docs/quality-report.md), and
  // incise must read what it wrote; a body's parts laid over each other go far deeper.
  double relative_tolerance = 0.02;
};

// The first overlapping pair found (first < second by TetId), or nothing. Pairs sharing a
// face are not tested: the readers check those (opposite sides of the face) already.
std::optional<std::pair<TetId, TetId>> find_overlapping_tets(const TetMesh& mesh, const OverlapOptions& options = {});

}  // namespace incise
