#pragma once
// Shared by the python/bind_*.cpp translation units: one bind_<area>() per area, called by
// module.cpp, and the conversions they all use. Vertex and tet arguments are ids (ints); a
// dead or out-of-range id raises incise.InvalidArgument.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <string>
#include <vector>

#include "mesh/io/surface.h"
#include "mesh/tet_mesh.h"

namespace incise::python {

namespace py = pybind11;

void bind_errors(py::module_& m);
void bind_mesh(py::module_& m);
void bind_io(py::module_& m);
void bind_quality(py::module_& m);
void bind_sim(py::module_& m);
void bind_cut(py::module_& m);
void bind_improve(py::module_& m);
void bind_tetra(py::module_& m);

// (n, 3) float64 array copied from positions (copies: the mesh's storage moves when it grows,
// so a view could dangle after an edit).
py::array_t<double> to_array(const std::vector<Vec3>& points);
// Any array-like of real numbers (int or float dtype) as float64; complex numbers, strings and
// objects raise InvalidArgument naming `what` (numpy's cast would drop the imaginary part or
// parse the text).
py::array_t<double, py::array::c_style | py::array::forcecast> to_reals(const py::handle& h, const std::string& what);
// Any array-like of integers as int64; floats raise InvalidArgument (a cast would truncate).
py::array_t<long long, py::array::c_style | py::array::forcecast> to_indices(const py::handle& h, const std::string& what);
// `rows` by 3 finite numbers -> positions (e.g. a deformed configuration indexed by vertex id).
std::vector<Vec3> to_points(const py::handle& h, std::size_t rows, const char* what);
// A 3-vector from any sequence of 3 finite numbers.
Vec3 to_vec3(const py::handle& h, const char* what);
// One id or a sequence / array of ids, each checked alive in `mesh`.
std::vector<VertexId> to_vertices(const TetMesh& mesh, const py::handle& h);
// Triangle surfaces as (#V by 3 float64, #F by 3 int64) pairs.
py::tuple surface_to_python(const SurfaceMesh& surface);
SurfaceMesh surface_from_python(const py::handle& h);
// JSON text -> Python object (json.loads), for reports the CLI prints as JSON.
py::object json_to_python(const std::string& text);

}  // namespace incise::python
