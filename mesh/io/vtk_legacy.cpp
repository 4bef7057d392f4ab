// VTK legacy .vtk: UNSTRUCTURED_GRID, ASCII or BINARY (big-endian), versions up to 5.1
// (OFFSETS/CONNECTIVITY cells). Written as 4.2, which every VTK, ParaView and meshio reads.
#include <algorithm>
#include <cmath>

#include "mesh/io/binary_util.h"
#include "mesh/io/formats.h"
#include "mesh/io/parse_util.h"

namespace incise::io {

NumType vtk_legacy_type(std::string_view n) {
  if (n == "unsigned_char") return NumType::UInt8;
  if (n == "char" || n == "signed_char") return NumType::Int8;
  if (n == "unsigned_short") return NumType::UInt16;
  if (n == "short") return NumType::Int16;
  if (n == "unsigned_int" || n == "vtktypeuint32") return NumType::UInt32;
  if (n == "int" || n == "vtktypeint32") return NumType::Int32;
  if (n == "unsigned_long" || n == "vtktypeuint64") return NumType::UInt64;
  if (n == "long" || n == "vtktypeint64" || n == "vtkIdType") return NumType::Int64;
  if (n == "float") return NumType::Float32;
  if (n == "double") return NumType::Float64;
  return NumType::Unknown;
}

namespace {

class VtkReader {
public:
  VtkReader(const std::string& file, const std::string& text) : c_(file, text) {}

