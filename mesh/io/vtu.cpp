// VTK XML UnstructuredGrid (.vtu). Read: ascii, inline base64 binary and appended (raw or
// base64) data, UInt32/UInt64 headers, either byte order, uncompressed or zlib; several
// Pieces are merged. Written: ascii or inline base64 binary, uncompressed.
// A small purpose-built XML scanner: VTU needs tags, attributes and the text of DataArray
// elements, nothing more, and raw appended data is not XML at all.
#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <optional>
#include <string_view>

#include "mesh/io/binary_util.h"
#include "mesh/io/formats.h"
#include "mesh/io/parse_util.h"

namespace incise::io {

NumType vtu_type(std::string_view n) {
  if (n == "Int8" || n == "Char") return NumType::Int8;
  if (n == "UInt8" || n == "UChar") return NumType::UInt8;
  if (n == "Int16") return NumType::Int16;
  if (n == "UInt16") return NumType::UInt16;
  if (n == "Int32") return NumType::Int32;
  if (n == "UInt32") return NumType::UInt32;
  if (n == "Int64" || n == "IdType") return NumType::Int64;
  if (n == "UInt64") return NumType::UInt64;
  if (n == "Float32") return NumType::Float32;
  if (n == "Float64") return NumType::Float64;
  return NumType::Unknown;
}

namespace {

// A value read as a double, for an error message: it may be far outside any integer range.
std::string number_text(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%.15g", v);
  return buf;
}

struct Tag {
  std::string_view name;
  std::vector<std::pair<std::string_view, std::string_view>> attrs;
  bool closing = false;
  bool self_closing = false;
  const char* start = nullptr;    // '<'
  const char* content = nullptr;  // just after '>'
  std::optional<std::string_view> attr(std::string_view key) const {
    for (const auto& [k, v] : attrs)
      if (k == key) return v;
    return std::nullopt;
  }
};

class Vtu {
public:
  Vtu(const std::string& file, const std::string& text) : file_(file), b_(text.data()), p_(text.data()), e_(text.data() + text.size()) {}

  RawMesh parse();

private:
  long line_at(const char* q) const {
    long l = 1;
    for (const char* s = b_; s < q && s < e_; ++s) l += *s == '\n';
    return l;
  }
  [[noreturn]] void fail_at(const char* q, const std::string& why) const { throw_io(file_, line_at(q), why); }

  bool next_tag(Tag& t);
  struct Array {
    Tag tag;
    std::string name;
    NumType type = NumType::Unknown;
    int components = 1;
  };
  std::vector<double> decode(const Array& a, std::size_t expected);  // expected: values, or 0 = any
  // max_bytes: the most the piece's counts allow this array to hold (checked before inflating).
  void decode_binary(const Array& a, const char* p, const char* e, bool base64, std::string& bytes,
                     std::uint64_t max_bytes);

