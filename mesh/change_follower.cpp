#include "mesh/change_follower.h"

#include <string>

#include "mesh/errors.h"

namespace incise {

void ChangeFollower::follow(const TetMesh& mesh, const TopologyChange& change) {
  if (change.serial != 0) {
    if (change.mesh != mesh_ || mesh.id() != mesh_)
      throw InvalidArgument("change: it is another mesh's change (apply it to the simulations of the mesh it came from)");
    if (change.serial != serial_ + 1)
      throw InvalidArgument("change: expected the mesh's change #" + std::to_string(serial_ + 1) + ", got #" +
                            std::to_string(change.serial) +
                            (change.serial <= serial_ ? " (applied already)" : " (apply every change, in order)"));
    // The consumer reads the mesh as it is now: a change the mesh has moved past (edited and
    // taken again since) no longer describes it.
    if (mesh.changes_taken() != change.serial || mesh.has_pending_change())
      throw InvalidArgument("change: #" + std::to_string(change.serial) + " is not the mesh's latest (#" +
                            std::to_string(mesh.changes_taken()) +
                            (mesh.has_pending_change() ? ", and edits are pending" : "") +
                            "): apply each change before the mesh is edited again");
    serial_ = change.serial;
    return;
  }
  if (change.empty()) return;
  // Made by hand: every id within the mesh, the added tets alive.
  const std::size_t nv = mesh.vertex_capacity(), nt = mesh.tet_capacity();
  auto bad = [](const std::string& what) { throw InvalidArgument("change: " + what + " is not in the mesh"); };
  for (TetId t : change.added_tets)
    if (!t.is_valid() || t.idx() >= nt || !mesh.is_alive(t)) bad("added tet " + std::to_string(t.idx()));
  for (TetId t : change.removed_tets)
    if (!t.is_valid() || t.idx() >= nt) bad("removed tet " + std::to_string(t.idx()));
  for (const auto* list : {&change.added_vertices, &change.moved_vertices})
    for (const VertexOrigin& o : *list) {
      if (!o.vertex.is_valid() || o.vertex.idx() >= nv) bad("vertex " + std::to_string(o.vertex.idx()));
      for (VertexId p : o.parents)
        if (p.is_valid() && p.idx() >= nv) bad("parent vertex " + std::to_string(p.idx()));
    }
  for (const auto* list : {&change.removed_vertices, &change.touched_vertices})
    for (VertexId v : *list)
      if (!v.is_valid() || v.idx() >= nv) bad("vertex " + std::to_string(v.idx()));
}

}  // namespace incise
