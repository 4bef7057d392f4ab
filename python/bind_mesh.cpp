// incise.TetMesh and the generators. Arrays are copies (see bindings.h); `points` is indexed
// by vertex id (vertex_capacity rows: dead ids keep their last position), `tets` and `labels`
// list the live tets in increasing id order (`tet_ids`). After compact() ids are dense and
// the two views agree with num_vertices / num_tets.
#include "python/bindings.h"

#include <algorithm>
#include <limits>
#include <sstream>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "mesh/io/formats.h"
#include "mesh/io/input_checks.h"
#include "mesh/refine.h"

namespace incise::python {

py::array_t<double> to_array(const std::vector<Vec3>& points) {
  py::array_t<double> a({static_cast<py::ssize_t>(points.size()), py::ssize_t(3)});
  auto w = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < points.size(); ++i)
    for (int k = 0; k < 3; ++k) w(i, k) = points[i][k];
  return a;
}

py::array_t<double, py::array::c_style | py::array::forcecast> to_reals(const py::handle& h, const std::string& what) {
  const py::array raw = py::array::ensure(h);
  if (!raw) throw InvalidArgument(what + ": expected numbers");
  const char k = raw.dtype().kind();
  // numpy would turn complex numbers into their real part and "1.5" into 1.5 without a word.
  if (k != 'f' && k != 'i' && k != 'u')
    throw InvalidArgument(what + ": expected real numbers, got " + py::str(raw.dtype()).cast<std::string>());
  return py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(raw);
}

py::array_t<long long, py::array::c_style | py::array::forcecast> to_indices(const py::handle& h,
                                                                             const std::string& what) {
  const py::array raw = py::array::ensure(h);
  if (!raw) throw InvalidArgument(what + ": expected integers");
  const char k = raw.dtype().kind();
  // A float index would be truncated (3.9 -> 3).
  if (k != 'i' && k != 'u' && !(raw.size() == 0 && k == 'f'))
    throw InvalidArgument(what + ": expected integers, got " + py::str(raw.dtype()).cast<std::string>());
  return py::array_t<long long, py::array::c_style | py::array::forcecast>::ensure(raw);
}

std::vector<Vec3> to_points(const py::handle& h, std::size_t rows, const char* what) {
  auto a = to_reals(h, what);
  if (a.ndim() != 2 || a.shape(1) != 3 || a.shape(0) != static_cast<py::ssize_t>(rows))
    throw InvalidArgument(std::string(what) + ": expected " + std::to_string(rows) + " by 3");
  std::vector<Vec3> p(rows);
  for (std::size_t i = 0; i < rows; ++i) {
    p[i] = Vec3(a.data()[3 * i], a.data()[3 * i + 1], a.data()[3 * i + 2]);
    if (!p[i].allFinite()) throw InvalidArgument(std::string(what) + ": " + non_finite_point(i));
  }
  return p;
}

Vec3 to_vec3(const py::handle& h, const char* what) {
  auto a = to_reals(h, what);
  if (a.size() != 3) throw InvalidArgument(std::string(what) + ": expected 3 numbers");
  const Vec3 v(a.data()[0], a.data()[1], a.data()[2]);
  if (!v.allFinite()) throw InvalidArgument(std::string(what) + ": expected 3 finite numbers");
  return v;
}

std::vector<VertexId> to_vertices(const TetMesh& mesh, const py::handle& h) {
  auto a = to_indices(h, "vertex ids");
  std::vector<VertexId> out;
  out.reserve(a.size());
  for (py::ssize_t i = 0; i < a.size(); ++i) {
    const long long v = a.data()[i];
    if (v < 0 || v >= static_cast<long long>(mesh.vertex_capacity()) || !mesh.is_alive(VertexId(v)))
      throw InvalidArgument("vertex " + std::to_string(v) + " is not a live vertex of the mesh");
    out.emplace_back(static_cast<std::uint32_t>(v));
  }
  return out;
}

