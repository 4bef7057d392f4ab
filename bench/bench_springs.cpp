// Spring-mass backend benchmarks; every figure is a ratio against a baseline measured in the
// same run (absolute times on a shared machine are noise).
//  1. step cost per integrator relative to symplectic Euler (same mesh, same state);
//  2. estimated stable time step against mesh resolution (expected ~ h);
//  3. local update (apply one TopologyChange) vs a full rebuild after k edited tets in an
//     N-tet mesh;
//  1b. step cost per spring configuration (volume term, stiffness rule, viscosity, stiffening)
//     relative to the default, with each one's stable step, so the cost of a simulated second;
//  4. what each volume term makes of the material (docs/solver.md#spring-volume-terms): the
//     effective Young's modulus and Poisson's ratio of a bar in tension, and a cantilever's tip
//     deflection against Timoshenko's, per mesh pattern and resolution, with corotational
//     nodal-averaged FEM on the same meshes as the baseline.
// Usage: bench_springs [--quick] [--only moduli|configurations|updates]
//        INCISE_BENCH_FACE_SHARE=S: the moduli rows "+faces" with SpringOptions::face_share = S
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <vector>

#include "bench/bench_common.h"
#include "mesh/generate.h"
#include "mesh/tet_mesh.h"
#include "sim/fem/fem_simulation.h"
#include "sim/springs/spring_model.h"
#include "testing/draws.h"
#include "testing/mesh_edits.h"
#ifdef INCISE_HAVE_TETRA
#include "mesh/io/surface.h"
#include "mesh/tetrahedralize/tetrahedralize.h"
#endif

using namespace incise;
using incise::testing::draw_vec3;

