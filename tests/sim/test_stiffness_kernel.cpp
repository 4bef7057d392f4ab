// The slab-coloured K x kernel on meshes large enough for its parallel path: equal to the
// assembled product, linear and corotational, before and after thousands of local edits.
#include <catch2/catch.hpp>

#include <random>

#include "mesh/generate.h"
#include "sim/fem/assembled_stiffness.h"
#include "sim/fem/fem_model.h"
#include "tests/sim/fem_test_util.h"

using namespace incise;
using namespace incise::testing;

TEST_CASE("slab-parallel K*x equals the assembled product through local edits", "[fem][kernel]") {
#if defined(__SANITIZE_ADDRESS__)
  const int cells = 40;  // 8640 tets: still above the parallel threshold (8000)
#else
  const int cells = 48;
#endif
  TetMesh m = make_box(Vec3(8, 1, 1), {cells, 6, 6});
  jitter(m, 0.3, 11);
  m.discard_change();
  Material mat;
  mat.young = 1e5;
  mat.poisson = 0.4;
  std::mt19937 rng(3);
  std::normal_distribution<double> nd;
  for (FemKind kind : {FemKind::Linear, FemKind::Corotational}) {
    FemModel model(m, MaterialTable(mat), kind);
    REQUIRE(m.num_tets() > 8000);
    auto check = [&] {
      Eigen::VectorXd u(model.rows()), x(model.rows()), y1, y2;
      for (Eigen::Index i = 0; i < u.size(); ++i) u[i] = 0.05 * nd(rng), x[i] = nd(rng);
      model.update_rotations(u);
      AssembledStiffness as(model);
      model.multiply(x, y1);
      as.multiply(x, y2);
      CHECK((y1 - y2).norm() <= 1e-12 * y2.norm());
    };
    check();
    TetMesh edited = m;
    FemModel local(edited, MaterialTable(mat), kind);
    for (int e = 0; e < 2000; ++e) {
      random_edit(edited, rng, true);
      if (e % 50 == 49) local.apply(edited.take_change());
    }
    local.apply(edited.take_change());
    Eigen::VectorXd u = Eigen::VectorXd::Zero(local.rows()), x(local.rows()), y1, y2;
    for (Eigen::Index i = 0; i < u.size(); ++i) u[i] = 0.05 * nd(rng), x[i] = nd(rng);
    local.update_rotations(u);
    AssembledStiffness as(local);
    local.multiply(x, y1);
    as.multiply(x, y2);
    CHECK((y1 - y2).norm() <= 1e-12 * y2.norm());
  }
}
