#pragma once
// What a consumer of a mesh's TopologyChanges (a simulation backend) has applied: the changes of
// its own mesh, in order, each once, while it is the mesh's latest. A change from another mesh,
// one applied twice, one after a skipped one, or one the mesh has been edited past is refused
// with InvalidArgument before the consumer touches its data (those crashed the backends: they
// index their arrays by the change's ids). A change made by
// hand (not stamped) is checked against the mesh instead: every id it names within the mesh,
// every tet it adds alive.
#include "mesh/tet_mesh.h"

namespace incise {

class ChangeFollower {
public:
  // Follows `mesh` from its current state (its changes taken so far count as applied).
  explicit ChangeFollower(const TetMesh& mesh) : mesh_(mesh.id()), serial_(mesh.changes_taken()) {}
  // Throws InvalidArgument ("change: ...") unless `change` is the next one of `mesh` (or a
  // consistent hand-made one); then counts it applied.
  void follow(const TetMesh& mesh, const TopologyChange& change);

private:
  std::uint64_t mesh_, serial_;
};

}  // namespace incise
