// Quadratic tets and Taylor-Hood through FemSimulation against outside answers: Timoshenko's
// cantilever, Cook's membrane's converged tip (testing/elasticity_cases.h), Taylor-Hood
// at Poisson's ratio 0.4999 and 0.5, corotational and implicit Euler against the static solve.
#include <catch2/catch.hpp>

#include <cmath>
#include <vector>

#include "mesh/generate.h"
#include "sim/fem/fem_simulation.h"
#include "sim/fem/quadratic_solver.h"
#include "testing/elasticity_cases.h"

using namespace incise;

namespace {

constexpr double kLen = 8, kH = 1, kE = 1e6, kLoad = -10;

double timoshenko_tip(double nu) {
  const double inertia = kH * kH * kH * kH / 12, area = kH * kH, g = kE / (2 * (1 + nu));
  const double kappa = 10 * (1 + nu) / (12 + 11 * nu);
  return kLoad * kLen * kLen * kLen / (3 * kE * inertia) + kLoad * kLen / (kappa * g * area);
}

FemSimulationOptions direct(Formulation f, FemKind kind = FemKind::Linear) {
  FemSimulationOptions o;
  o.formulation = f;
  o.kind = kind;
  o.method = SolverMethod::Direct;
  return o;
}

// The cantilever L x h x h (8 n x n x n cells) clamped at x = 0, a shear traction (kLoad times
// `scale` in all) on the tip face; returns the mean displacement of the tip face's vertices.
Vec3 cantilever_tip_vector(int n, double nu, const FemSimulationOptions& opt, double scale = 1,
                           FrameStats* stats = nullptr) {
  const TetMesh m = make_box(Vec3(kLen, kH, kH), {int(kLen) * n, n, n});
  FemSimulation sim(m, MaterialTable(Material{kE, nu, 1000}), opt);
  for (VertexId v : m.vertices())
    if (m.rest(v).x() < 1e-9) sim.fix(v);
  for (const BoundaryFace& f : m.boundary_faces()) {
    bool tip = true;
    for (VertexId v : f.vertices) tip = tip && m.rest(v).x() > kLen - 1e-9;
    if (tip) sim.add_face_traction(f.vertices[0], f.vertices[1], f.vertices[2], Vec3(0, 0, scale * kLoad / (kH * kH)));
  }
  const FrameStats st = sim.step();
  if (stats) *stats = st;
  REQUIRE(st.info == SolveInfo::Success);
  Vec3 tip = Vec3::Zero();
  int count = 0;
  for (VertexId v : m.vertices())
    if (m.rest(v).x() > kLen - 1e-9) tip += sim.displacement().segment<3>(3 * Eigen::Index(v.idx())), ++count;
  return tip / count;
}

// Its mean u_z.
double cantilever_tip(int n, double nu, const FemSimulationOptions& opt, FrameStats* stats = nullptr) {
  return cantilever_tip_vector(n, nu, opt, 1, stats).z();
}

}  // namespace

TEST_CASE("quadratic cantilever converges to Timoshenko, Taylor-Hood does not lock", "[quadratic]") {
  // The clamped face holds the lateral contraction beam theory leaves free, so the 3D answer is
  // a little stiffer than Timoshenko's, more so towards nu = 0.5 (docs/solver.md#quadratic-tets
  // has the table to 32 x 4 x 4 cells).
  for (const double nu : {0.3, 0.4999}) {
    const double theory = timoshenko_tip(nu);
    const double e1 = std::abs(cantilever_tip(1, nu, direct(Formulation::Quadratic)) / theory - 1);
    const double e2 = std::abs(cantilever_tip(2, nu, direct(Formulation::Quadratic)) / theory - 1);
    const double t1 = std::abs(cantilever_tip(1, nu, direct(Formulation::MixedQuadratic)) / theory - 1);
    const double t2 = std::abs(cantilever_tip(2, nu, direct(Formulation::MixedQuadratic)) / theory - 1);
    INFO("nu " << nu << ": P2 " << e1 << " -> " << e2 << ", Taylor-Hood " << t1 << " -> " << t2);
    // One element through the thickness, then two.
    CHECK(t1 < 0.09);
    CHECK(t2 < 0.045);
    CHECK(t2 < 0.6 * t1);
    CHECK(e2 < 0.6 * e1);
    if (nu == 0.3) CHECK(e2 < 0.02);
    else CHECK(e1 > 1.5 * t1);  // P2 alone still locks at 0.4999, Taylor-Hood does not
  }
  // Taylor-Hood at 0.5 is the limit of 0.4999.
  const double a = cantilever_tip(1, 0.4999, direct(Formulation::MixedQuadratic));
  const double b = cantilever_tip(1, 0.5, direct(Formulation::MixedQuadratic));
  CHECK(a == Approx(b).epsilon(1e-3));
}

