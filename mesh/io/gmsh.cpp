// Gmsh .msh: 1.0, 2.x ASCII and 4.1 ASCII read; 2.2 ASCII written.
// Labels: the physical tag of a tet, or its elementary/entity tag when it has none.
#include <unordered_map>

#include "mesh/io/formats.h"
#include "mesh/io/parse_util.h"

namespace incise::io {

namespace {

// Gmsh node tags are arbitrary positive integers; most files number them 1..N, so a dense
// table is the common case and a hash map the fallback.
class NodeIds {
public:
  void add(long long id) { ids_.push_back(id); }
  std::size_t size() const { return ids_.size(); }
  void finish(const Cursor& c) {
    long long lo = 0, hi = -1;
    for (long long id : ids_) {
      if (id < lo) lo = id;
      if (id > hi) hi = id;
    }
    dense_ok_ = lo >= 0 && hi < static_cast<long long>(4 * ids_.size() + 1024);
    if (dense_ok_) {
      dense_.assign(static_cast<std::size_t>(hi + 1), kNone);
      for (std::size_t i = 0; i < ids_.size(); ++i) {
        auto& slot = dense_[static_cast<std::size_t>(ids_[i])];
        if (slot != kNone) throw_io(c.file(), 0, "duplicate node id " + std::to_string(ids_[i]));
        slot = static_cast<std::uint32_t>(i);
      }
    } else {
      sparse_.reserve(ids_.size());
      for (std::size_t i = 0; i < ids_.size(); ++i)
        if (!sparse_.emplace(ids_[i], static_cast<std::uint32_t>(i)).second)
          throw_io(c.file(), 0, "duplicate node id " + std::to_string(ids_[i]));
    }
    ids_.clear();
    ids_.shrink_to_fit();
  }
  std::uint32_t lookup(long long id, const Cursor& c) const {
    if (dense_ok_) {
      if (id >= 0 && static_cast<std::size_t>(id) < dense_.size() && dense_[static_cast<std::size_t>(id)] != kNone)
        return dense_[static_cast<std::size_t>(id)];
    } else {
      auto it = sparse_.find(id);
      if (it != sparse_.end()) return it->second;
    }
    c.fail("element references unknown node " + std::to_string(id));
  }

private:
  static constexpr std::uint32_t kNone = 0xffffffffu;
  std::vector<long long> ids_;
  bool dense_ok_ = true;
  std::vector<std::uint32_t> dense_;
  std::unordered_map<long long, std::uint32_t> sparse_;
};

void expect(Cursor& c, std::string_view want, const char* hint) {
  std::string_view t = c.token(std::string(want).c_str());
  if (t != want) c.fail("expected " + std::string(want) + ", got '" + Cursor::shorten(t) + "'" + hint);
}

void skip_section(Cursor& c, std::string_view name) {
  std::string end = "$End" + std::string(name.substr(1));
  std::string end_upper = "$END" + std::string(name.substr(1));  // 1.0 spells it $ENDNOD
  long start = c.line();
  c.next_line();
  while (!c.at_end()) {
    std::string_view l = c.rest_of_line();
    while (!l.empty() && (l.back() == ' ' || l.back() == '\t')) l.remove_suffix(1);
    while (!l.empty() && (l.front() == ' ' || l.front() == '\t')) l.remove_prefix(1);
    if (equals_nocase(l, end) || equals_nocase(l, end_upper)) return;
  }
  throw_io(c.file(), start, "section " + std::string(name) + " is not terminated by " + end);
}

void add_tet(RawMesh& m, Cursor& c, const NodeIds& ids, int label, long line) {
  std::array<std::uint32_t, 4> t;
  for (auto& v : t) v = ids.lookup(c.integer("node id", true), c);
  m.tets.push_back(t);
  m.tet_labels.push_back(label);
  m.tet_lines.push_back(line);
}
void add_tri(RawMesh& m, Cursor& c, const NodeIds& ids, int tag) {
  std::array<std::uint32_t, 3> t;
  for (auto& v : t) v = ids.lookup(c.integer("node id", true), c);
  m.tris.push_back(t);
  m.tri_tags.push_back(tag);
  ++m.skipped_cells;
}

int to_label(long long v, const Cursor& c) {
  if (v < -2147483647LL || v > 2147483647LL) c.fail("tag " + std::to_string(v) + " out of range");
  return static_cast<int>(v);
}

// ---- 1.0 and 2.x: one node per line, one element per line with its tags ----------------
void read_nodes_v2(Cursor& c, RawMesh& m, NodeIds& ids) {
  std::size_t n = c.count("number of nodes", 8);
  m.points.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    ids.add(c.integer("node id"));
    double x = c.real("x coordinate", true), y = c.real("y coordinate", true), z = c.real("z coordinate", true);
    m.points.emplace_back(x, y, z);
  }
}

void read_elements_v2(Cursor& c, RawMesh& m, const NodeIds& ids, bool v1) {
  std::size_t n = c.count("number of elements", 8);
  m.tets.reserve(std::min<std::size_t>(n, c.remaining() / 16));
  for (std::size_t i = 0; i < n; ++i) {
    c.skip_ws();
    long line = c.line();
    c.integer("element id");
    long long type = c.integer("element type", true);
    long long phys = 0, elem = 0;
    if (v1) {
      phys = c.integer("physical region", true);
      elem = c.integer("elementary region", true);
      long long nn = c.integer("number of nodes", true);
      if ((type == 4 && nn != 4) || (type == 2 && nn != 3))
        c.fail("element type " + std::to_string(type) + " with " + std::to_string(nn) + " nodes");
    } else {
      long long ntags = c.integer("number of tags", true);
      if (ntags < 0 || ntags > 64) c.fail("bad number of tags " + std::to_string(ntags));
      for (long long k = 0; k < ntags; ++k) {
        long long tag = c.integer("tag", true);
        if (k == 0) phys = tag;
        if (k == 1) elem = tag;
      }
    }
    int label = to_label(phys != 0 ? phys : elem, c);
    if (type == 4 || type == 11) {  // tet, 10-node tet (corners first)
      add_tet(m, c, ids, label, line);
    } else if (type == 2 || type == 9) {  // triangle, 6-node triangle
      add_tri(m, c, ids, label);
    } else {
      ++m.skipped_cells;
    }
    c.next_line();
  }
}

// ---- 4.1: entity blocks; physical tags live in $Entities --------------------------------
using EntityPhysical = std::unordered_map<long long, int>;  // (dim << 32 | tag) -> physical
long long entity_key(long long dim, long long tag) { return (dim << 32) ^ (tag & 0xffffffffLL); }

void read_entities_v4(Cursor& c, EntityPhysical& phys) {
  std::size_t counts[4];
  for (int d = 0; d < 4; ++d) counts[d] = c.count("number of entities", 8);
  for (int d = 0; d < 4; ++d) {
    for (std::size_t i = 0; i < counts[d]; ++i) {
      long long tag = c.integer("entity tag");
      for (int k = 0; k < (d == 0 ? 3 : 6); ++k) c.real("entity bounding box", true);
      std::size_t np = c.count("number of physical tags", 2, true);
      for (std::size_t k = 0; k < np; ++k) {
        long long p = c.integer("physical tag", true);
        if (k == 0) phys[entity_key(d, tag)] = to_label(p, c);
      }
      if (d > 0) {
        std::size_t nb = c.count("number of bounding entities", 2, true);
        for (std::size_t k = 0; k < nb; ++k) c.integer("bounding entity", true);
      }
    }
  }
}

void read_nodes_v4(Cursor& c, RawMesh& m, NodeIds& ids) {
  std::size_t blocks = c.count("number of node blocks", 8);
  std::size_t total = c.count("number of nodes", 8);
  c.integer("min node tag");
  c.integer("max node tag");
  m.points.reserve(total);
  for (std::size_t b = 0; b < blocks; ++b) {
    long long dim = c.integer("entity dimension");
    c.integer("entity tag", true);
    long long parametric = c.integer("parametric flag", true);
    std::size_t n = c.count("nodes in block", 8, true);
    if (dim < 0 || dim > 3) c.fail("bad entity dimension " + std::to_string(dim));
    if (m.points.size() + n > total) c.fail("node blocks hold more nodes than the declared " + std::to_string(total));
    for (std::size_t i = 0; i < n; ++i) ids.add(c.integer("node tag"));
    for (std::size_t i = 0; i < n; ++i) {
      double x = c.real("x coordinate"), y = c.real("y coordinate", true), z = c.real("z coordinate", true);
      m.points.emplace_back(x, y, z);
      if (parametric)
        for (long long k = 0; k < dim; ++k) c.real("parametric coordinate", true);
    }
  }
  if (m.points.size() != total)
    c.fail("node blocks hold " + std::to_string(m.points.size()) + " nodes, header says " + std::to_string(total));
}

void read_elements_v4(Cursor& c, RawMesh& m, const NodeIds& ids, const EntityPhysical& phys) {
  std::size_t blocks = c.count("number of element blocks", 8);
  std::size_t total = c.count("number of elements", 4);
  c.integer("min element tag");
  c.integer("max element tag");
  std::size_t seen = 0;
  for (std::size_t b = 0; b < blocks; ++b) {
    long long dim = c.integer("entity dimension");
    long long tag = c.integer("entity tag", true);
    long long type = c.integer("element type", true);
    std::size_t n = c.count("elements in block", 4, true);
    seen += n;
    if (seen > total) c.fail("element blocks hold more elements than the declared " + std::to_string(total));
    auto it = phys.find(entity_key(dim, tag));
    int label = it != phys.end() ? it->second : to_label(tag, c);
    c.next_line();
    for (std::size_t i = 0; i < n; ++i) {
      c.skip_ws();
      long line = c.line();
      c.integer("element tag");
      if (type == 4 || type == 11)
        add_tet(m, c, ids, label, line);
      else if (type == 2 || type == 9)
        add_tri(m, c, ids, label);
      else
        ++m.skipped_cells;
      c.next_line();
    }
  }
  if (seen != total) c.fail("element blocks hold " + std::to_string(seen) + " elements, header says " + std::to_string(total));
}

}  // namespace

