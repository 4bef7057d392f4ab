#include "mesh/rest_bounds.h"

namespace incise {

RestBounds rest_bounds(const TetMesh& mesh) {
  RestBounds b;
  for (VertexId v : mesh.vertices()) {
    b.lo = b.lo.cwiseMin(mesh.rest(v));
    b.hi = b.hi.cwiseMax(mesh.rest(v));
  }
  return b;
}

}  // namespace incise