  std::string file_;
  const char* b_;
  const char* p_;
  const char* e_;
  bool big_endian_ = false;
  int header_size_ = 4;
  bool zlib_ = false;
  std::uint64_t cells_ = 0;  // the cell count of the piece being decoded (bounds its connectivity)
  const char* appended_ = nullptr;  // just after '_'
  bool appended_base64_ = false;
};

bool is_ws(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r'; }

bool Vtu::next_tag(Tag& t) {
  while (true) {
    while (p_ < e_ && *p_ != '<') ++p_;
    if (p_ >= e_) return false;
    std::string_view rest(p_, static_cast<std::size_t>(e_ - p_));
    auto skip_to = [&](std::string_view end) {
      auto k = rest.find(end);
      if (k == std::string_view::npos) fail_at(p_, "unterminated XML " + std::string(rest.substr(0, 4)));
      p_ += k + end.size();
    };
    if (rest.starts_with("<?")) {
      skip_to("?>");
      continue;
    }
    if (rest.starts_with("<!--")) {
      skip_to("-->");
      continue;
    }
    if (rest.starts_with("<!")) {
      skip_to(">");
      continue;
    }
    break;
  }
  t = Tag{};
  t.start = p_;
  ++p_;
  if (p_ < e_ && *p_ == '/') {
    t.closing = true;
    ++p_;
  }
  const char* s = p_;
  while (p_ < e_ && !is_ws(*p_) && *p_ != '>' && *p_ != '/') ++p_;
  t.name = std::string_view(s, static_cast<std::size_t>(p_ - s));
  if (t.name.empty()) fail_at(t.start, "malformed XML tag");
  while (true) {
    while (p_ < e_ && is_ws(*p_)) ++p_;
    if (p_ >= e_) fail_at(t.start, "unterminated XML tag <" + std::string(t.name));
    if (*p_ == '>') {
      ++p_;
      break;
    }
    if (*p_ == '/' && p_ + 1 < e_ && p_[1] == '>') {
      t.self_closing = true;
      p_ += 2;
      break;
    }
    const char* k = p_;
    while (p_ < e_ && !is_ws(*p_) && *p_ != '=' && *p_ != '>' && *p_ != '/') ++p_;
    std::string_view key(k, static_cast<std::size_t>(p_ - k));
    while (p_ < e_ && is_ws(*p_)) ++p_;
    if (key.empty() || p_ >= e_ || *p_ != '=') fail_at(t.start, "malformed attribute in <" + std::string(t.name) + ">");
    ++p_;
    while (p_ < e_ && is_ws(*p_)) ++p_;
    if (p_ >= e_ || (*p_ != '"' && *p_ != '\'')) fail_at(t.start, "unquoted attribute in <" + std::string(t.name) + ">");
    char q = *p_++;
    const char* v = p_;
    while (p_ < e_ && *p_ != q) ++p_;
    if (p_ >= e_) fail_at(t.start, "unterminated attribute in <" + std::string(t.name) + ">");
    t.attrs.emplace_back(key, std::string_view(v, static_cast<std::size_t>(p_ - v)));
    ++p_;
  }
  t.content = p_;
  return true;
}

int b64_value(char c) {
  if (c >= 'A' && c <= 'Z') return c - 'A';
  if (c >= 'a' && c <= 'z') return c - 'a' + 26;
  if (c >= '0' && c <= '9') return c - '0' + 52;
  if (c == '+') return 62;
  if (c == '/') return 63;
  return -1;
}

// Decodes base64 quantum by quantum until `out` holds `need` bytes. Each quantum is decoded
// on its own, so a header and data encoded separately (padding in between, as VTK writes)
// and encoded together (as meshio writes) both come out right.
class Base64Stream {
public:
  Base64Stream(const char* p, const char* e) : p_(p), e_(e) {}
  bool fill(std::string& out, std::size_t need) {
    while (out.size() < need) {
      int q[4];
      int n = 0;
      while (n < 4) {
        while (p_ < e_ && is_ws(*p_)) ++p_;
        if (p_ >= e_ || *p_ == '<') return false;
        char c = *p_++;
        if (c == '=') {
          q[n++] = -2;
        } else {
          int v = b64_value(c);
          if (v < 0) return bad_ = true, false;
          q[n++] = v;
        }
      }
      if (q[0] < 0 || q[1] < 0 || (q[2] == -2 && q[3] != -2)) return bad_ = true, false;
      out += static_cast<char>((q[0] << 2) | (q[1] >> 4));
      if (q[2] >= 0) out += static_cast<char>(((q[1] & 15) << 4) | (q[2] >> 2));
      if (q[2] >= 0 && q[3] >= 0) out += static_cast<char>(((q[2] & 3) << 6) | q[3]);
    }
    return true;
  }
  bool bad() const { return bad_; }
  std::size_t max_left() const { return static_cast<std::size_t>(e_ - p_) / 4 * 3 + 3; }

private:
  const char* p_;
  const char* e_;
  bool bad_ = false;
};

void Vtu::decode_binary(const Array& a, const char* p, const char* e, bool base64, std::string& bytes,
                        std::uint64_t max_bytes) {
  const std::string what = "DataArray '" + a.name + "': ";
  const int hs = header_size_;
  std::string buf;
  std::optional<Base64Stream> b64;
  if (base64) b64.emplace(p, e);
  // Makes the first n payload bytes available at the returned pointer.
  auto need = [&](std::size_t n) -> const char* {
    if (!base64) {
      if (n > static_cast<std::size_t>(e - p)) fail_at(a.tag.start, what + "binary data is truncated");
      return p;
    }
    if (n > buf.size() + b64->max_left()) fail_at(a.tag.start, what + "binary data is truncated");
    if (!b64->fill(buf, n))
      fail_at(a.tag.start, what + (b64->bad() ? "invalid base64 data" : "base64 data is truncated"));
    return buf.data();
  };
  if (!zlib_) {
    std::uint64_t nbytes = load_uint(need(hs), hs, big_endian_);
    if (nbytes > static_cast<std::uint64_t>(e - p)) fail_at(a.tag.start, what + "header claims more bytes than the file holds");
    const char* d = need(hs + nbytes);
    bytes.assign(d + hs, static_cast<std::size_t>(nbytes));
    return;
  }
  const char* h = need(3 * static_cast<std::size_t>(hs));
  std::uint64_t nblocks = load_uint(h, hs, big_endian_);
  std::uint64_t block = load_uint(h + hs, hs, big_endian_);
  std::uint64_t last = load_uint(h + 2 * hs, hs, big_endian_);
  if (nblocks > static_cast<std::uint64_t>(e - p) / hs) fail_at(a.tag.start, what + "bad compression header");
  std::size_t header_bytes = (3 + nblocks) * hs;
  h = need(header_bytes);
  std::uint64_t compressed = 0;
  std::vector<std::uint64_t> csize(nblocks);
  for (std::uint64_t i = 0; i < nblocks; ++i) {
    csize[i] = load_uint(h + (3 + i) * hs, hs, big_endian_);
    compressed += csize[i];
    if (csize[i] > static_cast<std::uint64_t>(e - p)) fail_at(a.tag.start, what + "bad compression header");
  }
  if (nblocks == 0) {
    bytes.clear();
    return;
  }
  if (last == 0) last = block;
  std::uint64_t total = (nblocks - 1) * block + last;
  // zlib cannot expand more than ~1032:1; anything beyond is a lying header.
  if (block > (std::uint64_t(1) << 32) || last > block || total > 1100 * compressed + 4096)
    fail_at(a.tag.start, what + "bad compression header");
  // A block that inflates to far more than the piece's counts allow is refused before any of it
  // is inflated (a small file declaring gigabytes).
  if (total > max_bytes)
    fail_at(a.tag.start, what + "the compression header declares " + std::to_string(total) +
                             " bytes, more than the piece's counts allow (" + std::to_string(max_bytes) + ")");
  const char* d = need(header_bytes + compressed) + header_bytes;
  bytes.resize(static_cast<std::size_t>(total));
  std::uint64_t in = 0, outpos = 0;
  for (std::uint64_t i = 0; i < nblocks; ++i) {
    uLongf len = static_cast<uLongf>(i + 1 == nblocks ? last : block);
    uLongf expect = len;
    int rc = ::uncompress(reinterpret_cast<Bytef*>(bytes.data() + outpos), &len, reinterpret_cast<const Bytef*>(d + in),
                          static_cast<uLong>(csize[i]));
    if (rc != Z_OK || len != expect) fail_at(a.tag.start, what + "zlib data is corrupt");
    in += csize[i];
    outpos += expect;
  }
}

std::vector<double> Vtu::decode(const Array& a, std::size_t expected) {
  const std::string what = "DataArray '" + a.name + "': ";
  std::string format(a.tag.attr("format").value_or("ascii"));
  std::vector<double> out;
  if (a.type == NumType::Unknown) fail_at(a.tag.start, what + "unsupported or missing type");
  if (format == "ascii") {
    if (a.tag.self_closing) fail_at(a.tag.start, what + "no data");
    const char* end = a.tag.content;
    while (end < e_ && *end != '<') ++end;
    std::string_view body(a.tag.content, static_cast<std::size_t>(end - a.tag.content));
    Cursor c(file_, body, 0, line_at(a.tag.content));
    while (!c.at_end()) {
      out.push_back(c.real((what + "number").c_str()));
      if (expected && out.size() > expected) c.fail(what + "more values than expected");
    }
  } else if (format == "binary" || format == "appended") {
    std::string bytes;
    // What the counts allow: `expected` values, or (connectivity, expected 0) a generous bound of
    // 64 values a cell. Plain binary data is bounded by the file itself.
    const std::uint64_t type_bytes = std::uint64_t(num_size(a.type));
    const std::uint64_t max_bytes = type_bytes * (expected ? std::uint64_t(expected) : 64 * std::uint64_t(cells_ + 1));
    if (format == "binary") {
      if (a.tag.self_closing) fail_at(a.tag.start, what + "no data");
      decode_binary(a, a.tag.content, e_, true, bytes, max_bytes);
    } else {
      if (!appended_) fail_at(a.tag.start, what + "format=\"appended\" but no <AppendedData>");
      auto off = a.tag.attr("offset");
      if (!off) fail_at(a.tag.start, what + "appended DataArray without offset");
      unsigned long long o = 0;
      auto r = std::from_chars(off->data(), off->data() + off->size(), o);
      if (r.ec != std::errc() || o > static_cast<unsigned long long>(e_ - appended_))
        fail_at(a.tag.start, what + "bad offset");
      decode_binary(a, appended_ + o, e_, appended_base64_, bytes, max_bytes);
    }
    const std::size_t sz = static_cast<std::size_t>(num_size(a.type));
    if (bytes.size() % sz != 0) fail_at(a.tag.start, what + "byte count is not a multiple of the type size");
    out.resize(bytes.size() / sz);
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = load_value(bytes.data() + i * sz, a.type, big_endian_);
  } else {
    fail_at(a.tag.start, what + "unknown format '" + Cursor::shorten(format) + "'");
  }
  if (expected && out.size() != expected)
    fail_at(a.tag.start, what + std::to_string(out.size()) + " values, expected " + std::to_string(expected));
  return out;
}

RawMesh Vtu::parse() {
  RawMesh m;
  Tag t;
  if (!next_tag(t) || t.name != "VTKFile")
    fail_at(p_ < e_ ? p_ : b_, "not a VTK XML file (no <VTKFile> element)");
  std::string type(t.attr("type").value_or(""));
  if (type != "UnstructuredGrid") fail_at(t.start, "VTKFile type '" + Cursor::shorten(type) + "' is not UnstructuredGrid");
  std::string order(t.attr("byte_order").value_or("LittleEndian"));
  if (order == "BigEndian")
    big_endian_ = true;
  else if (order != "LittleEndian")
    fail_at(t.start, "unknown byte_order '" + Cursor::shorten(order) + "'");
  std::string header(t.attr("header_type").value_or("UInt32"));
  if (header == "UInt64")
    header_size_ = 8;
  else if (header != "UInt32")
    fail_at(t.start, "unsupported header_type '" + Cursor::shorten(header) + "'");
  std::string compressor(t.attr("compressor").value_or(""));
  if (compressor == "vtkZLibDataCompressor")
    zlib_ = true;
  else if (!compressor.empty())
    fail_at(t.start, "data compressed with " + Cursor::shorten(compressor) +
                         " is not supported (write uncompressed or zlib-compressed VTU)");
  m.format = std::string("vtu") + (zlib_ ? " zlib" : "") + (big_endian_ ? " big-endian" : "") +
             (header_size_ == 8 ? " UInt64-header" : "");

  // First pass: the element structure. DataArrays are decoded after <AppendedData> is known.
  struct Piece {
    const char* start = nullptr;
    std::size_t np = 0, nc = 0;
    std::optional<Array> points, conn, offsets, types, label;
    std::vector<Array> scalars;  // the other one-component cell arrays
  };
  std::vector<Piece> pieces;
  std::string section;
  bool any_binary = false;
  while (next_tag(t)) {
    if (t.closing) {
      if (t.name == section) section.clear();
      continue;
    }
    if (t.name == "AppendedData") {
      std::string enc(t.attr("encoding").value_or("raw"));
      appended_base64_ = enc == "base64";
      if (!appended_base64_ && enc != "raw") fail_at(t.start, "unknown AppendedData encoding '" + Cursor::shorten(enc) + "'");
      const char* q = t.content;
      while (q < e_ && *q != '_') ++q;
      if (q >= e_) fail_at(t.start, "AppendedData without the '_' marker");
      appended_ = q + 1;
      break;  // raw bytes follow: no more XML to scan
    }
    if (t.name == "Piece") {
      pieces.emplace_back();
      pieces.back().start = t.start;
      auto num = [&](const char* key) -> std::size_t {
        auto v = t.attr(key);
        unsigned long long n = 0;
        if (!v || std::from_chars(v->data(), v->data() + v->size(), n).ec != std::errc())
          fail_at(t.start, std::string("Piece without a valid ") + key);
        if (n >= 0xffffffffull) fail_at(t.start, std::string(key) + " exceeds 32-bit ids");
        return static_cast<std::size_t>(n);
      };
      pieces.back().np = num("NumberOfPoints");
      pieces.back().nc = num("NumberOfCells");
      continue;
    }
    if (t.name == "Points" || t.name == "Cells" || t.name == "PointData" || t.name == "CellData") {
      if (!t.self_closing) section = std::string(t.name);
      continue;
    }
    if (t.name != "DataArray" || pieces.empty()) continue;
    Array a;
    a.tag = t;
    a.name = std::string(t.attr("Name").value_or(""));
    a.type = vtu_type(t.attr("type").value_or(""));
    if (auto nc = t.attr("NumberOfComponents")) {
      long long k = 0;
      if (std::from_chars(nc->data(), nc->data() + nc->size(), k).ec != std::errc() || k < 1 || k > 1024)
        fail_at(t.start, "bad NumberOfComponents");
      a.components = static_cast<int>(k);
    }
    if (t.attr("format").value_or("ascii") != "ascii") any_binary = true;
    Piece& pc = pieces.back();
    if (section == "Points") {
      pc.points = a;
    } else if (section == "Cells") {
      if (a.name == "connectivity") pc.conn = a;
      if (a.name == "offsets") pc.offsets = a;
      if (a.name == "types") pc.types = a;
    } else if (section == "PointData" && a.name == "displacement" && a.components == 3) {
      m.deformed = true;
    } else if (section == "CellData" && a.components == 1) {
      if (label_rank(a.name) > (pc.label ? label_rank(pc.label->name) : 0)) {
        if (pc.label) pc.scalars.push_back(*pc.label);
        pc.label = a;
      } else if (!a.name.empty()) {
        pc.scalars.push_back(a);
      }
    }
  }
  if (pieces.empty()) fail_at(b_, "no <Piece> in the UnstructuredGrid");
  if (any_binary) m.format += " binary";
  else m.format += " ascii";

  for (const Piece& pc : pieces) {
    if (!pc.points) fail_at(pc.start, "Piece without <Points>");
    if (pc.points->components != 3) fail_at(pc.points->tag.start, "Points must have 3 components");
    if (pc.nc > 0 && (!pc.conn || !pc.offsets || !pc.types))
      fail_at(pc.start, "Cells need connectivity, offsets and types arrays");
    std::vector<double> pts = decode(*pc.points, 3 * pc.np);
    const std::size_t base = m.points.size();
    for (std::size_t i = 0; i < pc.np; ++i) {
      Vec3 p(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]);
      if (!p.allFinite()) fail_at(pc.points->tag.start, "non-finite point coordinate (point " + std::to_string(i) + ")");
      m.points.push_back(p);
    }
    if (pc.nc == 0) continue;
    cells_ = pc.nc;
    std::vector<double> conn = decode(*pc.conn, 0);
    std::vector<double> offsets = decode(*pc.offsets, pc.nc);
    std::vector<double> types = decode(*pc.types, pc.nc);
    std::vector<double> labels;
    if (pc.label) labels = decode(*pc.label, pc.nc);
    // Other scalar arrays: kept for the tets (every piece's tets get a value; 0 where a piece
    // lacks the array).
    const std::size_t tets_before = m.tets.size();
    std::vector<std::vector<double>> scalars;
    std::vector<std::size_t> slot;  // index into m.cell_scalars per array of this piece
    std::vector<std::string_view> seen;
    for (const Array& a : pc.scalars) {
      if (std::find(seen.begin(), seen.end(), a.name) != seen.end()) continue;  // a name twice: the first
      seen.push_back(a.name);
      scalars.push_back(decode(a, pc.nc));
      std::size_t k = 0;
      while (k < m.cell_scalars.size() && m.cell_scalars[k].first != a.name) ++k;
      if (k == m.cell_scalars.size()) m.cell_scalars.push_back({a.name, std::vector<double>(tets_before, 0.0)});
      slot.push_back(k);
    }
    double prev = 0;
    for (std::size_t i = 0; i < pc.nc; ++i) {
      double o = offsets[i];
      if (!(o >= prev) || o > static_cast<double>(conn.size()) || o != std::floor(o))
        fail_at(pc.offsets->tag.start, "offsets: cell " + std::to_string(i) + " has a bad offset");
      const std::size_t begin = static_cast<std::size_t>(prev), count = static_cast<std::size_t>(o) - begin;
      prev = o;
      const double ty = types[i];
      if ((ty == 10 && count == 4) || (ty == 24 && count == 10)) {
        std::array<std::uint32_t, 4> tet;
        for (int k = 0; k < 4; ++k) {
          double v = conn[begin + k];
          if (!(v >= 0) || v >= static_cast<double>(pc.np) || v != std::floor(v))
            fail_at(pc.conn->tag.start, "connectivity: cell " + std::to_string(i) + " references point " +
                                            number_text(v) + " out of range");
          tet[k] = static_cast<std::uint32_t>(base + static_cast<std::size_t>(v));
        }
        double lab = labels.empty() ? 0 : labels[i];
        if (!std::isfinite(lab) || std::abs(lab) > 2147483647.0) fail_at(pc.label->tag.start, "bad label value");
        m.tets.push_back(tet);
        m.tet_labels.push_back(static_cast<int>(std::lround(lab)));
        m.tet_lines.push_back(0);
        for (std::size_t k = 0; k < scalars.size(); ++k) m.cell_scalars[slot[k]].second.push_back(scalars[k][i]);
      } else if (ty == 10 || ty == 24) {
        fail_at(pc.types->tag.start, "cell " + std::to_string(i) + " is a tetrahedron with " + std::to_string(count) + " points");
      } else {
        ++m.skipped_cells;
      }
    }
    for (auto& [name, values] : m.cell_scalars) values.resize(m.tets.size(), 0.0);  // arrays this piece lacks
  }
  return m;
}

// ---- writing ----------------------------------------------------------------------------
class VtuWriter {
public:
  VtuWriter(AtomicFile& out, const WriteOptions& o) : out_(out), binary_(o.binary), big_(o.big_endian), h64_(o.header_uint64) {}

