// TetGen .node/.ele: points numbered consecutively from 0 or 1; the first tet attribute is
// the region label (tetgen -A). A cut mesh's .ele has a second attribute, each tet's
// cut_face_mask (bit k: its face opposite corner k is a cut face; tet_io.h), which its header
// comment names: only a file that says so has its second attribute read as the mask (another
// tool's second attribute means something else).
#include <cmath>
#include <string_view>

#include "mesh/io/formats.h"
#include "mesh/io/parse_util.h"

namespace incise::io {

namespace {
constexpr std::string_view kCutMaskAttribute = "cut_face_mask";
}  // namespace

RawMesh parse_tetgen(const std::string& node_file, const std::string& node_text, const std::string& ele_file,
                     const std::string& ele_text) {
  RawMesh m;
  m.format = "tetgen";
  m.tet_file = ele_file;
  long long base = 0;
  {
    Cursor c(node_file, node_text, '#');
    if (c.at_end()) c.fail("empty file");
    std::size_t n = c.count("number of points", 8);
    long long dim = c.integer("dimension", true);
    if (dim != 3) c.fail("only 3D points are supported (dimension " + std::to_string(dim) + ")");
    long long nattr = c.integer("number of attributes", true);
    long long nmark = c.integer("number of boundary markers", true);
    if (nattr < 0 || nattr > 1024) c.fail("bad number of attributes " + std::to_string(nattr));
    if (nmark < 0 || nmark > 1) c.fail("boundary marker flag must be 0 or 1");
    if (n == 0) c.fail("no points (points in a .poly file are not supported)");
    m.points.reserve(n);
    for (std::size_t i = 0; i < n; ++i) {
      long long idx = c.integer("point index");
      if (i == 0) {
        if (idx != 0 && idx != 1) c.fail("point numbering must start at 0 or 1, not " + std::to_string(idx));
        base = idx;
      } else if (idx != base + static_cast<long long>(i)) {
        c.fail("point index " + std::to_string(idx) + " out of sequence (expected " +
               std::to_string(base + static_cast<long long>(i)) + ")");
      }
      double x = c.real("x coordinate", true), y = c.real("y coordinate", true), z = c.real("z coordinate", true);
      for (long long k = 0; k < nattr + nmark; ++k) c.real("point attribute", true);
      m.points.emplace_back(x, y, z);
    }
    if (!c.at_end()) c.fail("more points than the declared " + std::to_string(n));
  }
  // The header comment (the lines before the first number) names the attributes.
  bool has_mask = false;
  for (std::size_t at = 0; at < ele_text.size();) {
    std::size_t end = ele_text.find('\n', at);
    if (end == std::string::npos) end = ele_text.size();
    const std::string_view line(ele_text.data() + at, end - at);
    const std::size_t first = line.find_first_not_of(" \t\r");
    if (first != std::string_view::npos && line[first] != '#') break;
    if (line.find(kCutMaskAttribute) != std::string_view::npos) has_mask = true;
    at = end + 1;
  }
  Cursor c(ele_file, ele_text, '#');
  if (c.at_end()) c.fail("empty file");
  std::size_t n = c.count("number of tetrahedra", 10);
  long long per = c.integer("nodes per tetrahedron", true);
  if (per != 4 && per != 10) c.fail("nodes per tetrahedron must be 4 or 10, not " + std::to_string(per));
  long long nattr = c.eol() ? 0 : c.integer("number of attributes", true);
  if (nattr < 0 || nattr > 1024) c.fail("bad number of attributes " + std::to_string(nattr));
  m.tets.reserve(n);
  m.tet_labels.reserve(n);
  m.tet_lines.reserve(n);
  std::vector<double> mask;
  if (has_mask && nattr >= 2) mask.reserve(n);
  const long long np = static_cast<long long>(m.points.size());
  for (std::size_t i = 0; i < n; ++i) {
    c.skip_ws();
    long line = c.line();
    c.integer("tetrahedron index");
    std::array<std::uint32_t, 4> t;
    for (long long k = 0; k < per; ++k) {
      long long v = c.integer("point index", true) - base;
      if (v < 0 || v >= np)
        c.fail("point index " + std::to_string(v + base) + " out of range " + std::to_string(base) + ".." +
               std::to_string(np - 1 + base));
      if (k < 4) t[k] = static_cast<std::uint32_t>(v);
    }
    int label = 0;
    for (long long k = 0; k < nattr; ++k) {
      double a = c.real("region attribute", true);
      if (k == 0) {
        if (std::abs(a) > 2147483647.0) c.fail("region attribute out of range");
        label = static_cast<int>(std::lround(a));
      } else if (k == 1 && has_mask) {
        if (!(a >= 0 && a <= 15) || a != std::floor(a)) c.fail("cut face mask must be an integer 0..15");
        mask.push_back(a);
      }
    }
    m.tets.push_back(t);
    m.tet_labels.push_back(label);
    m.tet_lines.push_back(line);
  }
  if (!c.at_end()) c.fail("more tetrahedra than the declared " + std::to_string(n));
  if (!mask.empty()) m.cell_scalars.emplace_back("cut_face_mask", std::move(mask));
  return m;
}

void write_tetgen(const FlatMesh& m, AtomicFile& node, AtomicFile& ele, const WriteOptions&) {
  std::string b;
  b.reserve(std::size_t(1) << 21);
  b += "# incise tetrahedral mesh\n";
  append_int(b, static_cast<long long>(m.points.size()));
  b += " 3 0 0\n";
  for (std::size_t i = 0; i < m.points.size(); ++i) {
    append_int(b, static_cast<long long>(i));
    for (int d = 0; d < 3; ++d) {
      b += ' ';
      append_real(b, m.points[i][d]);
    }
    b += '\n';
    node.flush_if_large(b);
  }
  node.write(b);
  b.clear();
  const FlatMesh::DenseField* mask = nullptr;
  for (const FlatMesh::DenseField& f : m.cell_data)
    if (f.name == "cut_face_mask" && f.components == 1 && f.values.size() == m.tets.size()) mask = &f;
  if (mask) {
    b += "# incise tetrahedral mesh; attributes: region label, ";
    b += kCutMaskAttribute;
    b += " (bit k: the face opposite corner k is a cut face)\n";
  } else {
    b += "# incise tetrahedral mesh; attribute: region label\n";
  }
  append_int(b, static_cast<long long>(m.tets.size()));
  b += mask ? " 4 2\n" : " 4 1\n";
  for (std::size_t i = 0; i < m.tets.size(); ++i) {
    append_int(b, static_cast<long long>(i));
    for (std::uint32_t v : m.tets[i]) {
      b += ' ';
      append_int(b, v);
    }
    b += ' ';
    append_int(b, m.labels[i]);
    if (mask) {
      b += ' ';
      append_int(b, static_cast<long long>(mask->values[i]));
    }
    b += '\n';
    ele.flush_if_large(b);
  }
  ele.write(b);
}

}  // namespace incise::io