  RawMesh parse() {
    std::string_view header = c_.rest_of_line();
    constexpr std::string_view magic = "# vtk DataFile Version";
    if (header.substr(0, magic.size()) != magic)
      throw_io(c_.file(), 1, "not a VTK legacy file: the first line must be '# vtk DataFile Version x.x'");
    std::string version(header.substr(magic.size()));
    while (!version.empty() && version.front() == ' ') version.erase(0, 1);
    c_.rest_of_line();  // title
    std::string_view mode = c_.token("ASCII or BINARY");
    if (equals_nocase(mode, "BINARY"))
      binary_ = true;
    else if (!equals_nocase(mode, "ASCII"))
      c_.fail("expected ASCII or BINARY, got '" + Cursor::shorten(mode) + "'");
    std::string_view ds = c_.token("DATASET");
    if (!equals_nocase(ds, "DATASET")) c_.fail("expected DATASET, got '" + Cursor::shorten(ds) + "'");
    std::string_view type = c_.token("dataset type");
    if (!equals_nocase(type, "UNSTRUCTURED_GRID"))
      c_.fail("dataset " + Cursor::shorten(type) + " holds no tetrahedra (UNSTRUCTURED_GRID needed)");
    m_.format = "vtk legacy " + version + (binary_ ? " binary" : " ascii");

    bool have_points = false, have_cells = false, have_types = false;
    std::size_t np = 0;
    while (!c_.at_end()) {
      std::string_view kw = c_.token("keyword");
      if (equals_nocase(kw, "POINTS")) {
        if (have_points) c_.fail("second POINTS section");
        np = c_.count("number of points", 1, true);
        NumType t = type_token();
        read_values(3 * np, t, pts_);
        for (double v : pts_)
          if (!std::isfinite(v)) c_.fail("non-finite point coordinate");
        have_points = true;
      } else if (equals_nocase(kw, "CELLS")) {
        if (have_cells) c_.fail("second CELLS section");
        std::size_t a = c_.count("number of cells", 1, true);
        std::size_t b = c_.count("cell list size", 1, true);
        std::string_view next = c_.peek();
        if (equals_nocase(next, "OFFSETS")) {
          c_.token("OFFSETS");
          read_values(a, type_token(), offsets_);
          std::string_view k2 = c_.token("CONNECTIVITY");
          if (!equals_nocase(k2, "CONNECTIVITY")) c_.fail("expected CONNECTIVITY, got '" + Cursor::shorten(k2) + "'");
          read_values(b, type_token(), conn_);
          if (a == 0) c_.fail("OFFSETS must have at least one entry");
          ncells_ = a - 1;
        } else {
          read_values(b, binary_ ? NumType::Int32 : NumType::Int64, legacy_cells_);
          ncells_ = a;
        }
        have_cells = true;
      } else if (equals_nocase(kw, "CELL_TYPES")) {
        std::size_t n = c_.count("number of cell types", 1, true);
        read_values(n, binary_ ? NumType::Int32 : NumType::Int64, types_);
        have_types = true;
      } else if (equals_nocase(kw, "CELL_DATA") || equals_nocase(kw, "POINT_DATA")) {
        in_cells_ = equals_nocase(kw, "CELL_DATA");
        attr_n_ = c_.count("number of tuples", 1, true);
      } else if (equals_nocase(kw, "SCALARS")) {
        std::string name(c_.token_on_line("name"));
        NumType t = type_token_on_line();
        long long nc = c_.eol() ? 1 : c_.integer("number of components", true);
        if (nc < 1 || nc > 4) c_.fail("SCALARS with " + std::to_string(nc) + " components");
        std::string_view lt = c_.token("LOOKUP_TABLE");
        if (!equals_nocase(lt, "LOOKUP_TABLE")) c_.fail("expected LOOKUP_TABLE, got '" + Cursor::shorten(lt) + "'");
        c_.token_on_line("lookup table name");
        std::vector<double> v;
        read_values(attr_n_ * static_cast<std::size_t>(nc), t, v);
        if (nc == 1) offer_scalars(name, std::move(v));
      } else if (equals_nocase(kw, "LOOKUP_TABLE")) {
        c_.token_on_line("lookup table name");
        std::size_t n = c_.count("lookup table size", 1, true);
        std::vector<double> v;
        read_values(4 * n, binary_ ? NumType::UInt8 : NumType::Float64, v);
      } else if (equals_nocase(kw, "VECTORS") || equals_nocase(kw, "NORMALS") || equals_nocase(kw, "TENSORS")) {
        const std::string name(c_.token_on_line("name"));
        NumType t = type_token_on_line();
        std::vector<double> v;
        read_values(attr_n_ * (equals_nocase(kw, "TENSORS") ? 9 : 3), t, v);
        if (!in_cells_ && equals_nocase(kw, "VECTORS") && name == "displacement") m_.deformed = true;
      } else if (equals_nocase(kw, "TEXTURE_COORDINATES")) {
        c_.token_on_line("name");
        long long dim = c_.integer("dimension", true);
        if (dim < 1 || dim > 3) c_.fail("bad texture dimension");
        NumType t = type_token_on_line();
        std::vector<double> v;
        read_values(attr_n_ * static_cast<std::size_t>(dim), t, v);
      } else if (equals_nocase(kw, "COLOR_SCALARS")) {
        c_.token_on_line("name");
        long long nc = c_.integer("number of components", true);
        if (nc < 1 || nc > 4) c_.fail("bad COLOR_SCALARS components");
        std::vector<double> v;
        read_values(attr_n_ * static_cast<std::size_t>(nc), binary_ ? NumType::UInt8 : NumType::Float64, v);
      } else if (equals_nocase(kw, "FIELD")) {
        c_.token_on_line("field name");
        std::size_t k = c_.count("number of arrays", 2, true);
        for (std::size_t i = 0; i < k; ++i) {
          std::string name(c_.token("array name"));
          if (equals_nocase(name, "METADATA")) {
            skip_metadata();
            --i;
            continue;
          }
          long long nc = c_.integer("number of components", true);
          std::size_t nt = c_.count("number of tuples", 1, true);
          if (nc < 1 || nc > 1024) c_.fail("bad number of components " + std::to_string(nc));
          NumType t = type_token_on_line();
          std::vector<double> v;
          c_.check_fits(static_cast<unsigned long long>(nc) * nt, 1, "array size");
          read_values(static_cast<std::size_t>(nc) * nt, t, v);
          if (nc == 1 && nt == attr_n_) offer_scalars(name, std::move(v));
        }
      } else if (equals_nocase(kw, "METADATA")) {
        skip_metadata();
      } else {
        c_.fail("unknown VTK keyword '" + Cursor::shorten(kw) + "'");
      }
    }
    if (!have_points) c_.fail("no POINTS section");
    if (!have_cells) c_.fail("no CELLS section");
    if (!have_types) c_.fail("no CELL_TYPES section");
    if (types_.size() != ncells_)
      c_.fail(std::to_string(types_.size()) + " cell types for " + std::to_string(ncells_) + " cells");
    assemble(np);
    return std::move(m_);
  }

private:
  NumType type_token() {
    std::string_view t = c_.token("data type");
    NumType nt = vtk_legacy_type(t);
    if (nt == NumType::Unknown) c_.fail("unsupported data type '" + Cursor::shorten(t) + "'");
    return nt;
  }
  NumType type_token_on_line() {
    std::string_view t = c_.token_on_line("data type");
    NumType nt = vtk_legacy_type(t);
    if (nt == NumType::Unknown) c_.fail("unsupported data type '" + Cursor::shorten(t) + "'");
    return nt;
  }