  std::string b;

  template <class T, class Get>
  void array(const char* type, const std::string& name, int components, std::size_t n, Get get) {
    b += "<DataArray type=\"";
    b += type;
    b += "\" Name=\"" + name + "\"";
    if (components != 1) b += " NumberOfComponents=\"" + std::to_string(components) + "\"";
    b += binary_ ? " format=\"binary\">\n" : " format=\"ascii\">\n";
    const std::size_t count = n * static_cast<std::size_t>(components);
    if (binary_) {
      std::string raw;
      raw.reserve(count * sizeof(T) + 8);
      if (h64_)
        store_value(raw, static_cast<std::uint64_t>(count * sizeof(T)), big_);
      else
        store_value(raw, static_cast<std::uint32_t>(count * sizeof(T)), big_);
      for (std::size_t i = 0; i < count; ++i) store_value(raw, static_cast<T>(get(i)), big_);
      base64(raw);
    } else {
      for (std::size_t i = 0; i < count; ++i) {
        if constexpr (std::is_floating_point_v<T>)
          append_real(b, static_cast<double>(get(i)));
        else
          append_int(b, static_cast<long long>(get(i)));
        b += (i + 1) % static_cast<std::size_t>(components == 1 ? 6 : components) == 0 || i + 1 == count ? '\n' : ' ';
        out_.flush_if_large(b);
      }
    }
    b += "</DataArray>\n";
    out_.flush_if_large(b);
  }

private:
  void base64(const std::string& raw) {
    static const char* k = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::size_t i = 0;
    std::size_t col = 0;
    for (; i + 3 <= raw.size(); i += 3) {
      unsigned v = (static_cast<unsigned char>(raw[i]) << 16) | (static_cast<unsigned char>(raw[i + 1]) << 8) |
                   static_cast<unsigned char>(raw[i + 2]);
      b += k[v >> 18];
      b += k[(v >> 12) & 63];
      b += k[(v >> 6) & 63];
      b += k[v & 63];
      if (++col % 1024 == 0) out_.flush_if_large(b);
    }
    if (i < raw.size()) {
      unsigned v = static_cast<unsigned char>(raw[i]) << 16;
      if (i + 1 < raw.size()) v |= static_cast<unsigned char>(raw[i + 1]) << 8;
      b += k[v >> 18];
      b += k[(v >> 12) & 63];
      b += i + 1 < raw.size() ? k[(v >> 6) & 63] : '=';
      b += '=';
    }
    b += '\n';
  }