namespace {

// Through the readers' builder, so arrays get the checks and fixes a file gets (indices in
// range, inverted tets reoriented, overlapping tets refused, boundary tagged).
TetMesh from_arrays(const py::object& points_obj, const py::object& tets_obj, const py::object& labels) {
  const char* what = "TetMesh(points, tets)";
  const auto points = to_reals(points_obj, std::string(what) + ": points");
  const auto tets = to_indices(tets_obj, std::string(what) + ": tets");
  if (points.ndim() != 2 || points.shape(1) != 3) throw InvalidArgument(std::string(what) + ": points must be #V by 3");
  if (tets.ndim() != 2 || tets.shape(1) != 4) throw InvalidArgument(std::string(what) + ": tets must be #T by 4");
  io::RawMesh raw;
  raw.format = "arrays";
  raw.points.reserve(points.shape(0));
  auto p = points.unchecked<2>();
  for (py::ssize_t i = 0; i < points.shape(0); ++i) {
    raw.points.emplace_back(p(i, 0), p(i, 1), p(i, 2));
    if (!raw.points.back().allFinite()) throw InvalidArgument(std::string(what) + ": " + non_finite_point(i));
  }
  auto t = tets.unchecked<2>();
  raw.tets.reserve(tets.shape(0));
  for (py::ssize_t i = 0; i < tets.shape(0); ++i) {
    std::array<std::uint32_t, 4> q;
    for (int k = 0; k < 4; ++k) {
      const long long v = t(i, k);
      if (v < 0 || v >= points.shape(0))
        throw InvalidArgument(std::string(what) + ": tet #" + std::to_string(i) + " references vertex " +
                              std::to_string(v) + " out of range");
      q[k] = static_cast<std::uint32_t>(v);
    }
    raw.tets.push_back(q);
  }
  if (!labels.is_none()) {
    const auto l = to_indices(labels, std::string(what) + ": labels");
    if (l.ndim() != 1 || l.shape(0) != tets.shape(0))
      throw InvalidArgument(std::string(what) + ": labels must have one entry per tet");
    for (py::ssize_t i = 0; i < l.shape(0); ++i) {
      const long long x = l.data()[i];
      if (x < std::numeric_limits<int>::min() || x > std::numeric_limits<int>::max())
        throw InvalidArgument(std::string(what) + ": label " + std::to_string(x) + " of tet #" + std::to_string(i) +
                              " is out of range (a label is a 32-bit integer)");
      raw.tet_labels.push_back(static_cast<int>(x));
    }
  }
  return io::build_mesh(std::move(raw), what, nullptr);
}

py::array_t<long long> live_tets(const TetMesh& mesh) {
  const std::vector<TetId> ids = mesh.tets();
  py::array_t<long long> a({static_cast<py::ssize_t>(ids.size()), py::ssize_t(4)});
  auto w = a.mutable_unchecked<2>();
  for (std::size_t i = 0; i < ids.size(); ++i)
    for (int k = 0; k < 4; ++k) w(i, k) = mesh.tet_vertices(ids[i])[k].idx();
  return a;
}

template <class Id>
py::array_t<long long> id_array(const std::vector<Id>& ids) {
  py::array_t<long long> a(static_cast<py::ssize_t>(ids.size()));
  for (std::size_t i = 0; i < ids.size(); ++i) a.mutable_data()[i] = ids[i].is_valid() ? static_cast<long long>(ids[i].idx()) : -1LL;  // not the unsigned -1
  return a;
}

TetId to_tet(const TetMesh& mesh, long long t) {
  if (t < 0 || t >= static_cast<long long>(mesh.tet_capacity()) || !mesh.is_alive(TetId(t)))
    throw InvalidArgument("tet " + std::to_string(t) + " is not a live tet of the mesh");
  return TetId(static_cast<std::uint32_t>(t));
}

VertexId to_vertex(const TetMesh& mesh, long long v) { return to_vertices(mesh, py::int_(v)).front(); }

py::list origins(const std::vector<VertexOrigin>& list) {
  py::list out;
  for (const VertexOrigin& o : list) {
    py::list parents, weights;
    for (int k = 0; k < 4; ++k)
      if (o.parents[k].is_valid()) {
        parents.append(o.parents[k].idx());
        weights.append(o.weights[k]);
      }
    out.append(py::make_tuple(o.vertex.idx(), parents, weights));
  }
  return out;
}

std::array<int, 3> to_cells(const py::handle& h) {
  const auto a = to_indices(h, "cells");
  if (a.size() != 1 && a.size() != 3) throw InvalidArgument("cells: expected an integer or 3 integers");
  std::array<int, 3> c;
  for (int k = 0; k < 3; ++k) {
    const long long n = a.data()[a.size() == 1 ? 0 : k];
    // make_box checks the count; here only that it is an int (2**40 would wrap).
    if (n > std::numeric_limits<int>::max()) throw InvalidArgument("cells: " + std::to_string(n) + " is too large");
    c[k] = static_cast<int>(std::max<long long>(n, 0));
  }
  return c;
}

}  // namespace