RawMesh parse_gmsh(const std::string& file, const std::string& text) {
  Cursor c(file, text);
  RawMesh m;
  std::string_view first = c.token("$MeshFormat");
  int major = 0;
  if (first == "$NOD" || first == "$NOE") {
    major = 1;
    m.format = "gmsh 1.0";
  } else if (first == "$MeshFormat") {
    std::string_view vt = c.token("version");
    double version = c.to_real(vt, "version");
    long long filetype = c.integer("file type", true);
    c.integer("data size", true);
    if (filetype != 0) c.fail("binary Gmsh files are not supported; save as ASCII");
    if (version >= 2.0 && version < 3.0) {
      major = 2;
    } else if (version == 4.1) {
      major = 4;
    } else {
      c.fail("unsupported Gmsh version " + std::string(vt) + " (2.x, 4.1 ASCII and 1.0 are read)");
    }
    m.format = "gmsh " + std::string(vt) + " ascii";
    expect(c, "$EndMeshFormat", "");
  } else {
    c.fail("not a Gmsh file: expected $MeshFormat or $NOD, got '" + Cursor::shorten(first) + "'");
  }
  NodeIds ids;
  EntityPhysical phys;
  bool have_nodes = false, have_elements = false;
  std::string_view section = major == 1 ? first : std::string_view();
  while (true) {
    if (section.empty()) {
      if (c.at_end()) break;
      section = c.token("section");
    }
    long start = c.line();
    if (section.empty() || section[0] != '$') c.fail("expected a $Section, got '" + Cursor::shorten(section) + "'");
    if (major == 1 && section == "$NOD") {
      if (have_nodes) c.fail("second $NOD section");
      read_nodes_v2(c, m, ids);
      expect(c, "$ENDNOD", " (wrong node count?)");
      ids.finish(c);
      have_nodes = true;
    } else if (major == 1 && section == "$ELM") {
      if (!have_nodes) c.fail("$ELM before $NOD");
      read_elements_v2(c, m, ids, true);
      expect(c, "$ENDELM", " (wrong element count?)");
      have_elements = true;
    } else if (major >= 2 && section == "$Nodes") {
      if (have_nodes) c.fail("second $Nodes section");
      if (major == 2)
        read_nodes_v2(c, m, ids);
      else
        read_nodes_v4(c, m, ids);
      expect(c, "$EndNodes", " (wrong node count?)");
      ids.finish(c);
      have_nodes = true;
    } else if (major >= 2 && section == "$Elements") {
      if (!have_nodes) c.fail("$Elements before $Nodes");
      if (have_elements) c.fail("second $Elements section");
      if (major == 2)
        read_elements_v2(c, m, ids, false);
      else
        read_elements_v4(c, m, ids, phys);
      expect(c, "$EndElements", " (wrong element count?)");
      have_elements = true;
    } else if (major == 4 && section == "$Entities") {
      read_entities_v4(c, phys);
      expect(c, "$EndEntities", " (wrong entity count?)");
    } else {
      (void)start;
      skip_section(c, section);
    }
    section = {};
  }
  if (!have_nodes) throw_io(file, 0, major == 1 ? "no $NOD section" : "no $Nodes section");
  if (!have_elements) throw_io(file, 0, major == 1 ? "no $ELM section" : "no $Elements section");
  return m;
}

