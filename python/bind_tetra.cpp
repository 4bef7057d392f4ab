// incise.tetrahedralize: the `incise tetra` / `incise prepare` pipeline (surface or labeled
// image -> check -> repair when asked -> CGAL Mesh_3 or isosurface stuffing). Built only with
// incise_tetra (INCISE_WITH_CGAL).
#include "python/bindings.h"

#include "mesh/errors.h"
#include "mesh/tetrahedralize/pipeline.h"

namespace incise::python {

void bind_tetra(py::module_& m) {
  m.def(
      "tetrahedralize",
      [](const py::object& input, const std::string& size, const std::string& engine, bool repair,
         const std::string& optimize, unsigned seed, double facet_angle, double radius_edge, bool graded,
         bool progress, bool report) -> py::object {
        PipelineOptions o;
        o.tetra.size = Length::parse(size);
        if (engine == "cgal") o.engine = TetraEngine::Cgal;
        else if (engine == "stuffing") o.engine = TetraEngine::Stuffing;
        else throw InvalidArgument("engine: unknown value '" + engine + "' (expected cgal, stuffing)");
        o.repair = repair;
        o.tetra.optimize = parse_optimize(optimize);
        o.tetra.seed = seed;
        o.tetra.facet_angle = facet_angle;
        o.tetra.radius_edge = radius_edge;
        o.tetra.graded = graded;
        o.tetra.progress = progress;
        const bool is_path = py::isinstance<py::str>(input);
        const std::string path = is_path ? input.cast<std::string>() : std::string();
        const SurfaceMesh surface = is_path ? SurfaceMesh() : surface_from_python(input);
        PipelineReport rep;
        TetMesh mesh;
        {
          py::gil_scoped_release unlocked;  // minutes on big inputs; let other threads run
          if (is_path) mesh = mesh_file(path, o, &rep);
          else mesh = mesh_surface(surface, o, &rep);
        }
        if (!report) return py::cast(std::move(mesh));
        py::dict d;
        d["input"] = rep.input;
        d["image"] = rep.image;
        d["repaired"] = rep.repaired;
        d["engine"] = rep.stats.engine;
        d["size"] = rep.stats.size;
        d["seconds"] = rep.stats.seconds;
        d["min_dihedral"] = rep.stats.min_dihedral;
        d["max_dihedral"] = rep.stats.max_dihedral;
        d["summary"] = rep.stats.summary();
        d["messages"] = rep.messages;
        return py::make_tuple(std::move(mesh), d);
      },
      py::arg("input"), py::kw_only(), py::arg("size") = "3%", py::arg("engine") = "cgal", py::arg("repair") = false,
      py::arg("optimize") = "perturb,exude", py::arg("seed") = 0u, py::arg("facet_angle") = 25.0,
      py::arg("radius_edge") = 2.5, py::arg("graded") = false, py::arg("progress") = false,
      py::arg("report") = false,
      "Tet mesh of a surface file (.obj .stl .ply .off ...), a (vertices, triangles) pair, or a "
      "labeled image (.inr, .inr.gz); "
      "size is absolute ('0.05') or relative to the bounding-box diagonal ('3%'). With report=True "
      "returns (mesh, dict).");
}

}  // namespace incise::python
