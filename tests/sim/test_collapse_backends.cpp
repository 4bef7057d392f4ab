// Edge contractions, multi-face removals and cavity insertions fed to the backends: after
// batches of random splits, flips, tet removals, multi-face removals, cavity insertions and
// contractions, the locally updated FEM model and spring model equal ones built from scratch,
// and the fields of the surviving vertices are untouched.
#include <catch2/catch.hpp>

#include <random>

#include "mesh/generate.h"
#include "quality/multi_face_removal.h"
#include "sim/fem/fem_model.h"
#include "sim/springs/spring_model.h"
#include "tests/sim/fem_test_util.h"

using namespace incise;
using namespace incise::testing;

namespace {

// The best multi-face removal from a random face of a random tet (quality/multi_face_removal.h),
// when the mesh takes it and it has at least two faces (one is a 2-3 flip, which random_edit makes).
bool random_multi_face_removal(TetMesh& m, std::mt19937& rng) {
  const TetId t = random_tet(m, rng);
  const auto plan = best_multi_face_removal(m, t, static_cast<int>(rng() % 4), ImproveScope{});
  if (!plan || plan->faces.size() < 2 || !m.is_multi_face_removal_ok(plan->u, plan->w, plan->faces)) return false;
  m.remove_faces(plan->u, plan->w, plan->faces);
  return true;
}

struct Done {
  int collapses = 0, multi_face = 0, cavities = 0;
};

// A batch: random edits, multi-face removals and contractions interleaved; a contraction may
// remove any vertex, also one the batch itself added (its added record stays and it is listed
// as removed as well; freed ids are reused only after the batch, see mesh/edge_collapse.h).
void edit_batch(TetMesh& m, std::mt19937& rng, int edits, int removals, int collapses, Done& done) {
  while (edits + removals + collapses > 0) {
    const int k = static_cast<int>(rng() % std::uint32_t(edits + removals + collapses));
    if (k < edits) {
      random_edit(m, rng, true);
      --edits;
    } else if (k < edits + removals) {
      done.multi_face += random_multi_face_removal(m, rng);
      done.cavities += random_cavity_insertion(m, rng);  // quality/insertion.h's edit
      --removals;
    } else {
      done.collapses += random_collapse(m, rng, [](VertexId) { return true; });
      --collapses;
    }
  }
}

}  // namespace

TEST_CASE("contractions, multi-face removals and cavity insertions keep locally updated FEM and spring "
          "models equal to fresh ones",
          "[fem][springs][collapse][multiface]") {
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
  Done done;
  for (int batch = 0; batch < 300; ++batch) {
    edit_batch(m, rng, batch % 3, batch % 4, 4 + batch % 12, done);
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
  INFO(done.collapses << " contractions, " << done.multi_face << " multi-face removals, " << done.cavities
                      << " cavity insertions");
  CHECK(done.collapses > 50);
  CHECK(done.multi_face > 20);
  CHECK(done.cavities > 20);
}