void write_gmsh22(const FlatMesh& m, AtomicFile& out, const WriteOptions& options) {
  std::string b;
  b.reserve(std::size_t(1) << 21);
  b += "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n";
  append_int(b, static_cast<long long>(m.points.size()));
  b += '\n';
  for (std::size_t i = 0; i < m.points.size(); ++i) {
    append_int(b, static_cast<long long>(i + 1));
    for (int d = 0; d < 3; ++d) {
      b += ' ';
      append_real(b, m.points[i][d]);
    }
    b += '\n';
    out.flush_if_large(b);
  }
  b += "$EndNodes\n$Elements\n";
  const std::size_t nf = options.write_boundary ? m.faces.size() : 0;
  append_int(b, static_cast<long long>(nf + m.tets.size()));
  b += '\n';
  long long id = 1;
  for (std::size_t i = 0; i < nf; ++i) {
    append_int(b, id++);
    b += " 2 2 ";
    append_int(b, m.face_tags[i]);
    b += ' ';
    append_int(b, m.face_tags[i]);
    for (std::uint32_t v : m.faces[i]) {
      b += ' ';
      append_int(b, v + 1LL);
    }
    b += '\n';
    out.flush_if_large(b);
  }
  for (std::size_t i = 0; i < m.tets.size(); ++i) {
    append_int(b, id++);
    b += " 4 2 ";
    append_int(b, m.labels[i]);
    b += ' ';
    append_int(b, m.labels[i]);
    for (std::uint32_t v : m.tets[i]) {
      b += ' ';
      append_int(b, v + 1LL);
    }
    b += '\n';
    out.flush_if_large(b);
  }
  b += "$EndElements\n";
  out.write(b);
}

}  // namespace incise::io