  AtomicFile& out_;
  bool binary_, big_, h64_;
};

}  // namespace

RawMesh parse_vtu(const std::string& file, const std::string& text) { return Vtu(file, text).parse(); }

void write_vtu(const FlatMesh& m, AtomicFile& out, const WriteOptions& options) {
  VtuWriter w(out, options);
  std::string& b = w.b;
  b.reserve(std::size_t(1) << 21);
  b += "<?xml version=\"1.0\"?>\n<VTKFile type=\"UnstructuredGrid\" version=\"1.0\" byte_order=\"";
  b += options.binary && options.big_endian ? "BigEndian" : "LittleEndian";
  b += "\" header_type=\"";
  b += options.header_uint64 ? "UInt64" : "UInt32";
  b += "\">\n<UnstructuredGrid>\n<Piece NumberOfPoints=\"" + std::to_string(m.points.size()) + "\" NumberOfCells=\"" +
       std::to_string(m.tets.size()) + "\">\n";
  const std::size_t np = m.points.size(), nt = m.tets.size();
  if (!m.point_data.empty()) {
    b += "<PointData>\n";
    for (const auto& f : m.point_data)
      w.array<double>("Float64", f.name, f.components, np, [&](std::size_t i) { return f.values[i]; });
    b += "</PointData>\n";
  }
  b += "<CellData>\n";
  w.array<std::int32_t>("Int32", "label", 1, nt, [&](std::size_t i) { return m.labels[i]; });
  for (const auto& f : m.cell_data)
    w.array<double>("Float64", f.name, f.components, nt, [&](std::size_t i) { return f.values[i]; });
  b += "</CellData>\n<Points>\n";
  w.array<double>("Float64", "Points", 3, np, [&](std::size_t i) { return m.points[i / 3][static_cast<int>(i % 3)]; });
  b += "</Points>\n<Cells>\n";
  // Quadratic cells (VTK_QUADRATIC_TETRA = 24): the corners, then the six mid-edge points.
  const bool quadratic = !m.mid.empty();
  const std::size_t per = quadratic ? 10 : 4;
  w.array<std::int64_t>("Int64", "connectivity", 1, per * nt, [&](std::size_t i) {
    const std::size_t t = i / per, k = i % per;
    return k < 4 ? m.tets[t][k] : m.mid[t][k - 4];
  });
  w.array<std::int64_t>("Int64", "offsets", 1, nt, [&](std::size_t i) { return per * (i + 1); });
  w.array<std::uint8_t>("UInt8", "types", 1, nt, [&](std::size_t) { return quadratic ? 24 : 10; });
  b += "</Cells>\n</Piece>\n</UnstructuredGrid>\n</VTKFile>\n";
  out.write(b);
}

}  // namespace incise::io
