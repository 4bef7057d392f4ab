// Edge contractions fed to the backends: after batches of random splits, flips, tet removals
// and contractions, the locally updated FEM model and spring model equal ones built from
// scratch, and the fields of the surviving vertices are untouched.
#include <catch2/catch.hpp>

#include <random>

#include "mesh/generate.h"
#include "sim/fem_model.h"
#include "sim/spring_model.h"
#include "tests/sim/fem_test_util.h"

using namespace incise;
using namespace incise::testing;

namespace {

// A batch: random edits and contractions interleaved, of any vertex, also one the batch
// itself added (its added record stays and it is listed as removed as well; freed ids are
// reused only after the batch, see mesh/edge_collapse.h).
int edit_batch(TetMesh& m, std::mt19937& rng, int edits, int collapses) {
  int done = 0;
  while (edits + collapses > 0) {
    if (edits > 0 && (collapses == 0 || rng() % 2 == 0)) {
      random_edit(m, rng, true);
      --edits;
    } else {
      done += random_collapse(m, rng, [](VertexId) { return true; });
      --collapses;
    }
  }
  return done;
}

}  // namespace

TEST_CASE("contractions keep locally updated FEM and spring models equal to fresh ones", "[fem][springs][collapse]") {
  TetMesh m = make_box(Vec3(1, 1.5, 1), {4, 5, 4});
  jitter(m, 0.25, 9);
  for (TetId t : m.tets())
    if (t.idx() % 5 == 0) m.set_label(t, 2);
  m.discard_change();
  MaterialTable mats(Material{2e4, 0.45, 900});
  mats.set(2, Material{5e7, 0.2, 1900});
  FemModel fem(m, mats, FemKind::Corotational);
  SpringModel springs(m, mats);
  // An affine field: what survives an edit must stay exactly on it, new vertices land on it.
  Eigen::Matrix3d F;
  F << 0.01, 0.02, 0.0, -0.01, 0.03, 0.02, 0.0, 0.01, -0.02;
  Eigen::VectorXd u = Eigen::VectorXd::Zero(fem.rows());
  for (VertexId v : m.vertices()) u.segment<3>(3 * v.idx()) = F * m.rest(v);
  std::mt19937 rng(31), check_rng(2);
  std::normal_distribution<double> nd;
  int collapses = 0;
  for (int batch = 0; batch < 300; ++batch) {
    collapses += edit_batch(m, rng, batch % 3, 4 + batch % 12);
    const TopologyChange ch = m.take_change();
    fem.apply(ch);
    springs.apply(m, ch);
    interpolate_added_vertices(ch, fem.vertex_slots(), u);
    if (batch % 50 == 49) {
      REQUIRE_NOTHROW(m.validate({true, false}));
      FemModel scratch(m, mats, FemKind::Corotational);
      const Eigen::Index n = Eigen::Index(3 * m.vertex_capacity());
      Eigen::VectorXd x = Eigen::VectorXd::Zero(fem.rows()), xs = Eigen::VectorXd::Zero(scratch.rows()), y, ys;
      for (Eigen::Index i = 0; i < n; ++i) x[i] = xs[i] = nd(check_rng);
      fem.multiply(x, y);
      scratch.multiply(xs, ys);
      CHECK((y.head(n) - ys.head(n)).norm() <= 1e-12 * ys.head(n).norm());
      CHECK((fem.lumped_mass().head(n) - scratch.lumped_mass().head(n)).norm() <= 1e-12 * scratch.lumped_mass().head(n).norm());
      CHECK((fem.diagonal().head(n) - scratch.diagonal().head(n)).norm() <= 1e-12 * scratch.diagonal().head(n).norm());
      SpringModel fresh(m, mats);
      REQUIRE(springs.num_springs() == fresh.num_springs());
      for (VertexId v : m.vertices()) {
        CHECK(springs.mass(v) == Approx(fresh.mass(v)).epsilon(1e-12));
        CHECK((u.segment<3>(3 * v.idx()) - F * m.rest(v)).norm() <= 1e-12);
      }
      CHECK(springs.stable_time_step() == Approx(fresh.stable_time_step()).epsilon(1e-12));
    }
  }
  INFO(collapses << " contractions");
  CHECK(collapses > 50);
}
