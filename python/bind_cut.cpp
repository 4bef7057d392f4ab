// Cutting: incise.Cutter (progressive blade, plane and surface cuts). Each call returns a dict
// with the same figures as `incise cut --json` per step, the step's TopologyChange (hand it to
// FemSimulation.apply / SpringSimulation.apply) and the detached fragments.
#include <cmath>
#include "python/bindings.h"

#include "cut/blade_path.h"
#include "cut/cutter.h"
#include "mesh/errors.h"
#include "quality/improve_checks.h"

namespace incise::python {

namespace {

// The cutter edits the mesh in place: it keeps the Python mesh object alive.
struct PyCutter {
  py::object mesh_ref;
  TetMesh& mesh;
  Cutter cutter;
};

std::unique_ptr<PyCutter> make_cutter(const py::object& mesh_obj, const std::string& mode, double snap, bool improve,
                                      double improve_budget_ms, int improve_work, const py::object& frozen,
                                      std::size_t fragment_search_limit, double finish_insert, int finish_work,
                                      int finish_slice, double path_tolerance, bool exact_volumes,
                                      bool provisional, bool material_frame) {
  if (!py::isinstance<TetMesh>(mesh_obj))
    throw InvalidArgument("Cutter: mesh: expected an incise.TetMesh, got " +
                          py::str(py::type::of(mesh_obj).attr("__name__")).cast<std::string>());
  TetMesh& mesh = mesh_obj.cast<TetMesh&>();
  CutOptions o;
  if (mode == "subdivide") o.mode = CutMode::Subdivide;
  else if (mode == "remove") o.mode = CutMode::Remove;
  else throw InvalidArgument("cut: mode: unknown value '" + mode + "' (expected subdivide, remove)");
  o.snap = snap;
  o.improve = improve;
  // `incise cut --improve-budget-ms` / `--improve-work`: the same ranges (a budget past 1e6 ms
  // would overflow the clock's duration).
  check_finite_range("cut", "improve_budget_ms", improve_budget_ms, 0, 1e6, PythonNames{});
  if (improve_work < 0 || improve_work > 100000000)
    throw InvalidArgument("cut: improve_work: " + std::to_string(improve_work) + " is out of range [0, 100000000]");
  o.improve_budget_ms = improve_budget_ms;
  o.improve_options.max_work = improve_work;
  check_finite_range("cut", "finish_insert", finish_insert, 0, 90, PythonNames{});  // `incise cut --finish-insert`
  o.finish_insertion_below_deg = finish_insert;
  // `incise cut --finish-work`: the same range; a slice of 0 is the whole of it in finish().
  for (const auto& [name, v] : {std::pair<const char*, int>{"finish_work", finish_work}, {"finish_slice", finish_slice}})
    if (v < 0 || v > 100000000)
      throw InvalidArgument(std::string("cut: ") + name + ": " + std::to_string(v) + " is out of range [0, 100000000]");
  o.finish_improve_work = finish_work;
  o.finish_improve_slice = finish_slice;
  check_finite_range("cut", "path_tolerance", path_tolerance, 0, 10, PythonNames{});
  o.path_tolerance = path_tolerance;
  o.exact_volumes = exact_volumes;
  o.provisional = provisional;
  o.material_frame = material_frame;
  if (!frozen.is_none()) o.frozen = to_vertices(mesh, frozen);
  o.fragment_search_limit = fragment_search_limit;
  return std::unique_ptr<PyCutter>(new PyCutter{mesh_obj, mesh, Cutter(mesh, std::move(o))});
}

// Current positions (rows indexed by vertex id, e.g. FemSimulation.positions) or None.
Cutter::PositionFn positions_of(const TetMesh& mesh, const py::object& positions, std::vector<Vec3>& storage) {
  if (positions.is_none()) return {};
  storage = to_points(positions, mesh.vertex_capacity(), "positions");
  return [&storage](VertexId v) { return storage[v.idx()]; };
}

py::dict report(CutStepReport&& r) {
  py::dict d;
  d["tets_cut"] = r.tets_cut;
  d["tets_added"] = r.tets_added;
  d["vertices_added"] = r.vertices_added;
  d["vertices_duplicated"] = r.vertices_duplicated;
  d["cut_faces"] = r.cut_faces;
  d["provisional_faces"] = r.provisional_faces;
  d["tets_taken_back"] = r.tets_taken_back;
  d["vertices_taken_back"] = r.vertices_taken_back;
  d["cut_area"] = r.cut_area;
  d["exposed_area"] = r.exposed_area;
  d["ms"] = r.ms;
  d["ms_improve"] = r.ms_improve;
  const auto part = [](const Fragment& f) {
    py::array_t<long long> ids(static_cast<py::ssize_t>(f.tets.size()));
    for (std::size_t i = 0; i < f.tets.size(); ++i) ids.mutable_data()[i] = f.tets[i].idx();
    py::dict fd;
    fd["tets"] = ids;
    fd["volume"] = f.volume;
    return fd;
  };
  py::list fragments;
  for (const Fragment& f : r.fragments) fragments.append(part(f));
  d["fragments"] = fragments;
  // A small body cut through: the part taken as the body (the largest by volume), else None.
  d["body"] = r.body.tets.empty() ? py::object(py::none()) : py::object(part(r.body));
  d["change"] = py::cast(std::move(r.change));
  return d;
}

}  // namespace

void bind_cut(py::module_& m) {
  m.def(
      "read_blade_path",
      [](const std::string& path) {
        const std::vector<BladeSegment> p = read_blade_path(path);
        py::array_t<double> out({static_cast<py::ssize_t>(p.size()), py::ssize_t(2), py::ssize_t(3)});
        double* d = out.mutable_data();
        for (const BladeSegment& b : p)
          for (const Vec3& x : {b.a, b.b})
            for (int k = 0; k < 3; ++k) *d++ = x[k];
        return out;
      },
      py::arg("path"),
      "Blade positions from a path file (one 'AX AY AZ BX BY BZ' per line, as `incise cut --path` reads): an "
      "(N, 2, 3) array; the first places the blade (Cutter.start), each later one is a step (Cutter.advance)");
  py::class_<PyCutter>(m, "Cutter",
                       "Cuts a TetMesh in place: a blade segment swept over calls (progressive cuts), a plane, "
                       "or a triangulated surface (cut/cutter.h, docs/cut.md)")
      .def(py::init(&make_cutter), py::arg("mesh"), py::kw_only(), py::arg("mode") = "subdivide",
           py::arg("snap") = 0.05, py::arg("improve") = true, py::arg("improve_budget_ms") = 0.0,
           py::arg("improve_work") = CutOptions::kDefaultImproveWork,
           py::arg("frozen") = py::none(), py::arg("fragment_search_limit") = std::size_t(20000),
           py::arg("finish_insert") = CutOptions{}.finish_insertion_below_deg,
           py::arg("finish_work") = CutOptions{}.finish_improve_work, py::arg("finish_slice") = 0,
           py::arg("path_tolerance") = CutOptions{}.path_tolerance, py::arg("exact_volumes") = CutOptions{}.exact_volumes,
           py::arg("provisional") = CutOptions{}.provisional,
           py::arg("material_frame") = CutOptions{}.material_frame)
      .def(
          "start", [](PyCutter& c, const py::object& a, const py::object& b) {
            c.cutter.start({to_vec3(a, "blade a"), to_vec3(b, "blade b")});
          },
          py::arg("a"), py::arg("b"), "Places the blade (segment a-b) without cutting. A cut not finished is completed by the next step")
      .def(
          "finish",
          [](PyCutter& c, const py::object& positions) {
            std::vector<Vec3> storage;
            const auto pos = positions_of(c.mesh, positions, storage);
            return report(c.cutter.finish(pos));
          },
          py::arg("positions") = py::none(),
          "The blade is withdrawn: cuts the tets the blade was still in (embedding its last front), "
          "improves around the front with its vertices free, and forgets the cut. Returns a step report "
          "(its 'change' empty when there was nothing to do). With finish_slice > 0 the improvement runs "
          "at most that many operations here and the rest in finish_more() calls")
      .def(
          "finish_more", [](PyCutter& c) { return report(c.cutter.finish_more()); },
          "One more slice of the withdrawn blade's improvement (finish_slice operations; call once a frame "
          "while `finishing`). Take its 'change' like a step's: give it to every simulation's apply")
      .def_property_readonly("finishing", [](const PyCutter& c) { return c.cutter.finishing(); },
                             "True while the withdrawn blade's improvement has slices left (finish_more)")
      .def(
          "advance",
          [](PyCutter& c, const py::object& a, const py::object& b, const py::object& positions) {
            std::vector<Vec3> storage;
            const auto pos = positions_of(c.mesh, positions, storage);
            return report(c.cutter.advance({to_vec3(a, "blade a"), to_vec3(b, "blade b")}, pos));
          },
          py::arg("a"), py::arg("b"), py::arg("positions") = py::none(),
          "Moves the blade to a-b and cuts what it swept (tets the blade is still in wait for later "
          "steps or finish()); positions: current positions by vertex id (the cut is made in that "
          "configuration). Returns the step report with its 'change'.")
      .def(
          "cut_plane",
          [](PyCutter& c, const py::object& point, const py::object& normal, const py::object& positions) {
            std::vector<Vec3> storage;
            const auto pos = positions_of(c.mesh, positions, storage);
            return report(c.cutter.cut_plane(to_vec3(point, "point"), to_vec3(normal, "normal"), pos));
          },
          py::arg("point"), py::arg("normal"), py::arg("positions") = py::none())
      .def(
          "cut_surface",
          [](PyCutter& c, const py::object& surface, const py::object& positions) {
            const SurfaceMesh s = surface_from_python(surface);
            std::vector<CutTriangle> tris;
            for (const auto& t : s.triangles) tris.push_back({{s.vertices[t[0]], s.vertices[t[1]], s.vertices[t[2]]}});
            std::vector<Vec3> storage;
            const auto pos = positions_of(c.mesh, positions, storage);
            return report(c.cutter.cut_surface(tris, pos));
          },
          py::arg("surface"), py::arg("positions") = py::none(), "surface: a (vertices, triangles) pair")
      .def_property_readonly("blade", [](const PyCutter& c) {
        const BladeSegment& b = c.cutter.blade();
        return py::make_tuple(py::make_tuple(b.a.x(), b.a.y(), b.a.z()), py::make_tuple(b.b.x(), b.b.y(), b.b.z()));
      });
  m.attr("TAG_SURFACE") = int(kTagSurface);
  m.attr("TAG_CUT") = int(kTagCut);
}

}  // namespace incise::python