namespace {

double now_ms() {
  using namespace std::chrono;
  return duration<double, std::milli>(steady_clock::now().time_since_epoch()).count();
}

MaterialTable soft_tissue() { return MaterialTable(Material{3e3, 0.45, 1000}); }

void perturb(SpringModel& s, const TetMesh& m, double amount) {
  std::mt19937 rng(1);
  std::uniform_real_distribution<double> u(-amount, amount);
  for (VertexId v : m.vertices()) s.set_position(v, m.rest(v) + draw_vec3(u, rng));
}

// Refinement and flip edits around random tets (no removals: they keep the mesh a solid).
int edit_tets(TetMesh& m, std::mt19937& rng, int k) {
  std::uniform_int_distribution<std::uint32_t> pick(0, static_cast<std::uint32_t>(m.tet_capacity() - 1));
  int done = 0;
  while (done < k) {
    TetId t(pick(rng));
    if (!m.is_alive(t)) continue;
    auto v = m.tet_vertices(t);
    switch (rng() % 4) {
      case 0: m.split_edge(v[0], v[1], 0.4); break;
      case 1: m.split_face(t, static_cast<int>(rng() % 4)); break;
      case 2: m.split_tet(t); break;
      default: {
        const int f = static_cast<int>(rng() % 4);
        if (!m.is_flip23_ok(t, f)) continue;
        m.flip23(t, f);
      }
    }
    ++done;
  }
  return done;
}

// Static equilibrium of a model under per-vertex forces with the vertices at x = 0 held:
// springs by implicit Euler with a huge step (each step a Newton step), FEM by its static solve.
// Returns the displacement per vertex slot. model: "tet", "nodal" (share 1), "none" (the volume
// term, Van Gelder's constants, edges), the same with "-fit" (SpringStiffness::Fitted) or
// "+faces" (springs across faces), "default" (SpringOptions' defaults) or "fem".
std::vector<Vec3> equilibrium(const TetMesh& m, const Material& mat, const std::string& model,
                              const std::vector<std::pair<VertexId, Vec3>>& forces,
                              bool (*held)(const Vec3&) = [](const Vec3& p) { return p.x() < 1e-9; }) {
  std::vector<Vec3> u(m.vertex_capacity(), Vec3::Zero());
  const bool fit = model.size() > 4 && model.compare(model.size() - 4, 4, "-fit") == 0;
  const bool faces = model.size() > 6 && model.compare(model.size() - 6, 6, "+faces") == 0;
  const std::string volume = fit ? model.substr(0, model.size() - 4) : faces ? model.substr(0, model.size() - 6) : model;
  if (volume == "fem") {
    FemSimulationOptions o;
    o.kind = FemKind::Corotational;
    o.formulation = Formulation::NodalAveraged;
    o.nonlinear_iterations = 3;
    o.cg.tolerance = 1e-10;
    FemSimulation fem(m, MaterialTable(mat), o);
    for (VertexId v : m.vertices())
      if (held(m.rest(v))) fem.fix(v);
    for (const auto& [v, f] : forces) fem.set_force(v, f);
    for (int k = 0; k < 3; ++k) fem.step();
    for (VertexId v : m.vertices()) u[v.idx()] = fem.displacement().segment<3>(3 * v.idx());
    return u;
  }
  SpringOptions o;  // "default": SpringOptions' own
  if (model != "default") {
    o.volume_term = volume != "none";
    o.nodal_volume = volume == "nodal";
    o.nodal_share = 1;
    o.stiffness = fit ? SpringStiffness::Fitted : SpringStiffness::VanGelder;
    o.across_faces = faces;
  }
  if (const char* share = std::getenv("INCISE_BENCH_FACE_SHARE")) o.face_share = std::atof(share);
  o.cg_tolerance = 1e-12;
  o.cg_max_iterations = 50000;
  o.compute_energy = false;
  SpringModel s(m, MaterialTable(mat), o);
  for (VertexId v : m.vertices())
    if (held(m.rest(v))) s.set_fixed(v, true);
  for (const auto& [v, f] : forces) s.set_external_force(v, f);
  for (int k = 0; k < 8; ++k) s.step(1e6, Integrator::ImplicitEuler);
  for (VertexId v : m.vertices()) u[v.idx()] = s.positions()[v.idx()] - m.rest(v);
  return u;
}

// Mean of f(u, rest) over the vertices whose rest position passes `in`.
template <class In, class F>
double mean_over(const TetMesh& m, const std::vector<Vec3>& u, In in, F f) {
  double sum = 0;
  int n = 0;
  for (VertexId v : m.vertices())
    if (in(m.rest(v))) sum += f(u[v.idx()]), ++n;
  return n ? sum / n : 0.0;
}

// 1b. What each spring configuration costs: a symplectic Euler step (the scenes' default
// integrator) and an implicit Euler step at 10x the stable step, relative to the default
// configuration in the same run, on a jittered box (a structured one has every tet alike), and
// the explicit stable step each one allows; per simulated second the explicit cost is ms/step
// over dt.
void configuration_costs(bool quick) {
  const int n = quick ? 10 : 20;
  TetMesh m = make_box(Vec3(0.1, 0.1, 0.1), {n, n, n});
  testing::jitter(m, 0.2, 5);
  m.discard_change();
  struct Config {
    const char* name;
    SpringOptions o;
  };
  std::vector<Config> configs;
  SpringOptions base;
  base.damping = 2.0;
  base.compute_energy = false;
  base.cg_tolerance = 1e-6;
  // Each configuration spelled out (volume term, its nodal share, connectivity, stiffness).
  auto with = [&](bool volume, bool nodal, double share, bool faces, bool fitted) {
    SpringOptions o = base;
    o.volume_term = volume;
    o.nodal_volume = nodal;
    o.nodal_share = share;
    o.across_faces = faces;
    o.stiffness = fitted ? SpringStiffness::Fitted : SpringStiffness::VanGelder;
    return o;
  };
  configs.push_back({"default: nodal 0.9+faces", base});
  configs.push_back({"volume tet, edges", with(true, false, 1, false, false)});
  configs.push_back({"nodal 1, edges", with(true, true, 1, false, false)});
  configs.push_back({"nodal 0.9, edges", with(true, true, 0.9, false, false)});
  configs.push_back({"no volume, edges", with(false, false, 1, false, false)});
  configs.push_back({"tet, edges, fitted", with(true, false, 1, false, true)});
  configs.push_back({"nodal 0.9, edges, fitted", with(true, true, 0.9, false, true)});
  configs.push_back({"tet, across faces", with(true, false, 1, true, false)});
  configs.push_back({"nodal 1, across faces", with(true, true, 1, true, false)});
  SpringOptions o = with(true, true, 1, true, false);
  o.inversion_guard = 0.25;
  configs.push_back({"nodal 1+faces, guard 0.25", o});
  o = base;
  o.viscosity = 1e-3;
  configs.push_back({"viscosity 1e-3 s", o});
  o = base;
  o.stiffening = 8;
  configs.push_back({"stiffening 8", o});
  std::printf("== step cost per spring configuration, %zu tets (jittered box; relative to the default)\n", m.num_tets());
  std::printf("%-26s %12s %8s %12s %8s %14s %10s %12s\n", "configuration", "explicit ms", "ratio", "dt_stable",
              "dt/def", "ms/sim-second", "ratio", "implicit ms");
  double base_ms = 0, base_dt = 0, base_implicit = 0, implicit_dt = 0;
  for (const Config& c : configs) {
    SpringModel s(m, soft_tissue(), c.o);
    perturb(s, m, 1e-4);
    const double dt = 0.5 * s.stable_time_step(Integrator::SymplecticEuler);
    if (implicit_dt == 0) implicit_dt = 10 * dt;  // the default's, for every configuration
    const int steps = quick ? 50 : 200;
    s.step(dt, Integrator::SymplecticEuler);  // warm-up
    double t0 = now_ms();
    for (int i = 0; i < steps; ++i) s.step(dt, Integrator::SymplecticEuler);
    const double per = (now_ms() - t0) / steps;
    SpringModel si(m, soft_tissue(), c.o);
    perturb(si, m, 1e-4);
    const int isteps = quick ? 5 : 15;
    t0 = now_ms();
    for (int i = 0; i < isteps; ++i) si.step(implicit_dt, Integrator::ImplicitEuler);
    const double implicit = (now_ms() - t0) / isteps;
    const double stable = s.stable_time_step(Integrator::SymplecticEuler);
    if (base_ms == 0) base_ms = per, base_dt = stable, base_implicit = implicit;
    const double per_second = per / stable, base_second = base_ms / base_dt;
    std::printf("%-26s %12.3f %8.2f %12.3e %8.2f %14.1f %10.2f %12.3f (%.2f)\n", c.name, per, per / base_ms, stable,
                stable / base_dt, per_second, per_second / base_second, implicit, implicit / base_implicit);
  }
  std::printf("(explicit: symplectic Euler at half the stable step; implicit Euler at 10x the default's half; "
              "ms/sim-second at the stable step)\n\n");
}

// The affine map that fits u over the vertices whose rest position passes `in` (least squares):
// its gradient, the strain of a body that is not meshed in planes of vertices.
template <class In>
Eigen::Matrix3d fitted_gradient(const TetMesh& m, const std::vector<Vec3>& u, In in) {
  Eigen::Matrix4d ata = Eigen::Matrix4d::Zero();
  Eigen::Matrix<double, 4, 3> atb = Eigen::Matrix<double, 4, 3>::Zero();
  for (VertexId v : m.vertices()) {
    const Vec3 p = m.rest(v);
    if (!in(p)) continue;
    const Eigen::Vector4d a(p.x(), p.y(), p.z(), 1);
    ata += a * a.transpose();
    atb += a * u[v.idx()].transpose();
  }
  const Eigen::Matrix<double, 4, 3> x = ata.ldlt().solve(atb);
  return x.topRows<3>().transpose();  // (i, j): du_i / dp_j
}

#ifdef INCISE_HAVE_TETRA
// A box [0, size] meshed by CGAL's Delaunay refinement (incise tetra's engine), tets of about
// edge h, its edges kept as features: the unstructured pattern of issue 41's moduli tests.
TetMesh cgal_box(const Vec3& size, double h) {
  SurfaceMesh box;
  for (int i = 0; i < 8; ++i) box.vertices.push_back(Vec3((i & 1) * size.x(), (i >> 1 & 1) * size.y(), (i >> 2 & 1) * size.z()));
  box.triangles = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                   {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  TetraOptions o;
  o.size = Length{0.612 * h, false};  // a regular tet's circumradius over its edge
  o.features_angle = 60;
  return tetrahedralize_surface(box, o);
}
#endif

void effective_moduli(bool quick) {
  const Material mat{1e4, 0.45, 1000};
  std::printf("== what each volume term makes of E = 1e4, nu = 0.45: a 4x1x1 bar pulled (strain 1e-4), and\n"
              "   an 8x1x1 cantilever's tip under a load (deflection over Timoshenko's, which FEM's converges to)\n");
  std::printf("%-10s %5s %8s %-9s %10s %10s %10s %14s\n", "pattern", "cells", "tets", "model", "E_eff/E", "nu_eff",
              "G_eff/G", "tip/Timoshenko");
  std::vector<std::string> patterns = {"kuhn", "mirrored", "jittered"};
#ifdef INCISE_HAVE_TETRA
  patterns.push_back("cgal");
#endif
  for (const std::string& pattern : patterns) {
    const bool unstructured = pattern == "cgal";
    for (int n : {1, 2, 4}) {
      if (quick && n > 2) break;
      auto mesh = [&](const Vec3& size, std::array<int, 3> cells) {
#ifdef INCISE_HAVE_TETRA
        if (unstructured) return cgal_box(size, 1.0 / n);
#endif
        TetMesh m = make_box(size, cells, 1, pattern == "mirrored" ? BoxSplit::Mirrored : BoxSplit::Kuhn);
        if (pattern == "jittered") incise::testing::jitter(m, 0.3, 11);
        return m;
      };
      const TetMesh bar = mesh(Vec3(4, 1, 1), {4 * n, n, n}), beam = mesh(Vec3(8, 1, 1), {8 * n, n, n});
      for (const char* model : {"default", "tet", "tet-fit", "tet+faces", "nodal", "nodal-fit", "nodal+faces", "none", "none-fit", "fem"}) {
        // Tension: force E * 1e-4 over the end face's vertices.
        std::vector<std::pair<VertexId, Vec3>> pull, load;
        std::vector<VertexId> end;
        for (VertexId v : bar.vertices())
          if (bar.rest(v).x() > 4 - 1e-9) end.push_back(v);
        for (VertexId v : end) pull.push_back({v, Vec3(mat.young * 1e-4 / double(end.size()), 0, 0)});
        const auto ub = equilibrium(bar, mat, model, pull);
        auto mid = [](double x0, double x1) { return [=](const Vec3& p) { return p.x() > x0 - 1e-9 && p.x() < x1 + 1e-9; }; };
        // Strains over the middle half, x in [1, 3]: between its end planes of vertices and across
        // its side faces on the structured patterns; on CGAL's, which has no inner planes of
        // vertices, the gradient of the affine map that fits the displacements there.
        double ex = (mean_over(bar, ub, [](const Vec3& p) { return std::abs(p.x() - 3) < 1e-9; },
                                     [](const Vec3& d) { return d.x(); }) -
                           mean_over(bar, ub, [](const Vec3& p) { return std::abs(p.x() - 1) < 1e-9; },
                                     [](const Vec3& d) { return d.x(); })) / 2;
        double ey =
            mean_over(bar, ub, [&](const Vec3& p) { return mid(1, 3)(p) && p.y() > 1 - 1e-9; }, [](const Vec3& d) { return d.y(); }) -
            mean_over(bar, ub, [&](const Vec3& p) { return mid(1, 3)(p) && p.y() < 1e-9; }, [](const Vec3& d) { return d.y(); });
        if (unstructured) {
          const Eigen::Matrix3d g = fitted_gradient(bar, ub, mid(1, 3));
          ex = g(0, 0);
          ey = g(1, 1);
        }
        // Bending: a small total load at the tip (the deflection a few thousandths of the length).
        const double F = 1e-3 * mat.young / 8;
        end.clear();
        for (VertexId v : beam.vertices())
          if (beam.rest(v).x() > 8 - 1e-9) end.push_back(v);
        for (VertexId v : end) load.push_back({v, Vec3(0, 0, -F / double(end.size()))});
        const auto uc = equilibrium(beam, mat, model, load);
        // Shear: a 4x4x1 slab held at z = 0, its top pulled along x by tau = 1e-4 G; the shear
        // strain from the top's mean displacement over its middle quarter.
        const TetMesh slab = mesh(Vec3(4, 4, 1), {4 * n, 4 * n, n});
        const double G = mat.young / (2 * (1 + mat.poisson)), tau = 1e-4 * G;
        std::vector<VertexId> top;
        for (VertexId v : slab.vertices())
          if (slab.rest(v).z() > 1 - 1e-9) top.push_back(v);
        std::vector<std::pair<VertexId, Vec3>> shear;
        for (VertexId v : top) shear.push_back({v, Vec3(tau * 16 / double(top.size()), 0, 0)});
        const auto us = equilibrium(slab, mat, model, shear, [](const Vec3& p) { return p.z() < 1e-9; });
        const double gamma = mean_over(slab, us, [](const Vec3& p) {
          return p.z() > 1 - 1e-9 && std::abs(p.x() - 2) < 1 + 1e-9 && std::abs(p.y() - 2) < 1 + 1e-9; },
                                       [](const Vec3& d) { return d.x(); });
        const double tip = -mean_over(beam, uc, [](const Vec3& p) { return p.x() > 8 - 1e-9; }, [](const Vec3& d) { return d.z(); });
        const double timoshenko = F * 512 / (3 * mat.young / 12) + F * 8 / (5.0 / 6 * G);
        std::printf("%-10s %5d %8zu %-9s %10.3f %10.3f %10.3f %14.3f\n", pattern.c_str(), n, bar.num_tets(), model,
                    1e-4 / ex, -ey / ex, 1e-4 / gamma, tip / timoshenko);
        std::fflush(stdout);
      }
    }
  }
  std::printf("(cells: across the section; tets: the bar's. jittered: Kuhn tets, interior vertices moved up to\n"
              " 0.3 of their shortest edge; cgal: CGAL's Delaunay refinement of the box, tets of about the\n"
              " cells' edge, its strains fitted)\n\n");
}

}  // namespace

// 3. Local update (apply one change) against a rebuild, with the default configuration.
void local_updates(bool quick) {
  {
    std::printf("== local update vs full rebuild after k edited tets\n");
    std::printf("%10s %6s %14s %14s %12s %14s\n", "N tets", "k", "update [ms]", "rebuild [ms]", "ratio", "visits/update");
    std::vector<int> sizes = quick ? std::vector<int>{8, 16} : std::vector<int>{12, 24, 48};
    for (int n : sizes) {
      TetMesh m = make_box(Vec3(1, 1, 1), {n, n, n});
      SpringModel s(m, soft_tissue());
      std::mt19937 rng(7);
      for (int k : {1, 10, 100}) {
        // Several repetitions of the update (cheap) against one rebuild (expensive).
        const int reps = 20;
        double t_update = 0;
        s.reset_counters();
        for (int r = 0; r < reps; ++r) {
          edit_tets(m, rng, k);
          TopologyChange ch = m.take_change();
          const double t0 = now_ms();
          s.apply(m, ch);
          t_update += now_ms() - t0;
        }
        t_update /= reps;
        const double visits = double(s.counters().visits) / double(s.counters().updates);
        const double t0 = now_ms();
        SpringModel fresh(m, soft_tissue());
        const double t_rebuild = now_ms() - t0;
        std::printf("%10zu %6d %14.4f %14.2f %12.0f %14.0f\n", m.num_tets(), k, t_update, t_rebuild,
                    t_rebuild / t_update, visits);
      }
    }
  }
}

int main(int argc, char** argv) {
  const bench::Args args(argc, argv);  // --help: where the options are written
  const bool quick = args.flag("--quick");
  if (args.get("--only", "") == "configurations") {
    configuration_costs(quick);
    return 0;
  }
  if (args.get("--only", "") == "updates") {
    local_updates(quick);
    return 0;
  }
  if (args.get("--only", "") == "moduli") {
    effective_moduli(false);
    return 0;
  }

  // ---- 1. step cost per integrator ---------------------------------------------------------
  {
    const int n = quick ? 10 : 20;
    TetMesh m = make_box(Vec3(0.1, 0.1, 0.1), {n, n, n});
    std::printf("== step cost per integrator, %zu tets, %zu vertices (relative to symplectic Euler)\n",
                m.num_tets(), m.num_vertices());
    std::printf("%-18s %10s %12s %10s %14s\n", "integrator", "dt/dt_s", "ms/step", "ratio", "CG it/step");
    double base = 0;
    for (Integrator integ : {Integrator::SymplecticEuler, Integrator::ExplicitEuler, Integrator::Verlet,
                             Integrator::ImplicitEuler}) {
      SpringOptions o;
      o.damping = 2.0;
      o.compute_energy = false;
      o.cg_tolerance = 1e-6;
      SpringModel s(m, soft_tissue(), o);
      perturb(s, m, 1e-4);
      const bool implicit = integ == Integrator::ImplicitEuler;
      const double factor = implicit ? 10.0 : 0.5;
      const double dt = factor * (integ == Integrator::ExplicitEuler ? s.stable_time_step(integ) : s.stable_time_step());
      const int steps = implicit ? (quick ? 10 : 30) : (quick ? 50 : 200);
      s.step(dt, integ);  // warm-up
      long cg = 0;
      const double t0 = now_ms();
      for (int i = 0; i < steps; ++i) cg += s.step(dt, integ).cg_iterations;
      const double per = (now_ms() - t0) / steps;
      if (integ == Integrator::SymplecticEuler) base = per;
      std::printf("%-18s %10.2f %12.3f %10.2f %14.1f\n", integrator_name(integ), factor, per, per / base,
                  double(cg) / steps);
    }
    std::printf("(implicit Euler at 10x the stable step; explicit Euler at 0.5x its own, damped, limit)\n\n");
  }

  configuration_costs(quick);

  // ---- 2. stable time step vs resolution -----------------------------------------------------
  {
    std::printf("== estimated stable time step vs mesh resolution (unit cube, E 3 kPa, nu 0.45)\n");
    std::printf("%8s %10s %14s %14s %14s\n", "cells", "h", "dt_stable [s]", "dt/dt(h0)", "h/h0");
    double dt0 = 0, h0 = 0;
    for (int n : {4, 8, 16, 32}) {
      if (quick && n > 16) break;
      TetMesh m = make_box(Vec3(1, 1, 1), {n, n, n});
      SpringModel s(m, soft_tissue());
      const double h = 1.0 / n, dt = s.stable_time_step();
      if (n == 4) dt0 = dt, h0 = h;
      std::printf("%8d %10.4f %14.4e %14.4f %14.4f\n", n, h, dt, dt / dt0, h / h0);
    }
    for (double nu : {0.3, 0.45, 0.49, 0.499}) {
      TetMesh m = make_box(Vec3(1, 1, 1), {8, 8, 8});
      SpringModel s(m, MaterialTable(Material{3e3, nu, 1000}));
      std::printf("   nu %.3f (8^3 cells): dt_stable %.4e s\n", nu, s.stable_time_step());
    }
    std::printf("\n");
  }

  local_updates(quick);
  return 0;
}
