#pragma once
// Shared helpers of the io tests: scratch directories, file contents, the meshes the round
// trips run over, and exact mesh comparison.
#include <catch2/catch.hpp>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>

#include "mesh/generate.h"
#include "mesh/io/tet_io.h"

namespace incise::testing {

namespace fs = std::filesystem;

// A fresh directory under the build tree, removed at the end of the test.
struct ScratchDir {
  fs::path path;
  explicit ScratchDir(const std::string& name) {
    path = fs::path(INCISE_BINARY_DIR) / "io_test_tmp" / (name + "_" + std::to_string(::getpid()));
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~ScratchDir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  std::string operator/(const std::string& f) const { return (path / f).string(); }
};

inline void write_text(const std::string& path, const std::string& text) {
  std::ofstream(path, std::ios::binary) << text;
}
inline std::string read_text(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

// An ellipsoid whose tets carry four labels by octant and whose boundary carries three tags.
inline TetMesh labeled_ellipsoid(double scale = 1.0, const Vec3& offset = Vec3::Zero()) {
  TetMesh m = make_ellipsoid(Vec3(1.0, 0.6, 0.4) * scale, 2, 1);
  for (VertexId v : m.vertices()) m.set_rest(v, m.rest(v) + offset);
  for (TetId t : m.tets()) {
    Vec3 c = Vec3::Zero();
    for (VertexId v : m.tet_vertices(t)) c += m.rest(v) - offset;
    m.set_label(t, 1 + (c.x() > 0 ? 1 : 0) + (c.z() > 0 ? 2 : 0) + (c.y() > 0 ? 10 : 0));
  }
  for (const BoundaryFace& f : m.boundary_faces()) {
    Vec3 c = Vec3::Zero();
    for (VertexId v : f.vertices) c += m.rest(v) - offset;
    m.set_face_tag(f.tet, f.local, c.x() > 0 ? 17 : (c.y() > 0 ? kTagCut : kTagSurface));
  }
  return m;
}

// A box from which some tets and a vertex were removed: dead ids the writers must skip.
inline TetMesh box_with_holes() {
  TetMesh m = make_box(Vec3(2, 1, 1), {4, 2, 2}, 3);
  auto tets = m.tets();
  for (std::size_t i = 0; i < tets.size(); i += 7) m.set_label(tets[i], 8);
  // Remove tets touching the corner vertex 0, then the vertex itself.
  std::vector<TetId> around(m.incident_tets(VertexId(0)).begin(), m.incident_tets(VertexId(0)).end());
  for (TetId t : around) m.remove_tet(t);
  m.remove_vertex(VertexId(0));
  tag_boundary(m);
  m.discard_change();
  return m;
}

// Live vertices in id order and live tets in id order, as the writers emit them.
// Which boundary tags a format carries: all (triangles with tags: msh, mesh), the cut faces
// only (a per-tet cut_face_mask: VTU, VTK), none (every face comes back kTagSurface).
enum class TagsCarried { All, Cut, None };

inline void require_same_mesh(const TetMesh& a, const TetMesh& b, TagsCarried tags) {
  REQUIRE(b.num_vertices() == a.num_vertices());
  REQUIRE(b.num_tets() == a.num_tets());
  auto va = a.vertices(), vb = b.vertices();
  std::vector<std::uint32_t> map(a.vertex_capacity(), 0);
  for (std::size_t i = 0; i < va.size(); ++i) {
    map[va[i].idx()] = vb[i].idx();
    if (a.rest(va[i]) != b.rest(vb[i])) {
      INFO("vertex " << i << ": " << a.rest(va[i]).transpose() << " vs " << b.rest(vb[i]).transpose());
      REQUIRE(a.rest(va[i]) == b.rest(vb[i]));
    }
  }
  auto ta = a.tets(), tb = b.tets();
  for (std::size_t i = 0; i < ta.size(); ++i) {
    const auto& x = a.tet_vertices(ta[i]);
    const auto& y = b.tet_vertices(tb[i]);
    for (int k = 0; k < 4; ++k) REQUIRE(map[x[k].idx()] == y[k].idx());
    REQUIRE(a.label(ta[i]) == b.label(tb[i]));
    for (int f = 0; f < 4; ++f) {
      REQUIRE(a.neighbor(ta[i], f).is_valid() == b.neighbor(tb[i], f).is_valid());
      if (!b.neighbor(tb[i], f).is_valid()) {
        const std::uint16_t was = a.face_tag(ta[i], f);
        if (tags == TagsCarried::All)
          REQUIRE(b.face_tag(tb[i], f) == (was == kTagNone ? std::uint16_t(kTagSurface) : was));
        else if (tags == TagsCarried::Cut && was == kTagCut)
          REQUIRE(b.face_tag(tb[i], f) == kTagCut);
        else
          REQUIRE(b.face_tag(tb[i], f) == kTagSurface);
      }
    }
  }
}

inline bool have_meshio() { return std::system("/usr/bin/python3 -c 'import meshio' >/dev/null 2>&1") == 0; }

inline std::string meshio_tool() { return std::string(INCISE_SOURCE_DIR) + "/tests/io/meshio_tool.py"; }

}  // namespace incise::testing