  void read_values(std::size_t n, NumType t, std::vector<double>& out) {
    out.clear();
    if (binary_) {
      c_.skip_one_newline();
      c_.check_fits(n, static_cast<std::size_t>(num_size(t)), "values");
      const char* p = c_.take_bytes(n * static_cast<std::size_t>(num_size(t)), "data");
      out.resize(n);
      for (std::size_t i = 0; i < n; ++i) out[i] = load_value(p + i * num_size(t), t, true);
    } else {
      c_.check_fits(n, 2, "values");
      out.resize(n);
      for (std::size_t i = 0; i < n; ++i) out[i] = c_.real("number");
    }
  }

  void skip_metadata() {
    // METADATA blocks end at an empty line.
    c_.next_line();
    while (c_.remaining() > 0) {
      std::string_view l = c_.rest_of_line();
      if (l.find_first_not_of(" \t\r") == std::string_view::npos) break;
    }
  }

  // A one-component cell array: the label when its name ranks best so far; every one is
  // also kept for the tets (as VTU's are: a frame's cut_face_mask, von_mises, ...).
  void offer_scalars(const std::string& name, std::vector<double>&& v) {
    if (!in_cells_) return;
    if (std::none_of(scalars_.begin(), scalars_.end(), [&](const auto& s) { return s.first == name; }))
      scalars_.push_back({name, v});
    int rank = label_rank(name);
    if (rank > label_rank_) {
      label_rank_ = rank;
      label_name_ = name;
      labels_ = std::move(v);
    }
  }

  std::uint32_t index(double v, std::size_t np, std::size_t cell) const {
    if (!(v >= 0) || v >= static_cast<double>(np) || v != std::floor(v))
      throw_io(c_.file(), 0, "cell #" + std::to_string(cell) + " references point " + real_text(v) + ", not an index in 0.." +
                                      (np > 0 ? std::to_string(np - 1) : std::string("-1 (no points)")));
    return static_cast<std::uint32_t>(v);
  }

  void assemble(std::size_t np) {
    m_.points.resize(np);
    for (std::size_t i = 0; i < np; ++i) m_.points[i] = Vec3(pts_[3 * i], pts_[3 * i + 1], pts_[3 * i + 2]);
    pts_ = {};
    bool use_labels = label_rank_ > 0 && labels_.size() == ncells_;
    std::erase_if(scalars_, [&](const auto& s) { return s.second.size() != ncells_ || (use_labels && s.first == label_name_); });
    for (const auto& s : scalars_) m_.cell_scalars.push_back({s.first, {}});
    std::size_t pos = 0;
    for (std::size_t i = 0; i < ncells_; ++i) {
      std::size_t begin, count;
      if (!offsets_.empty()) {
        double o0 = offsets_[i], o1 = offsets_[i + 1];
        if (!(o0 >= 0) || o1 < o0 || o1 > static_cast<double>(conn_.size()))
          throw_io(c_.file(), 0, "cell #" + std::to_string(i) + " has bad offsets");
        begin = static_cast<std::size_t>(o0);
        count = static_cast<std::size_t>(o1) - begin;
      } else {
        if (pos >= legacy_cells_.size())
          throw_io(c_.file(), 0, "CELLS list ends before cell #" + std::to_string(i));
        double cnt = legacy_cells_[pos];
        if (!(cnt >= 0) || cnt > static_cast<double>(legacy_cells_.size() - pos - 1))
          throw_io(c_.file(), 0, "cell #" + std::to_string(i) + " has a bad point count");
        begin = pos + 1;
        count = static_cast<std::size_t>(cnt);
        pos = begin + count;
      }
      const std::vector<double>& ids = offsets_.empty() ? legacy_cells_ : conn_;
      double type = types_[i];
      if ((type == 10 && count == 4) || (type == 24 && count == 10)) {
        std::array<std::uint32_t, 4> t;
        for (int k = 0; k < 4; ++k) t[k] = index(ids[begin + k], np, i);
        m_.tets.push_back(t);
        double lab = use_labels ? labels_[i] : 0;
        if (!std::isfinite(lab) || std::abs(lab) > 2147483647.0)
          throw_io(c_.file(), 0, "cell #" + std::to_string(i) + " has a bad label");
        m_.tet_labels.push_back(static_cast<int>(std::lround(lab)));
        m_.tet_lines.push_back(0);
        for (std::size_t k = 0; k < scalars_.size(); ++k) m_.cell_scalars[k].second.push_back(scalars_[k].second[i]);
      } else if (type == 10 || type == 24) {
        throw_io(c_.file(), 0, "cell #" + std::to_string(i) + " is a tetrahedron with " + std::to_string(count) + " points");
      } else {
        ++m_.skipped_cells;
      }
    }
    if (offsets_.empty() && pos != legacy_cells_.size())
      throw_io(c_.file(), 0, "CELLS list size does not match its cells");
  }

