// Medit .mesh (ASCII): Vertices, Tetrahedra (ref = label), Triangles (ref = boundary tag).
// Other keywords are skipped up to the next keyword.
#include <cctype>

#include "mesh/io/formats.h"
#include "mesh/io/parse_util.h"

namespace incise::io {

namespace {

bool is_keyword(std::string_view t) { return !t.empty() && std::isalpha(static_cast<unsigned char>(t[0])); }

std::uint32_t vertex_index(Cursor& c, std::size_t np, bool same_line = true) {
  long long v = c.integer("vertex index", same_line);
  if (v < 1 || static_cast<std::size_t>(v) > np)
    c.fail("vertex index " + std::to_string(v) + " out of range 1.." + std::to_string(np));
  return static_cast<std::uint32_t>(v - 1);
}

int ref_value(Cursor& c) {
  long long r = c.integer("reference", true);
  if (r < -2147483647LL || r > 2147483647LL) c.fail("reference " + std::to_string(r) + " out of range");
  return static_cast<int>(r);
}

}  // namespace

RawMesh parse_medit(const std::string& file, const std::string& text) {
  Cursor c(file, text, '#');
  RawMesh m;
  m.format = "medit";
  std::string_view first = c.token("MeshVersionFormatted");
  if (first == "MeshVersionUnformatted") c.fail("binary Medit files are not supported (use .mesh ASCII)");
  if (first != "MeshVersionFormatted")
    c.fail("not a Medit file: expected MeshVersionFormatted, got '" + Cursor::shorten(first) + "'");
  c.integer("version");
  bool have_vertices = false, have_end = false;
  while (!c.at_end()) {
    std::string_view kw = c.token("keyword");
    if (!is_keyword(kw)) c.fail("expected a keyword, got '" + Cursor::shorten(kw) + "'");
    if (kw == "End") {
      have_end = true;
      break;
    }
    if (kw == "Dimension") {
      long long d = c.integer("dimension");
      if (d != 3) c.fail("only 3D meshes are supported (Dimension " + std::to_string(d) + ")");
    } else if (kw == "Vertices") {
      if (have_vertices) c.fail("second Vertices section");
      std::size_t n = c.count("number of vertices", 8);
      m.points.reserve(n);
      for (std::size_t i = 0; i < n; ++i) {
        double x = c.real("x coordinate"), y = c.real("y coordinate", true), z = c.real("z coordinate", true);
        c.integer("vertex reference", true);
        m.points.emplace_back(x, y, z);
      }
      have_vertices = true;
    } else if (kw == "Tetrahedra" || kw == "TetrahedraP2") {
      if (!have_vertices) c.fail(std::string(kw) + " before Vertices");
      std::size_t n = c.count("number of tetrahedra", 10);
      m.tets.reserve(m.tets.size() + n);
      const int extra = kw == "TetrahedraP2" ? 6 : 0;  // mid-edge nodes after the corners
      for (std::size_t i = 0; i < n; ++i) {
        c.skip_ws();
        long line = c.line();
        std::array<std::uint32_t, 4> t;
        for (int k = 0; k < 4; ++k) t[k] = vertex_index(c, m.points.size(), k > 0);
        for (int k = 0; k < extra; ++k) vertex_index(c, m.points.size());
        m.tets.push_back(t);
        m.tet_labels.push_back(ref_value(c));
        m.tet_lines.push_back(line);
      }
    } else if (kw == "Triangles") {
      if (!have_vertices) c.fail("Triangles before Vertices");
      std::size_t n = c.count("number of triangles", 8);
      m.tris.reserve(m.tris.size() + n);
      for (std::size_t i = 0; i < n; ++i) {
        c.skip_ws();
        std::array<std::uint32_t, 3> t;
        for (int k = 0; k < 3; ++k) t[k] = vertex_index(c, m.points.size(), k > 0);
        m.tris.push_back(t);
        m.tri_tags.push_back(ref_value(c));
        ++m.skipped_cells;
      }
    } else {
      // Edges, Corners, Ridges, Required*, Normals, ...: a count and numbers up to the next
      // keyword. Cells among them are counted as skipped.
      bool cells = kw == "Edges" || kw == "Quadrilaterals" || kw == "Hexahedra" || kw == "Prisms" ||
                   kw == "Pyramids" || kw == "Corners";
      std::size_t n = 0;
      if (!is_keyword(c.peek()) && !c.peek().empty()) n = c.count("count", 2);
      if (cells) m.skipped_cells += n;
      while (!c.at_end() && !is_keyword(c.peek())) c.token("value");
    }
  }
  if (!have_vertices) throw_io(file, 0, "no Vertices section");
  (void)have_end;  // End is optional in practice
  return m;
}

void write_medit(const FlatMesh& m, AtomicFile& out, const WriteOptions& options) {
  std::string b;
  b.reserve(std::size_t(1) << 21);
  b += "MeshVersionFormatted 2\nDimension 3\n\nVertices\n";
  append_int(b, static_cast<long long>(m.points.size()));
  b += '\n';
  for (const Vec3& p : m.points) {
    for (int d = 0; d < 3; ++d) {
      append_real(b, p[d]);
      b += ' ';
    }
    b += "0\n";
    out.flush_if_large(b);
  }
  if (options.write_boundary && !m.faces.empty()) {
    b += "\nTriangles\n";
    append_int(b, static_cast<long long>(m.faces.size()));
    b += '\n';
    for (std::size_t i = 0; i < m.faces.size(); ++i) {
      for (std::uint32_t v : m.faces[i]) {
        append_int(b, v + 1LL);
        b += ' ';
      }
      append_int(b, m.face_tags[i]);
      b += '\n';
      out.flush_if_large(b);
    }
  }
  b += "\nTetrahedra\n";
  append_int(b, static_cast<long long>(m.tets.size()));
  b += '\n';
  for (std::size_t i = 0; i < m.tets.size(); ++i) {
    for (std::uint32_t v : m.tets[i]) {
      append_int(b, v + 1LL);
      b += ' ';
    }
    append_int(b, m.labels[i]);
    b += '\n';
    out.flush_if_large(b);
  }
  b += "\nEnd\n";
  out.write(b);
}

}  // namespace incise::io
