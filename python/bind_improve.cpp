// Quality improvement: incise.improve (whole mesh) and incise.improve_local (seed tets plus a
// few rings, within a budget), returning the `incise improve --json` report as a dict and
// the edits as a TopologyChange for the simulations.
#include "python/bindings.h"

#include "mesh/errors.h"
#include "quality/improve.h"
#include "quality/improve_checks.h"
#include "quality/improve_report.h"

namespace incise::python {

namespace {

ImproveOptions options(double time_limit, double budget_ms, int max_work, double target, double target_max,
                       bool flips, bool multi_face, bool smoothing, bool insertion, double max_growth,
                       double radius_ratio_floor, bool keep_surface, bool fixed_boundary, double feature_angle,
                       double volume_tolerance, const std::vector<VertexId>& frozen, bool edge_stars = true) {
  ImproveOptions o;
  o.time_limit_s = time_limit;
  o.time_budget_ms = budget_ms;
  o.max_work = max_work;
  o.target_dihedral_deg = target;
  o.target_max_dihedral_deg = target_max;
  o.flips = flips;
  o.collapse = flips;  // like --no-flips: contraction changes connectivity too
  o.multi_face_removal = multi_face;
  o.radius_ratio_floor = radius_ratio_floor;
  o.smoothing = smoothing;
  o.insertion = insertion;
  o.edge_star_insertion = edge_stars;
  o.max_growth = max_growth;
  // The command line's rules: curved sliding unless keep_surface; nothing on the boundary
  // moves with fixed_boundary.
  o.slide_curved = !keep_surface && !fixed_boundary;
  o.move_surface = o.move_cut = o.move_interface = !fixed_boundary;
  o.feature_angle_deg = feature_angle;
  o.volume_tolerance = volume_tolerance;
  o.frozen = frozen;
  check_improve_options(o, PythonNames{});  // the rules of `incise improve`, Python's names
  return o;
}

py::dict result(TetMesh& mesh, const ImproveReport& r) {
  py::dict d = json_to_python(improve_report_json(r).dump()).cast<py::dict>();
  d["change"] = py::cast(mesh.take_change());
  return d;
}

}  // namespace

void bind_improve(py::module_& m) {
  m.def(
      "improve",
      [](TetMesh& mesh, double time_limit, double target, double target_max, bool flips, bool multi_face,
         bool smoothing, bool insertion, double max_growth, double radius_ratio_floor, bool keep_surface,
         bool fixed_boundary, double feature_angle, double volume_tolerance, const py::object& frozen,
         bool edge_stars, int max_work) {
        if (max_work < 0) throw InvalidArgument("improve: max_work: expected an integer >= 0 (0: no cap)");
        if (mesh.has_pending_change())
          throw InvalidArgument("improve: the mesh has edits not yet taken (call take_change() first)");
        const std::vector<VertexId> fz = frozen.is_none() ? std::vector<VertexId>{} : to_vertices(mesh, frozen);
        const ImproveReport r =
            improve(mesh, options(time_limit, 0, max_work, target, target_max, flips, multi_face, smoothing, insertion,
                                  max_growth, radius_ratio_floor, keep_surface, fixed_boundary, feature_angle,
                                  volume_tolerance, fz, edge_stars));
        return result(mesh, r);
      },
      py::arg("mesh"), py::kw_only(), py::arg("time_limit") = 10.0, py::arg("target_dihedral") = 35.0,
      py::arg("target_max_dihedral") = 135.0, py::arg("flips") = true, py::arg("multi_face") = true,
      py::arg("smoothing") = true, py::arg("insert") = false, py::arg("max_growth") = 1.5,
      py::arg("radius_ratio_floor") = 0.1, py::arg("keep_surface") = false,
      py::arg("fixed_boundary") = false, py::arg("feature_angle") = 30.0, py::arg("volume_tolerance") = 1e-4,
      py::arg("frozen") = py::none(), py::arg("edge_stars") = true, py::arg("max_work") = 0,
      "Flips and smoothing over the whole mesh, worst first (as `incise improve`; edge_stars=False "
      "as --no-edge-stars, max_work as --max-work); returns the "
      "`incise improve --json` report with the edits as 'change'");
  m.def(
      "improve_local",
      [](TetMesh& mesh, const py::object& seeds, double budget_ms, int max_work, int rings, const py::object& frozen) {
        if (mesh.has_pending_change())
          throw InvalidArgument("improve: the mesh has edits not yet taken (call take_change() first)");
        check_finite_range("improve_local", "budget_ms", budget_ms, 0, 1e6, PythonNames{});
        if (max_work < 0) throw InvalidArgument("improve_local: max_work: expected an integer >= 0 (0: no cap)");
        if (rings < 0) throw InvalidArgument("improve_local: rings: expected an integer >= 0 (0: the seeds only)");
        std::vector<TetId> ts;
        const auto seed_ids = to_indices(seeds, "improve_local: seeds");
        for (py::ssize_t i = 0; i < seed_ids.size(); ++i) {
          const long long t = seed_ids.data()[i];
          if (t < 0 || t >= static_cast<long long>(mesh.tet_capacity()) || !mesh.is_alive(TetId(std::uint32_t(t))))
            throw InvalidArgument("improve_local: seed tet " + std::to_string(t) + " is not a live tet");
          ts.push_back(TetId(std::uint32_t(t)));
        }
        const std::vector<VertexId> fz = frozen.is_none() ? std::vector<VertexId>{} : to_vertices(mesh, frozen);
        // Local passes keep the surface exactly, as the cutter's does.
        ImproveOptions o =
            options(10, budget_ms, max_work, 35, 135, true, true, true, false, 1.5, 0.1, true, false, 30, 1e-4, fz);
        o.rings = rings;
        return result(mesh, improve_local(mesh, ts, o));
      },
      py::arg("mesh"), py::arg("seeds"), py::kw_only(), py::arg("budget_ms") = 0.0, py::arg("max_work") = 0,
      py::arg("rings") = 2, py::arg("frozen") = py::none(),
      "The local pass the cutter runs: seed tets plus `rings` rings, within budget_ms / max_work");
}

}  // namespace incise::python
