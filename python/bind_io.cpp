// incise.read / incise.write: every tet format of mesh/io/tet_io.h, chosen by extension.
#include "python/bindings.h"

#include "mesh/errors.h"
#include "mesh/io/tet_io.h"

namespace incise::python {

namespace {

// A point or cell field: capacity values (scalar) or capacity by 3 (vector), row = id.
Field to_field(const std::string& name, const py::handle& h, std::size_t capacity, const char* what) {
  auto a = to_reals(h, std::string(what) + " '" + name + "'");
  const bool ok = a.ndim() >= 1 && a.shape(0) == static_cast<py::ssize_t>(capacity) &&
                  (a.ndim() == 1 || (a.ndim() == 2 && a.shape(1) == 3));
  if (!ok) {
    const bool cells = std::string(what) == "cell_data";
    std::string got = std::to_string(a.ndim() >= 1 ? a.shape(0) : 0);
    for (py::ssize_t d = 1; d < a.ndim(); ++d) got += " by " + std::to_string(a.shape(d));
    throw InvalidArgument(std::string(what) + " '" + name + "': got " + got + "; expected one row per " +
                          (cells ? "tet id" : "vertex id") + " slot, " + std::to_string(capacity) + " rows (mesh." +
                          (cells ? "tet_capacity" : "vertex_capacity") + ", dead ids included) of 1 or 3 values");
  }
  Field f;
  f.name = name;
  f.components = a.ndim() == 1 ? 1 : 3;
  f.values.assign(a.data(), a.data() + a.size());
  return f;
}

}  // namespace

py::tuple surface_to_python(const SurfaceMesh& surface) {
  py::array_t<long long> f({static_cast<py::ssize_t>(surface.triangles.size()), py::ssize_t(3)});
  auto w = f.mutable_unchecked<2>();
  for (std::size_t i = 0; i < surface.triangles.size(); ++i)
    for (int k = 0; k < 3; ++k) w(i, k) = surface.triangles[i][k];
  return py::make_tuple(to_array(surface.vertices), f);
}

SurfaceMesh surface_from_python(const py::handle& h) {
  const char* what = "surface";
  if (!py::isinstance<py::tuple>(h) && !py::isinstance<py::list>(h))
    throw InvalidArgument(std::string(what) + ": expected a path or a (vertices, triangles) pair");
  auto seq = h.cast<py::sequence>();
  if (seq.size() != 2) throw InvalidArgument(std::string(what) + ": expected a (vertices, triangles) pair");
  auto v = to_reals(seq[0], "surface vertices");
  if (v.ndim() != 2 || v.shape(1) != 3) throw InvalidArgument(std::string(what) + ": vertices must be #V by 3");
  SurfaceMesh s;
  s.vertices = to_points(v, v.shape(0), "surface vertices");
  auto f = to_indices(seq[1], "surface triangles");
  if (f.ndim() != 2 || f.shape(1) != 3) throw InvalidArgument(std::string(what) + ": triangles must be #F by 3");
  for (py::ssize_t i = 0; i < f.shape(0); ++i) {
    std::array<int, 3> t;
    for (int k = 0; k < 3; ++k) {
      const long long x = f.data()[3 * i + k];
      if (x < 0 || x >= v.shape(0))
        throw InvalidArgument(std::string(what) + ": triangle #" + std::to_string(i) + " references vertex " +
                              std::to_string(x) + " out of range");
      t[k] = static_cast<int>(x);
    }
    s.triangles.push_back(t);
  }
  return s;
}

void bind_io(py::module_& m) {
  m.def(
      "read",
      [](const std::string& path, bool report) -> py::object {
        ReadReport r;
        TetMesh mesh = read_tet_mesh(path, &r);
        if (!report) return py::cast(std::move(mesh));
        py::dict d;
        d["format"] = r.format;
        d["skipped_cells"] = r.skipped_cells;
        d["reoriented_tets"] = r.reoriented_tets;
        d["unreferenced_vertices"] = r.unreferenced_vertices;
        d["degenerate_tets"] = r.degenerate_tets;
        d["boundary_faces_tagged_by_file"] = r.tagged_boundary_faces;
        return py::make_tuple(std::move(mesh), d);
      },
      py::arg("path"), py::arg("report") = false,
      "Reads a tet mesh (.msh .mesh .vtk .vtu .node/.ele); with report=True returns (mesh, dict). "
      "Raises IoError('FILE:LINE: reason').");
  m.def(
      "write",
      [](const TetMesh& mesh, const std::string& path, bool binary, const py::object& positions,
         const py::dict& point_data, const py::dict& cell_data) {
        WriteOptions o;
        o.binary = binary;
        if (positions.is_none() && point_data.empty() && cell_data.empty()) {
          write_tet_mesh(mesh, path, o);
          return;
        }
        // Fields and deformed positions: VTU / VTK legacy only (ParaView frames).
        MeshFields fields;
        std::vector<Vec3> current;
        if (!positions.is_none()) {
          current = to_points(positions, mesh.vertex_capacity(), "positions");
          fields.points = &current;
        }
        for (auto [k, v] : point_data)
          fields.point_data.push_back(to_field(k.cast<std::string>(), v, mesh.vertex_capacity(), "point_data"));
        for (auto [k, v] : cell_data)
          fields.cell_data.push_back(to_field(k.cast<std::string>(), v, mesh.tet_capacity(), "cell_data"));
        write_tet_mesh_with_fields(mesh, path, fields, o);
      },
      py::arg("mesh"), py::arg("path"), py::arg("binary") = false, py::arg("positions") = py::none(),
      py::arg("point_data") = py::dict(), py::arg("cell_data") = py::dict(),
      "Writes atomically, format by extension. positions / point_data / cell_data (rows indexed "
      "by id, as TetMesh.points) need .vtu or .vtk.");
  m.def(
      "read_surface", [](const std::string& path) { return surface_to_python(read_surface(path)); }, py::arg("path"),
      "A triangle surface (OBJ, STL, PLY, OFF, glTF, ... through assimp) as (vertices, triangles)");
  m.def(
      "write_surface",
      [](const py::object& surface, const std::string& path) { write_surface(surface_from_python(surface), path); },
      py::arg("surface"), py::arg("path"), "Writes (vertices, triangles) as OFF, OBJ or STL by extension; atomic");
  m.def(
      "boundary_surface", [](const TetMesh& mesh) { return surface_to_python(boundary_surface(mesh)); },
      py::arg("mesh"), "The mesh boundary as (vertices, triangles), outward oriented, vertices compacted");
}

}  // namespace incise::python
