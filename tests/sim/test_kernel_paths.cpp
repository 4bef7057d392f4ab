// The matrix-free kernel's two paths (AVX2 with padded vectors, and the portable one other
// CPUs run) give the same product, linear and corotational, serial and threaded, with
// removals; the AVX2 one (the default here) is checked against the assembled matrix in
// test_stiffness_kernel.cpp.
#include <catch2/catch.hpp>

#include <random>

#include "mesh/generate.h"
#include "sim/fem/stiffness_kernel.h"
#include "testing/mesh_edits.h"
#include "testing/draws.h"

using namespace incise;
using incise::testing::draw_quaternion;

namespace {
Eigen::Matrix3d random_rotation(std::mt19937& rng) {
  std::normal_distribution<double> n;
  const Eigen::Quaterniond q = draw_quaternion(n, rng);
  return q.normalized().toRotationMatrix();
}

void compare_paths(const TetMesh& m, bool corot, std::uint32_t seed) {
  StiffnessKernel simd(corot), portable(corot);
  portable.set_simd(false);
  simd.configure(m);
  portable.configure(m);
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  for (TetId t : m.tets()) {
    const auto& tv = m.tet_vertices(t);
    const std::array<std::uint32_t, 4> v{tv[0].idx(), tv[1].idx(), tv[2].idx(), tv[3].idx()};
    Eigen::Matrix3d e;
    for (int j = 0; j < 3; ++j) e.col(j) = m.rest(tv[std::size_t(j) + 1]) - m.rest(tv[0]);
    const Eigen::Matrix3d bm = e.inverse();
    const double vmu = 1 + u(rng) * 0.5, vl = 2 + u(rng);
    simd.add(m, t.idx(), v, bm, vmu, vl);
    portable.add(m, t.idx(), v, bm, vmu, vl);
    if (corot) {
      const Eigen::Matrix3d r = random_rotation(rng);
      simd.set_rotation(t.idx(), r);
      portable.set_rotation(t.idx(), r);
    }
  }
  // Remove a few (swaps the last tet of a block into the slot; packets keep zeroed lanes).
  int k = 0;
  for (TetId t : m.tets())
    if (++k % 7 == 0) {
      simd.remove(t.idx());
      portable.remove(t.idx());
    }
  const Eigen::Index rows = Eigen::Index(3 * m.vertex_capacity());
  Eigen::VectorXd x(rows), y1, y2;
  for (Eigen::Index i = 0; i < rows; ++i) x[i] = u(rng);
  simd.multiply(x, y1, rows);
  portable.multiply(x, y2, rows);
  REQUIRE(y1.size() == rows);
  REQUIRE(y2.size() == rows);
  CHECK((y1 - y2).norm() <= 1e-12 * y2.norm());
  CHECK(y2.norm() > 0);
}
}  // namespace

TEST_CASE("the AVX2 and portable kernels give the same product", "[sim][kernel]") {
  for (bool corot : {false, true}) {
    TetMesh small = make_box(Vec3(1, 2, 1), {3, 5, 2});  // serial path, partial packets
    compare_paths(small, corot, 1);
    TetMesh big = make_box(Vec3(4, 1, 1), {40, 10, 10});  // 24k tets: threaded, coloured slabs
    testing::jitter(big, 0.3, 5);
    compare_paths(big, corot, 2);
  }
}
