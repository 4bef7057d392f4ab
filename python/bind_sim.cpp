// Simulation: Material(s), FemSimulation (static / dynamic FEM, CG statistics per step),
// SpringSimulation (spring-mass), scenes (load_scene, run_scene). A simulation keeps its
// mesh alive and reads it; vertex arguments are ids, one or many.
#include "python/bindings.h"

#include <filesystem>
#include <limits>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "quality/improve_checks.h"
#include "scene/run_directory.h"
#include "scene/run_scene.h"
#include "sim/fem/fem_simulation.h"
#include "sim/fem/quadratic_solver.h"
#include "sim/linalg/preconditioner.h"
#include "sim/fem/mixed_solver.h"
#include "sim/springs/spring_model.h"

namespace incise::python {

namespace {

template <class E>
E parse_choice(const std::string& what, const std::string& s, std::initializer_list<std::pair<const char*, E>> choices) {
  std::string names;
  for (const auto& [n, e] : choices) {
    if (s == n) return e;
    names += std::string(names.empty() ? "" : ", ") + n;
  }
  throw InvalidArgument(what + ": unknown value '" + s + "' (expected " + names + ")");
}

// A Material (every label), a {label: Material} dict (a "*" key: every label not listed;
// without one, a label of the mesh missing from the dict is an error), or a table. Poisson's
// ratio 0.5 passes here (the mixed formulation takes it); the models that cannot refuse it.
MaterialTable to_materials(const py::object& o) {
  if (o.is_none()) return MaterialTable();
  if (py::isinstance<MaterialTable>(o)) return o.cast<MaterialTable>();
  if (py::isinstance<Material>(o)) {
    const Material m = o.cast<Material>();
    check_material(m, "materials", true);
    return MaterialTable(m);
  }
  if (py::isinstance<py::dict>(o)) {
    MaterialTable t;
    t.clear_default();
    for (auto [k, v] : o.cast<py::dict>()) {
      const std::string key = py::str(k).cast<std::string>();
      if (!py::isinstance<Material>(v))
        throw InvalidArgument("materials[" + key + "]: expected a Material, got " +
                              py::str(py::type::of(v).attr("__name__")).cast<std::string>());
      const Material m = v.cast<Material>();
      if (py::isinstance<py::str>(k) && key == "*") {
        check_material(m, "materials[*]", true);
        t.set_default(m);
        continue;
      }
      if (!py::isinstance<py::int_>(k) || py::isinstance<py::bool_>(k))
        throw InvalidArgument("materials: key " + py::repr(k).cast<std::string>() +
                              ": expected an integer region label or \"*\"");
      const long long label = k.cast<long long>();
      if (label < std::numeric_limits<int>::min() || label > std::numeric_limits<int>::max())
        throw InvalidArgument("materials: label " + key + " is out of range (a label is a 32-bit integer)");
      check_material(m, "materials[" + key + "]", true);
      t.set(static_cast<int>(label), m);
    }
    return t;
  }
  throw InvalidArgument("materials: expected a Material, a {label: Material} dict or a MaterialTable");
}

// True or False (numpy's too), not any object with a truth value: volume_term=-1 is a mistake.
bool strict_bool(const py::handle& h, const char* what) {
  if (py::isinstance<py::bool_>(h)) return h.cast<bool>();
  const py::object np_bool = py::module_::import("numpy").attr("bool_");
  if (py::isinstance(h, np_bool)) return h.cast<bool>();
  throw InvalidArgument(std::string(what) + ": expected True or False, got " + py::repr(h).cast<std::string>());
}

// The mesh argument of a simulation or cutter (a clear error instead of pybind11's "Unable to
// cast Python instance").
TetMesh& mesh_of(const py::object& o, const char* what) {
  if (!py::isinstance<TetMesh>(o))
    throw InvalidArgument(std::string(what) + ": mesh: expected an incise.TetMesh, got " +
                          py::str(py::type::of(o).attr("__name__")).cast<std::string>());
  return o.cast<TetMesh&>();
}

// Snake-case names for programs (to_string() is the text for people, kept in "message").
const char* info_name(SolveInfo info) {
  switch (info) {
    case SolveInfo::Success: return "success";
    case SolveInfo::NoConvergence: return "no_convergence";
    case SolveInfo::BudgetExhausted: return "budget_exhausted";
    case SolveInfo::NotPositiveDefinite: return "not_positive_definite";
    case SolveInfo::NumericalIssue: return "numerical_issue";
  }
  return "unknown";
}

py::dict stats_dict(const FrameStats& s) {
  py::dict d;
  d["iterations"] = s.iterations;
  d["relative_residual"] = s.relative_residual;
  d["solve_ms"] = s.solve_ms;
  d["frame_ms"] = s.frame_ms;
  d["budget_exhausted"] = s.budget_exhausted;
  d["info"] = info_name(s.info);
  d["message"] = s.message.empty() ? std::string(to_string(s.info)) : s.message;
  return d;
}

py::dict step_dict(const StepStats& s) {
  py::dict d;
  d["dt"] = s.dt;
  d["stable_step_exceeded"] = s.stable_step_exceeded;
  d["cg_iterations"] = s.cg_iterations;
  d["cg_relative_residual"] = s.cg_relative_residual;
  d["kinetic_energy"] = s.kinetic_energy;
  d["potential_energy"] = s.potential_energy;
  return d;
}

// The simulation and the mesh it reads; the py::object keeps the mesh alive.
struct Fem {
  py::object mesh_ref;
  const TetMesh& mesh;
  FemSimulation sim;
};
struct Springs {
  py::object mesh_ref;
  const TetMesh& mesh;
  SpringModel model;
};

std::unique_ptr<Fem> make_fem(const py::object& mesh_obj, const py::object& materials, const std::string& kind,
                              const std::string& method, const std::string& backend, double tolerance,
                              int max_iterations, double budget_ms, const std::string& preconditioner,
                              bool warm_start, bool dynamic, double dt, double damping, int nonlinear_iterations,
                              const py::object& gravity, bool check_rigid_modes, const std::string& formulation,
                              double inversion_barrier, double barrier_stiffness, const std::string& petsc_options) {
  FemSimulationOptions o;
  o.inversion_barrier = {.j_min = inversion_barrier, .stiffness = barrier_stiffness};
  const auto f = parse_formulation(formulation);
  if (!f) throw InvalidArgument("formulation: expected " + std::string(kFormulationNames) + ", got \"" + formulation + "\"");
  o.formulation = *f;
  o.kind = parse_choice<FemKind>("kind", kind, {{"linear", FemKind::Linear}, {"corotational", FemKind::Corotational}});
  o.method = parse_choice<SolverMethod>("method", method, {{"cg", SolverMethod::Cg}, {"direct", SolverMethod::Direct}});
  o.backend = parse_choice<StiffnessBackend>(
      "backend", backend,
      {{"matrix-free", StiffnessBackend::MatrixFree}, {"assembled", StiffnessBackend::Assembled}, {"petsc", StiffnessBackend::Petsc}});
  o.petsc_options = petsc_options;
  o.cg.tolerance = tolerance;
  o.cg.max_iterations = max_iterations;
  o.cg.budget_ms = budget_ms;
  try {
    o.cg.preconditioner = parse_preconditioner(preconditioner);
  } catch (const InvalidArgument& e) {
    throw InvalidArgument(std::string("preconditioner: ") + e.what());
  }
  o.warm_start = warm_start;
  o.dynamic = dynamic;
  o.dt = dt;
  o.damping = damping;
  o.nonlinear_iterations = nonlinear_iterations;
  o.gravity = to_vec3(gravity, "gravity");
  o.check_rigid_modes = check_rigid_modes;
  const TetMesh& mesh = mesh_of(mesh_obj, "FemSimulation");
  return std::unique_ptr<Fem>(new Fem{mesh_obj, mesh, FemSimulation(mesh, to_materials(materials), o)});
}

// The model's per-vertex vectors have spare slots beyond the mesh's capacity (they grow
// geometrically); Python sees exactly vertex_capacity rows, like TetMesh.points.
py::array_t<double> vertex_array(const Eigen::VectorXd& u, std::size_t capacity) {
  py::array_t<double> a({static_cast<py::ssize_t>(capacity), py::ssize_t(3)});
  std::copy(u.data(), u.data() + 3 * capacity, a.mutable_data());
  return a;
}

// Exactly vertex_capacity rows (the model may keep spare slots).
std::vector<Vec3> per_vertex(const Springs& s, const std::vector<Vec3>& values) {
  std::vector<Vec3> out(values.begin(), values.begin() + std::min(values.size(), s.mesh.vertex_capacity()));
  out.resize(s.mesh.vertex_capacity(), Vec3::Zero());
  return out;
}

}  // namespace

void bind_sim(py::module_& m) {
  py::class_<Material>(m, "Material", "Young's modulus [Pa], Poisson's ratio, density [kg/m^3]")
      .def(py::init([](double young, double poisson, double density, double viscosity, double stiffening) {
             const Material m{young, poisson, density, viscosity, stiffening};
             check_material(m, "Material", true);  // 0.5 passes: the mixed formulation takes it
             return m;
           }),
           py::arg("young") = 1e6, py::arg("poisson") = 0.3, py::arg("density") = 1000, py::kw_only(),
           py::arg("viscosity") = 0.0, py::arg("stiffening") = 0.0)
      .def_readwrite("viscosity", &Material::viscosity)
      .def_readwrite("stiffening", &Material::stiffening)
      .def_readwrite("young", &Material::young)
      .def_readwrite("poisson", &Material::poisson)
      .def_readwrite("density", &Material::density)
      .def("__repr__", [](const Material& x) {
        return "Material(young=" + std::to_string(x.young) + ", poisson=" + std::to_string(x.poisson) +
               ", density=" + std::to_string(x.density) + ")";
      });
  py::class_<MaterialTable>(m, "MaterialTable", "Material per region label, with a default")
      .def(py::init<>())
      .def("set", &MaterialTable::set, py::arg("label"), py::arg("material"))
      .def("set_default", &MaterialTable::set_default)
      .def("get", &MaterialTable::get, py::arg("label"));

  py::class_<Fem>(m, "FemSimulation",
                  "Linear / corotational FEM, static (K u = f per step) or dynamic (backward Euler); "
                  "CG warm-started across steps (sim/fem/fem_simulation.h)")
      .def(py::init(&make_fem), py::arg("mesh"), py::arg("materials") = py::none(), py::kw_only(),
           py::arg("kind") = "linear", py::arg("method") = "cg", py::arg("backend") = "matrix-free",
           py::arg("tolerance") = 1e-8, py::arg("max_iterations") = 10000, py::arg("budget_ms") = 0.0,
           py::arg("preconditioner") = "cholesky", py::arg("warm_start") = true, py::arg("dynamic") = false,
           py::arg("dt") = 0.01, py::arg("damping") = 0.0, py::arg("nonlinear_iterations") = 1,
           py::arg("gravity") = py::make_tuple(0.0, 0.0, 0.0), py::arg("check_rigid_modes") = true,
           py::arg("formulation") = "standard", py::arg("inversion_barrier") = 0.0,
           py::arg("barrier_stiffness") = InversionBarrierOptions{}.stiffness, py::arg("petsc_options") = "")
      .def_property_readonly("barrier_tets",
                             [](const Fem& f) { return f.sim.model().inversion_barrier().held(); })
      .def("fix", [](Fem& f, const py::object& v) { for (VertexId x : to_vertices(f.mesh, v)) f.sim.fix(x); })
      .def("constrain", [](Fem& f, const py::object& v, const std::string& components, const py::object& d) {
        unsigned axes = 0;
        for (char c : components) {
          const auto at = std::string_view("xyz").find(c);
          if (at == std::string_view::npos || (axes >> at & 1u))
            throw InvalidArgument("constrain: components: expected letters of \"xyz\", each once, got \"" + components + "\"");
          axes |= 1u << at;
        }
        if (!axes) throw InvalidArgument("constrain: components: expected at least one of x, y, z");
        const Vec3 u = to_vec3(d, "displacement");
        for (VertexId x : to_vertices(f.mesh, v)) f.sim.constrain(x, axes, u);
      }, py::arg("vertices"), py::arg("components"), py::arg("displacement") = py::make_tuple(0.0, 0.0, 0.0),
         "Holds only the given components (\"z\", \"xy\"): rollers on symmetry planes")
      .def_property_readonly("pressure", [](const Fem& f) -> py::object {
        const bool taylor_hood = f.sim.quadratic() && f.sim.quadratic()->options().taylor_hood;
        if (!f.sim.mixed() && !taylor_hood) return py::none();
        const Eigen::VectorXd& p = taylor_hood ? f.sim.quadratic()->pressure() : f.sim.mixed()->pressure();
        py::array_t<double> a(static_cast<py::ssize_t>(f.mesh.vertex_capacity()));
        for (std::size_t v = 0; v < f.mesh.vertex_capacity(); ++v) a.mutable_data()[v] = Eigen::Index(v) < p.size() ? p[Eigen::Index(v)] : 0.0;
        return a;
      }, "Mixed formulations (mixed, mixed-edge-smoothed, mixed-quadratic): the pressure per vertex (row = vertex id); "
         "None for the others")
      .def_property_readonly("mid_edge_nodes", [](const Fem& f) -> py::object {
        const QuadraticSolver* q = f.sim.quadratic();
        if (!q) return py::none();
        const P2Mesh& p2 = q->p2();
        const auto ne = static_cast<py::ssize_t>(p2.edges.size());
        py::array_t<std::int64_t> edges({ne, py::ssize_t(2)});
        py::array_t<double> disp({ne, py::ssize_t(3)});
        const Eigen::VectorXd& u = f.sim.quadratic_displacement();
        for (py::ssize_t e = 0; e < ne; ++e) {
          for (int k = 0; k < 2; ++k) edges.mutable_at(e, k) = p2.edges[std::size_t(e)][std::size_t(k)];
          for (int k = 0; k < 3; ++k) disp.mutable_at(e, k) = u[3 * Eigen::Index(p2.corner_slots + std::size_t(e)) + k];
        }
        return py::make_tuple(edges, disp);
      }, "Quadratic formulations: (edges, displacement), the mid-edge nodes' edge (E by 2 vertex ids) and "
         "displacement (E by 3); None for the others")
      .def("prescribe", [](Fem& f, const py::object& v, const py::object& d) {
        const Vec3 u = to_vec3(d, "displacement");
        for (VertexId x : to_vertices(f.mesh, v)) f.sim.prescribe(x, u);
      }, py::arg("vertices"), py::arg("displacement"))
      .def("release", [](Fem& f, const py::object& v) { for (VertexId x : to_vertices(f.mesh, v)) f.sim.release(x); })
      .def("set_force", [](Fem& f, const py::object& v, const py::object& force) {
        const Vec3 g = to_vec3(force, "force");
        for (VertexId x : to_vertices(f.mesh, v)) f.sim.set_force(x, g);
      }, py::arg("vertices"), py::arg("force"), "Force [N] on each given vertex")
      .def("add_force", [](Fem& f, const py::object& v, const py::object& force) {
        const Vec3 g = to_vec3(force, "force");
        for (VertexId x : to_vertices(f.mesh, v)) f.sim.add_force(x, g);
      }, py::arg("vertices"), py::arg("force"))
      .def("clear_forces", [](Fem& f) { f.sim.clear_forces(); })
      .def("set_gravity", [](Fem& f, const py::object& g) { f.sim.set_gravity(to_vec3(g, "gravity")); })
      .def("check_constraints", [](const Fem& f) { f.sim.check_constraints(); },
           "Raises InvalidArgument when a part of the mesh has a rigid mode left")
      .def("step", [](Fem& f, double spent_ms) {
             check_finite_range("FemSimulation.step", "spent_ms", spent_ms, 0, 1e9, PythonNames{});
             return stats_dict(f.sim.step(spent_ms));
           }, py::arg("spent_ms") = 0.0,
           "One frame; returns the CG statistics (iterations, relative_residual, solve_ms, "
           "budget_exhausted, info, message). spent_ms: what the frame already spent (a cut "
           "step), taken off the solver's budget_ms so that the budget bounds the whole frame")
      .def_property_readonly("last_stats", [](const Fem& f) { return stats_dict(f.sim.last_stats()); })
      .def("reset_state", [](Fem& f) { f.sim.reset_state(); })
      .def("apply", [](Fem& f, const TopologyChange& c) { f.sim.apply(c); }, py::arg("change"),
           "Follows one edit batch of the mesh locally (new vertices get interpolated state)")
      .def_property_readonly("displacement", [](const Fem& f) { return vertex_array(f.sim.displacement(), f.mesh.vertex_capacity()); },
                             "vertex_capacity by 3 (row = vertex id)")
      .def_property_readonly("velocity", [](const Fem& f) { return vertex_array(f.sim.velocity(), f.mesh.vertex_capacity()); })
      .def_property_readonly("positions", [](const Fem& f) { return to_array(f.sim.positions()); })
      .def("von_mises", [](Fem& f) {
        const std::vector<double> s = f.sim.von_mises();
        return py::array_t<double>(static_cast<py::ssize_t>(std::min(s.size(), f.mesh.tet_capacity())), s.data());
      }, "Von Mises stress per tet id (tet_capacity entries)");

  py::class_<Springs>(m, "SpringSimulation",
                      "Spring-mass model: springs on the mesh edges and across its interior faces, and volume terms (sim/springs/spring_model.h)")
      .def(py::init([](const py::object& mesh_obj, const py::object& materials, double damping,
                       const py::object& volume_term, const py::object& compute_energy,
                       const py::object& nodal_volume, double viscosity, double stiffening,
                       const std::string& stiffness, const py::object& across_faces, double face_share,
                       double nodal_share, double inversion_guard) {
             SpringOptions o;
             o.nodal_share = nodal_share;
             o.inversion_guard = inversion_guard;
             o.face_share = face_share;
             const auto rule = parse_spring_stiffness(stiffness);
             if (!rule)
               throw InvalidArgument("SpringSimulation: stiffness: expected " + std::string(kSpringStiffnessNames) +
                                     ", got \"" + stiffness + "\"");
             o.stiffness = *rule;
             o.across_faces = across_faces.is_none() ? default_across_faces(o.stiffness)
                                                     : strict_bool(across_faces, "SpringSimulation: across_faces");
             o.viscosity = viscosity;
             o.stiffening = stiffening;
             o.nodal_volume = strict_bool(nodal_volume, "SpringSimulation: nodal_volume");
             o.damping = damping;
             o.volume_term = strict_bool(volume_term, "SpringSimulation: volume_term");
             o.compute_energy = strict_bool(compute_energy, "SpringSimulation: compute_energy");
             const TetMesh& mesh = mesh_of(mesh_obj, "SpringSimulation");
             return std::unique_ptr<Springs>(new Springs{mesh_obj, mesh, SpringModel(mesh, to_materials(materials), o)});
           }),
           py::arg("mesh"), py::arg("materials") = py::none(), py::kw_only(), py::arg("damping") = 0.0,
           py::arg("volume_term") = py::bool_(true), py::arg("compute_energy") = py::bool_(true),
           py::arg("nodal_volume") = py::bool_(SpringOptions{}.nodal_volume), py::arg("viscosity") = 0.0, py::arg("stiffening") = 0.0,
           py::arg("stiffness") = "van-gelder", py::arg("across_faces") = py::none(),
           py::arg("face_share") = SpringOptions{}.face_share, py::arg("nodal_share") = SpringOptions{}.nodal_share,
           py::arg("inversion_guard") = SpringOptions{}.inversion_guard)
      .def("fix", [](Springs& s, const py::object& v) { for (VertexId x : to_vertices(s.mesh, v)) s.model.set_fixed(x, true); })
      .def("release", [](Springs& s, const py::object& v) {
        for (VertexId x : to_vertices(s.mesh, v)) {
          s.model.set_fixed(x, false);
          s.model.clear_prescribed(x);
        }
      })
      .def("prescribe", [](Springs& s, const py::object& v, const py::object& p) {
        const Vec3 x = to_vec3(p, "position");
        for (VertexId id : to_vertices(s.mesh, v)) s.model.set_prescribed(id, x);
      }, py::arg("vertices"), py::arg("position"), "Target position reached at the next step")
      .def("set_force", [](Springs& s, const py::object& v, const py::object& force) {
        const Vec3 g = to_vec3(force, "force");
        for (VertexId x : to_vertices(s.mesh, v)) s.model.set_external_force(x, g);
      }, py::arg("vertices"), py::arg("force"))
      .def("set_gravity", [](Springs& s, const py::object& g) { s.model.set_gravity(to_vec3(g, "gravity")); })
      .def("set_positions", [](Springs& s, const py::object& x) {
        const std::vector<Vec3> p = to_points(x, s.mesh.vertex_capacity(), "SpringSimulation.set_positions");
        for (VertexId v : s.mesh.vertices()) s.model.set_position(v, p[v.idx()]);
      }, py::arg("positions"), "Every live vertex's position (vertex_capacity by 3, row = vertex id): initial conditions")
      .def("set_velocities", [](Springs& s, const py::object& u) {
        const std::vector<Vec3> p = to_points(u, s.mesh.vertex_capacity(), "SpringSimulation.set_velocities");
        for (VertexId v : s.mesh.vertices()) s.model.set_velocity(v, p[v.idx()]);
      }, py::arg("velocities"), "Every live vertex's velocity (vertex_capacity by 3, row = vertex id)")
      .def("apply", [](Springs& s, const TopologyChange& c) { s.model.apply(s.mesh, c); }, py::arg("change"))
      .def("step", [](Springs& s, double dt, const std::string& integrator) {
        return step_dict(s.model.step(dt, parse_integrator(integrator)));
      }, py::arg("dt"), py::arg("integrator") = "symplectic-euler",
         "explicit-euler, symplectic-euler, verlet or implicit-euler")
      .def("stable_time_step", [](const Springs& s, const std::string& integrator) {
        return s.model.stable_time_step(parse_integrator(integrator));
      }, py::arg("integrator") = "symplectic-euler",
         "The stable step from Gershgorin's bound at rest: cheap, loose")
      .def("estimated_stable_time_step", [](Springs& s, const std::string& integrator, int iterations) {
        return s.model.estimated_stable_time_step(parse_integrator(integrator), iterations);
      }, py::arg("integrator") = "symplectic-euler", py::arg("iterations") = 60,
         "The stable step at the current state from an estimate of its fastest mode: tight, O(iterations x mesh)")
      .def_property_readonly("positions", [](const Springs& s) { return to_array(per_vertex(s, s.model.positions())); })
      .def_property_readonly("velocities", [](const Springs& s) { return to_array(per_vertex(s, s.model.velocities())); })
      .def_property_readonly("displacement", [](const Springs& s) {
        std::vector<Vec3> d = per_vertex(s, s.model.positions());
        for (std::uint32_t v = 0; v < d.size(); ++v)  // a dead slot moves nowhere (its values are stale)
          d[v] = s.mesh.is_alive(VertexId(v)) ? Vec3(d[v] - s.mesh.rest(VertexId(v))) : Vec3::Zero();
        return to_array(d);
      })
      .def_property_readonly("num_springs", [](const Springs& s) { return s.model.num_springs(); })
      .def_property_readonly("kinetic_energy", [](const Springs& s) { return s.model.kinetic_energy(); })
      .def_property_readonly("potential_energy", [](const Springs& s) { return s.model.potential_energy(); });

  py::class_<Scene>(m, "Scene", "A scene file (docs/scene.md), checked on load")
      .def_readonly("path", &Scene::path)
      .def_property_readonly("model", [](const Scene& s) {
        return s.model == SceneModel::Springs ? "springs" : s.model == SceneModel::FemCorotational ? "fem-corotational" : "fem-linear";
      })
      .def_property_readonly("formulation", [](const Scene& s) { return std::string(formulation_name(s.formulation)); },
                             "\"standard\", \"nodal-averaged\", \"edge-smoothed\", \"mixed\", \"mixed-edge-smoothed\", \"quadratic\" or "
                             "\"mixed-quadratic\"")
      .def_readonly("materials", &Scene::materials)
      .def_property_readonly("fixed", [](const Scene& s) {
        py::list l;
        for (const SceneFixed& f : s.fixed) {
          const SceneBox& b = f.box;
          l.append(py::make_tuple(py::make_tuple(b.lo.x(), b.lo.y(), b.lo.z()), py::make_tuple(b.hi.x(), b.hi.y(), b.hi.z())));
        }
        return l;
      }, "Fixed boxes as (lo, hi) pairs")
      .def_property_readonly("solver", [](const Scene& s) {
        py::dict d;
        d["method"] = s.method == SolverMethod::Direct ? "direct" : "cg";
        d["backend"] = s.backend == StiffnessBackend::Assembled ? "assembled"
                       : s.backend == StiffnessBackend::Petsc  ? "petsc"
                                                               : "matrix-free";
        d["tolerance"] = s.cg.tolerance;
        d["max_iterations"] = s.cg.max_iterations;
        d["budget_ms"] = s.cg.budget_ms;
        d["preconditioner"] = to_string(s.cg.preconditioner);
        d["warm_start"] = s.warm_start;
        d["nonlinear_iterations"] = s.nonlinear_iterations;
        return d;
      }, "Keyword arguments of FemSimulation")
      .def_property_readonly("springs", [](const Scene& s) {
        py::dict d;
        d["volume_term"] = s.springs_volume != "none";
        d["nodal_volume"] = s.springs_volume == "nodal";
        d["nodal_share"] = s.springs_nodal_share;
        d["inversion_guard"] = s.springs_inversion_guard;
        d["stiffness"] = s.springs_stiffness;
        d["across_faces"] = s.springs_connectivity == "across-faces";
        d["viscosity"] = s.springs_viscosity;
        d["stiffening"] = s.springs_stiffening;
        return d;
      }, "Keyword arguments of SpringSimulation (the scene's springs key)")
      .def_readonly("frames", &Scene::frames)
      .def_readonly("dt", &Scene::dt)
      .def_readonly("integrator", &Scene::integrator)
      .def_readonly("damping", &Scene::damping)
      .def("mesh", &load_scene_mesh, "The scene's mesh: its file (relative to the scene) or its generator");
  m.def("load_scene", &load_scene, py::arg("path"), "Reads and checks a scene; raises IoError naming the key");
  m.def(
      "run_scene",
      [](const std::string& path, const std::string& out_dir, const py::object& frames) {
        SceneRunOptions o;
        o.out_dir = out_dir;
        if (!frames.is_none()) {
          // `incise simulate --frames`: at least 1 (None: the scene's own count).
          const auto n = to_indices(frames, "run_scene: frames");
          if (n.ndim() != 0 || n.data()[0] < 1 || n.data()[0] > 1000000000)
            throw InvalidArgument("run_scene: frames: expected an integer in [1, 1000000000] (None: the scene's)");
          o.frames = static_cast<int>(n.data()[0]);
        }
        // Into a directory as `incise simulate -o` writes one: never over a user's files, one
        // run's output whatever happened before (scene/run_directory.h).
        const SceneRunSummary r = out_dir.empty() ? run_scene(load_scene(path), o)
                                                  : run_scene_into(load_scene(path), o, out_dir);
        py::dict d;
        d["frames"] = r.frames;
        d["total_iterations"] = r.total_iterations;
        d["total_solve_ms"] = r.total_solve_ms;
        d["frames_budget_exhausted"] = r.frames_budget_exhausted;
        d["frames_not_converged"] = r.frames_not_converged;
        d["max_displacement"] = r.max_displacement;
        d["max_inverted"] = r.max_inverted;
        d["frames_with_inverted"] = r.frames_with_inverted;
        d["first_stable_dt"] = r.first_stable_dt;
        d["min_stable_dt"] = r.min_stable_dt;
        d["estimated_stable_dt"] = r.estimated_stable_dt;
        d["vertices"] = r.vertices;
        d["tets"] = r.tets;
        d["total_cut_ms"] = r.total_cut_ms;
        d["fragments_handled"] = r.fragments_handled;
        py::list cuts;
        for (const auto& c : r.cuts) {
          py::dict x;
          x["tets_cut"] = c.tets_cut;
          x["faces_opened"] = c.faces_opened;
          x["parts"] = c.parts;
          cuts.append(x);
        }
        d["cuts"] = cuts;
        d["warnings"] = r.warnings;
        d["files"] = r.files;
        return d;
      },
      py::arg("path"), py::arg("out_dir") = "", py::arg("frames") = py::none(),
      "Plays a scene as `incise simulate` does (VTU frames, .pvd, stats.csv into out_dir when given)");
}

}  // namespace incise::python