TEST_CASE("quadratic solvers agree: direct, CG and MINRES with each preconditioner", "[quadratic]") {
  for (const Formulation f : {Formulation::Quadratic, Formulation::MixedQuadratic}) {
    const double ref = cantilever_tip(1, 0.45, direct(f));
    for (const Preconditioner pc : {Preconditioner::Jacobi, Preconditioner::BlockJacobi, Preconditioner::Cholesky}) {
      FemSimulationOptions o = direct(f);
      o.method = SolverMethod::Cg;
      o.cg.preconditioner = pc;
      o.cg.tolerance = f == Formulation::MixedQuadratic ? 1e-10 : 1e-12;  // MINRES: the true residual, in its norm
      o.cg.max_iterations = 50000;
      FrameStats st;
      INFO(formulation_name(f) << " " << to_string(pc));
      CHECK(cantilever_tip(1, 0.45, o, &st) == Approx(ref).epsilon(1e-8));
      CHECK(st.iterations > 0);
    }
  }
}

TEST_CASE("quadratic Cook's membrane converges to the published tip displacement", "[quadratic]") {
  // The tip u_y(48, 60) for E = 70, force 100; its converged value is 32.263 at nu = 1/3
  // (elasticity_cases.h; CalculiX's fine quadratic mesh: 32.27).
  // The corner (0, 44) is singular: the observed order is about 1.4-1.5 (elasticity_cases.h),
  // whatever the element's own order; P2 must reach it.
  const double ref = incise::testing::cook_reference_tip(1.0 / 3);
  std::vector<double> err;
  for (const int cells : {2, 4, 8}) {
    const auto r = incise::testing::run_cook(cells, 70, 1.0 / 3, 100, direct(Formulation::Quadratic));
    err.push_back(std::abs(r.tip / ref - 1));
    INFO(cells << " cells: tip " << r.tip << ", error " << err.back());
    CHECK(r.tip < ref);  // displacement elements are too stiff
  }
  INFO("errors " << err[0] << " " << err[1] << " " << err[2]);
  CHECK(std::log2(err[1] / err[2]) > 1.2);
  CHECK(std::log2(err[0] / err[1]) > 1.2);
  CHECK(err[2] < 0.025);
}

TEST_CASE("quadratic corotational equals linear under small loads and stays bounded under large ones", "[quadratic]") {
  for (const Formulation f : {Formulation::Quadratic, Formulation::MixedQuadratic}) {
    const double lin = cantilever_tip(1, 0.45, direct(f));
    FemSimulationOptions co = direct(f, FemKind::Corotational);
    co.nonlinear_iterations = 4;
    const double rot = cantilever_tip(1, 0.45, co);
    INFO(formulation_name(f) << ": linear " << lin << ", corotational " << rot);
    // A tip deflection of 0.26 % of the length: the two differ by far less than that.
    CHECK(rot == Approx(lin).epsilon(2e-3));
    // 100 times the load: a linear tip moves straight down, off the circle a bending beam's tip
    // follows; corotational tets keep the beam's length, so the tip also comes back along x.
    co.nonlinear_iterations = 30;
    const Vec3 big_lin = cantilever_tip_vector(1, 0.45, direct(f), 100);
    const Vec3 big_rot = cantilever_tip_vector(1, 0.45, co, 100);
    INFO("100x: linear " << big_lin.transpose() << ", corotational " << big_rot.transpose());
    CHECK(std::abs(big_lin.x()) < 1e-3 * std::abs(big_lin.z()));
    CHECK(big_rot.allFinite());
    CHECK(big_rot.x() < -0.05 * std::abs(big_rot.z()));
    CHECK(std::abs(big_rot.z()) == Approx(std::abs(big_lin.z())).epsilon(0.1));  // a quarter of the length down
  }
}

TEST_CASE("quadratic implicit Euler comes to rest at the static solution", "[quadratic]") {
  for (const Formulation f : {Formulation::Quadratic, Formulation::MixedQuadratic}) {
    const TetMesh m = make_box(Vec3(4, 1, 1), {4, 1, 1});
    // The first bending mode's omega is about 6 rad/s: damping 10 decays it by e^-5 a second.
    const Material mat{1e7, 0.4, 1000};
    FemSimulationOptions st = direct(f), dy = direct(f);
    dy.dynamic = true;
    dy.dt = 0.01;
    dy.damping = 10;
    FemSimulation s(m, MaterialTable(mat), st), d(m, MaterialTable(mat), dy);
    for (FemSimulation* sim : {&s, &d}) {
      for (VertexId v : m.vertices())
        if (m.rest(v).x() < 1e-9) sim->fix(v);
      sim->set_gravity(Vec3(0, 0, -9.81));
    }
    s.step();
    double first = 0;
    for (int k = 0; k < 600; ++k) {
      d.step();
      if (k == 0) first = (d.quadratic_displacement() - s.quadratic_displacement()).norm();
    }
    INFO(formulation_name(f));
    CHECK(first > 0.5 * s.quadratic_displacement().norm());  // it starts at rest, far from the static shape
    CHECK((d.quadratic_displacement() - s.quadratic_displacement()).norm() <= 1e-6 * s.quadratic_displacement().norm());
  }
}

TEST_CASE("quadratic cantilever table", "[.quadratic-report]") {
  for (const double nu : {0.3, 0.45, 0.4999})
    for (const Formulation f : {Formulation::Quadratic, Formulation::MixedQuadratic})
      for (int n = 1; n <= 4; ++n)
        std::printf("nu %g %s n %d: %+.4f%%\n", nu, std::string(formulation_name(f)).c_str(), n,
                    100 * (cantilever_tip(n, nu, direct(f)) / timoshenko_tip(nu) - 1));
}