  Cursor c_;
  RawMesh m_;
  bool binary_ = false;
  bool in_cells_ = false;
  std::size_t attr_n_ = 0;
  std::size_t ncells_ = 0;
  std::vector<double> pts_, offsets_, conn_, legacy_cells_, types_, labels_;
  std::vector<std::pair<std::string, std::vector<double>>> scalars_;
  std::string label_name_;
  int label_rank_ = 0;
};

void put_values(std::string& b, const std::vector<double>& v, bool binary) {
  if (binary) {
    for (double x : v) store_value(b, x, true);
    b += '\n';
  } else {
    for (std::size_t i = 0; i < v.size(); ++i) {
      append_real(b, v[i]);
      b += (i + 1) % 9 == 0 || i + 1 == v.size() ? '\n' : ' ';
    }
  }
}

void put_field(std::string& b, const FlatMesh::DenseField& f, bool binary) {
  if (f.components == 1) {
    b += "SCALARS " + f.name + " double 1\nLOOKUP_TABLE default\n";
  } else if (f.components == 3) {
    b += "VECTORS " + f.name + " double\n";
  } else if (f.components == 9) {
    b += "TENSORS " + f.name + " double\n";
  } else {
    b += "FIELD FieldData 1\n" + f.name + " " + std::to_string(f.components) + " " +
         std::to_string(f.values.size() / f.components) + " double\n";
  }
  put_values(b, f.values, binary);
}

}  // namespace

RawMesh parse_vtk_legacy(const std::string& file, const std::string& text) { return VtkReader(file, text).parse(); }

void write_vtk_legacy(const FlatMesh& m, AtomicFile& out, const WriteOptions& options) {
  const bool bin = options.binary;
  std::string b;
  b.reserve(std::size_t(1) << 21);
  b += "# vtk DataFile Version 4.2\nincise tetrahedral mesh\n";
  b += bin ? "BINARY\n" : "ASCII\n";
  b += "DATASET UNSTRUCTURED_GRID\nPOINTS " + std::to_string(m.points.size()) + " double\n";
  for (const Vec3& p : m.points) {
    for (int d = 0; d < 3; ++d) {
      if (bin) {
        store_value(b, p[d], true);
      } else {
        append_real(b, p[d]);
        b += d == 2 ? '\n' : ' ';
      }
    }
    out.flush_if_large(b);
  }
  if (bin) b += '\n';
  const std::size_t nt = m.tets.size();
  b += "CELLS " + std::to_string(nt) + " " + std::to_string(5 * nt) + "\n";
  for (const auto& t : m.tets) {
    if (bin) {
      store_value(b, std::int32_t(4), true);
      for (std::uint32_t v : t) store_value(b, static_cast<std::int32_t>(v), true);
    } else {
      b += '4';
      for (std::uint32_t v : t) {
        b += ' ';
        append_int(b, v);
      }
      b += '\n';
    }
    out.flush_if_large(b);
  }
  if (bin) b += '\n';
  b += "CELL_TYPES " + std::to_string(nt) + "\n";
  for (std::size_t i = 0; i < nt; ++i) {
    if (bin)
      store_value(b, std::int32_t(10), true);
    else
      b += "10\n";
    out.flush_if_large(b);
  }
  if (bin) b += '\n';
  b += "CELL_DATA " + std::to_string(nt) + "\nSCALARS label int 1\nLOOKUP_TABLE default\n";
  for (std::size_t i = 0; i < nt; ++i) {
    if (bin) {
      store_value(b, static_cast<std::int32_t>(m.labels[i]), true);
    } else {
      append_int(b, m.labels[i]);
      b += '\n';
    }
    out.flush_if_large(b);
  }
  if (bin) b += '\n';
  for (const auto& f : m.cell_data) put_field(b, f, bin);
  if (!m.point_data.empty()) {
    b += "POINT_DATA " + std::to_string(m.points.size()) + "\n";
    for (const auto& f : m.point_data) put_field(b, f, bin);
  }
  out.write(b);
}

}  // namespace incise::io