void bind_mesh(py::module_& m) {
  py::class_<TopologyChange>(m, "TopologyChange",
                             "One batch of mesh edits (mesh/topology_change.h); pass it to every simulation's apply()")
      .def_property_readonly("removed_tets", [](const TopologyChange& c) { return id_array(c.removed_tets); })
      .def_property_readonly("added_tets", [](const TopologyChange& c) { return id_array(c.added_tets); })
      .def_property_readonly("added_vertices", [](const TopologyChange& c) { return origins(c.added_vertices); },
                             "[(vertex, parents, weights)] in creation order")
      .def_property_readonly("moved_vertices", [](const TopologyChange& c) { return origins(c.moved_vertices); },
                             "[(vertex, parents, weights)] in move order")
      .def_property_readonly("removed_vertices", [](const TopologyChange& c) { return id_array(c.removed_vertices); })
      .def_property_readonly("touched_vertices", [](const TopologyChange& c) { return id_array(c.touched_vertices); })
      .def("empty", &TopologyChange::empty);

  py::class_<TetMesh>(m, "TetMesh", "Tetrahedral mesh with stable ids (see docs/architecture.md)")
      .def(py::init<>())
      .def(py::init(&from_arrays), py::arg("points"), py::arg("tets"), py::arg("labels") = py::none(),
           "From #V by 3 positions and #T by 4 vertex indices (optional #T labels); inverted tets "
           "are reoriented, boundary faces tagged as surface.")
      .def_property_readonly("num_vertices", &TetMesh::num_vertices)
      .def_property_readonly("num_tets", &TetMesh::num_tets)
      .def_property_readonly("vertex_capacity", &TetMesh::vertex_capacity)
      .def_property_readonly("tet_capacity", &TetMesh::tet_capacity)
      .def_property_readonly(
          "points",
          [](const TetMesh& mesh) {
            std::vector<Vec3> p(mesh.vertex_capacity());
            for (std::uint32_t v = 0; v < p.size(); ++v) p[v] = mesh.rest(VertexId(v));
            return to_array(p);
          },
          "Rest positions, vertex_capacity by 3 (row = vertex id)")
      .def_property_readonly("tets", &live_tets, "Live tets, #T by 4 vertex ids, positively oriented")
      .def_property_readonly(
          "labels",
          [](const TetMesh& mesh) {
            const std::vector<TetId> ids = mesh.tets();
            py::array_t<int> a(static_cast<py::ssize_t>(ids.size()));
            for (std::size_t i = 0; i < ids.size(); ++i) a.mutable_data()[i] = mesh.label(ids[i]);
            return a;
          },
          "Region label of each live tet (same order as tets)")
      .def_property_readonly("tet_ids", [](const TetMesh& mesh) { return id_array(mesh.tets()); })
      .def_property_readonly("vertex_ids", [](const TetMesh& mesh) { return id_array(mesh.vertices()); })
      // Ids are 32-bit: a larger Python int must not wrap onto a live id.
      .def("is_alive_vertex", [](const TetMesh& mesh, long long v) {
        return v >= 0 && v < VertexId::invalid_index && mesh.is_alive(VertexId(std::uint32_t(v)));
      })
      .def("is_alive_tet", [](const TetMesh& mesh, long long t) {
        return t >= 0 && t < TetId::invalid_index && mesh.is_alive(TetId(std::uint32_t(t)));
      })
      .def("volume", &TetMesh::total_volume, "Total signed rest volume")
      .def(
          "boundary_faces",
          [](const TetMesh& mesh) {
            const std::vector<BoundaryFace> faces = mesh.boundary_faces();
            py::array_t<long long> f({static_cast<py::ssize_t>(faces.size()), py::ssize_t(3)});
            py::array_t<int> tags(static_cast<py::ssize_t>(faces.size()));
            auto w = f.mutable_unchecked<2>();
            for (std::size_t i = 0; i < faces.size(); ++i) {
              for (int k = 0; k < 3; ++k) w(i, k) = faces[i].vertices[k].idx();
              tags.mutable_data()[i] = faces[i].tag;
            }
            return py::make_tuple(f, tags);
          },
          "(#F by 3 outward-oriented vertex ids, #F tags: 1 surface, 2 cut)")
      .def(
          "validate",
          [](const TetMesh& mesh, bool manifold) { mesh.validate({true, manifold}); },
          py::arg("check_manifold_boundary") = false, "Checks every invariant; raises InvalidMesh")
      .def(
          "split_edge",
          [](TetMesh& mesh, long long a, long long b, double s) {
            return mesh.split_edge(to_vertex(mesh, a), to_vertex(mesh, b), s).idx();
          },
          py::arg("a"), py::arg("b"), py::arg("s") = 0.5, "New vertex at (1-s) a + s b splitting every tet around the edge")
      .def(
          "split_tet",
          [](TetMesh& mesh, long long t, const std::array<double, 4>& w) { return mesh.split_tet(to_tet(mesh, t), w).idx(); },
          py::arg("tet"), py::arg("weights") = std::array<double, 4>{0.25, 0.25, 0.25, 0.25},
          "New vertex at barycentric weights (all > 0, summing to 1) in the tet, split 1 -> 4")
      .def("take_change", &TetMesh::take_change, "The edits since the last call, as one TopologyChange")
      .def_property_readonly("has_pending_change", &TetMesh::has_pending_change)
      .def(
          "compact",
          [](TetMesh& mesh) {
            CompactMaps maps = mesh.compact();
            return py::make_tuple(id_array(maps.vertex), id_array(maps.tet));
          },
          "Renumbers densely; returns (old->new vertex map, old->new tet map), -1 for dead ids")
      .def(
          "compact_spatially",
          [](TetMesh& mesh) {
            CompactMaps maps = mesh.compact_spatially();
            return py::make_tuple(id_array(maps.vertex), id_array(maps.tet));
          },
          "Renumbers densely along a space-filling curve (vertices by position, tets by centroid: solvers run "
          "faster); returns (old->new vertex map, old->new tet map), -1 for dead ids")
      .def(
          "copy", [](const TetMesh& mesh) { return TetMesh(mesh); },
          "An independent copy: the same ids, dead slots and pending change")
      .def("__repr__", [](const TetMesh& mesh) {
        std::ostringstream s;
        s << "<incise.TetMesh " << mesh.num_vertices() << " vertices, " << mesh.num_tets() << " tets>";
        return s.str();
      });

  m.def(
      "refine_uniform", [](const TetMesh& mesh) { return refine_uniform(mesh); }, py::arg("mesh"),
      "Every tet split 1:8 (edges half as long; labels and boundary tags inherited); the input's vertex ids are "
      "kept and the edge midpoints follow. The input must be compact (TetMesh.compact()); a cut stays open");
  m.def(
      "generate_box",
      [](const py::object& size, const py::object& cells, int label) {
        return make_box(py::isinstance<py::float_>(size) || py::isinstance<py::int_>(size)
                            ? Vec3::Constant(size.cast<double>())
                            : to_vec3(size, "size"),
                        to_cells(cells), label);
      },
      py::arg("size") = py::make_tuple(1.0, 1.0, 1.0), py::arg("cells") = py::make_tuple(4, 4, 4),
      py::arg("label") = 1, "Box [0,size] with cells (int or 3 ints) cubes of 6 Kuhn tets each");
  m.def(
      "generate_ellipsoid",
      [](const py::object& radii, int n, int label) {
        return make_ellipsoid(py::isinstance<py::float_>(radii) || py::isinstance<py::int_>(radii)
                                  ? Vec3::Constant(radii.cast<double>())
                                  : to_vec3(radii, "radii"),
                              n, label);
      },
      py::arg("radii") = py::make_tuple(1.0, 1.0, 1.0), py::arg("n") = 4, py::arg("label") = 1,
      "Ellipsoid centred at the origin: (2n)^3 cubes mapped onto the ball, then scaled");
}

}  // namespace incise::python
