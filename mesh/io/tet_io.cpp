// Format dispatch, the shared mesh builder and the flattening writers start from.
#include "mesh/io/tet_io.h"

#include <cerrno>
#include <cstring>
#include <algorithm>
#include <cmath>
#include <fstream>
#include <sys/stat.h>
#include <unordered_map>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "mesh/io/formats.h"
#include "mesh/io/input_checks.h"
#include "mesh/io/input_file.h"
#include "mesh/io/parse_util.h"
#include "mesh/overlap.h"

namespace incise {

namespace io {

std::string lower_extension(const std::string& path) {
  auto slash = path.find_last_of('/');
  auto dot = path.find_last_of('.');
  if (dot == std::string::npos || (slash != std::string::npos && dot < slash)) return {};
  std::string ext = path.substr(dot + 1);
  for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
  return ext;
}

// Label arrays in VTK files, best first (0: not a label array).
int label_rank(std::string_view name) {
  if (name == "label") return 4;
  if (name == "gmsh:physical") return 3;
  if (name == "CellEntityIds") return 2;
  if (name == "medit:ref") return 1;
  return 0;
}


std::string read_file_bytes(const std::string& path) {
  check_input_file(path);
  std::ifstream in(path, std::ios::binary);
  if (!in) io::throw_io(path, 0, std::string("cannot open: ") + std::strerror(errno));
  std::string data;
  in.seekg(0, std::ios::end);
  std::streamoff size = in.tellg();
  in.seekg(0, std::ios::beg);
  if (size > 0) {
    data.resize(static_cast<std::size_t>(size));
    in.read(data.data(), size);
    if (in.gcount() != size) io::throw_io(path, 0, "read error");
  } else {
    // Not seekable (a pipe): read as a stream.
    data.assign(std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>());
  }
  // A UTF-8 byte order mark (editors on Windows write one) is no part of any format.
  if (data.compare(0, 3, "\xEF\xBB\xBF") == 0) data.erase(0, 3);
  return data;
}

namespace {

struct TriKey {
  std::uint32_t a, b, c;
  bool operator==(const TriKey&) const = default;
};
struct TriKeyHash {
  std::size_t operator()(const TriKey& k) const noexcept {
    std::uint64_t h = k.a * 0x9E3779B97F4A7C15ull;
    h ^= (h >> 29) + k.b * 0xBF58476D1CE4E5B9ull;
    h ^= (h >> 31) + k.c * 0x94D049BB133111EBull;
    return static_cast<std::size_t>(h ^ (h >> 32));
  }
};
TriKey sorted_key(std::uint32_t a, std::uint32_t b, std::uint32_t c) {
  if (a > b) std::swap(a, b);
  if (b > c) std::swap(b, c);
  if (a > b) std::swap(a, b);
  return {a, b, c};
}

}  // namespace

TetMesh build_mesh(RawMesh&& raw, const std::string& file, ReadReport* report, const ReadOptions& options) {
  const std::string& tfile = raw.tet_file.empty() ? file : raw.tet_file;
  if (raw.tets.empty()) {
    if (raw.skipped_cells > 0 || !raw.tris.empty())
      io::throw_io(tfile, 0,
                    "no tetrahedra (" + std::to_string(raw.skipped_cells + raw.tris.size()) +
                        " other cells only): a volume mesh is needed, not a surface");
    io::throw_io(tfile, 0, "no tetrahedra");
  }
  const std::size_t np = raw.points.size();
  for (std::size_t i = 0; i < np; ++i)  // the readers refuse these with a line; arrays reach here
    if (!raw.points[i].allFinite()) io::throw_io(file, 0, non_finite_point(i));
  TetMesh m;
  m.reserve(np, raw.tets.size());
  for (const Vec3& p : raw.points) m.add_vertex(p);
  std::size_t reoriented = 0, degenerate = 0;
  std::vector<char> swapped(raw.tets.size(), 0);
  for (std::size_t i = 0; i < raw.tets.size(); ++i) {
    auto t = raw.tets[i];
    long line = i < raw.tet_lines.size() ? raw.tet_lines[i] : 0;
    auto where = [&] { return line > 0 ? std::string("tet") : "tet #" + std::to_string(i); };
    for (std::uint32_t v : t)
      if (v >= np) io::throw_io(tfile, line, where() + " references vertex " + std::to_string(v) + " out of range");
    const Vec3 &a = raw.points[t[0]], &b = raw.points[t[1]], &c = raw.points[t[2]], &d = raw.points[t[3]];
    double det = (b - a).cross(c - a).dot(d - a);
    if (det < 0) {
      std::swap(t[2], t[3]);
      swapped[i] = 1;
      ++reoriented;
    } else if (det == 0) {
      ++degenerate;
    }
    TetId id;
    try {
      id = m.add_tet(VertexId(t[0]), VertexId(t[1]), VertexId(t[2]), VertexId(t[3]),
                     i < raw.tet_labels.size() ? raw.tet_labels[i] : 0);
    } catch (const InvalidMesh& e) {
      io::throw_io(tfile, line, where() + ": " + e.what());
    }
    // Tets sharing a face must lie on opposite sides of it (the face runs opposite ways in
    // the two); the same four vertices twice is the extreme case. Either is no mesh -- except
    // in a deformed frame, where a tet the motion inverted was flipped above and now lies on
    // its neighbour's side: the frame is read back as it was written (docs/view.md).
    for (int f = 0; f < 4; ++f) {
      TetId n = m.neighbor(id, f);
      if (!n.is_valid()) continue;
      if (m.local_index(n, VertexId(t[f])) >= 0)
        io::throw_io(tfile, line, where() + " repeats tet #" + std::to_string(n.idx()) + " (same four vertices)");
      if (raw.deformed) continue;
      int g = 0;
      while (g < 4 && m.neighbor(n, g) != id) ++g;
      auto fa = m.face_vertices(id, f);
      auto fb = m.face_vertices(n, g);
      int k = 0;
      while (k < 3 && fb[k] != fa[0]) ++k;
      if (g == 4 || k == 3 || fb[(k + 1) % 3] != fa[2])
        io::throw_io(tfile, line, where() + " overlaps tet #" + std::to_string(n.idx()) +
                                      " (both on the same side of their shared face)");
    }
  }
  if (options.refuse_overlaps && !raw.deformed)  // a deformed shape may press a cut's sides together
    if (auto pair = find_overlapping_tets(m)) {
      const std::size_t i = pair->second.idx();  // tets were added in file order: TetId = index
      const long line = i < raw.tet_lines.size() ? raw.tet_lines[i] : 0;
      io::throw_io(tfile, line, (line > 0 ? std::string("tet") : "tet #" + std::to_string(i)) + " overlaps tet #" +
                                    std::to_string(pair->first.idx()) + " (their interiors intersect)");
    }
  tag_boundary(m);
  std::size_t tagged = 0;
  if (!raw.tris.empty()) {
    std::unordered_map<TriKey, int, TriKeyHash> tags;
    tags.reserve(raw.tris.size());
    for (std::size_t i = 0; i < raw.tris.size(); ++i) {
      const auto& f = raw.tris[i];
      if (f[0] >= np || f[1] >= np || f[2] >= np) continue;  // readers already reject these
      tags[sorted_key(f[0], f[1], f[2])] = raw.tri_tags[i];
    }
    for (std::uint32_t ti = 0; ti < m.tet_capacity(); ++ti) {
      TetId t(ti);
      for (int f = 0; f < 4; ++f) {
        if (m.neighbor(t, f).is_valid()) continue;
        auto fv = m.face_vertices(t, f);
        auto it = tags.find(sorted_key(fv[0].idx(), fv[1].idx(), fv[2].idx()));
        if (it != tags.end() && it->second > 0 && it->second <= 0xffff) {
          m.set_face_tag(t, f, static_cast<std::uint16_t>(it->second));
          ++tagged;
        }
      }
    }
  }
  // Cut faces of a simulation frame (scene/scene_output.cpp writes the mask): VTU has no
  // boundary triangles to carry tags, so the frame says which faces of each tet a cut opened.
  for (const auto& [name, values] : raw.cell_scalars) {
    if (name != "cut_face_mask") continue;
    for (std::size_t i = 0; i < values.size() && i < m.tet_capacity(); ++i) {
      const double x = values[i];
      if (!(x >= 1 && x <= 15) || x != std::floor(x)) continue;
      unsigned bits = unsigned(x);
      if (swapped[i]) bits = (bits & 3u) | ((bits & 4u) << 1) | ((bits & 8u) >> 1);  // faces 2 and 3 swapped
      const TetId t(static_cast<std::uint32_t>(i));
      for (int f = 0; f < 4; ++f)
        if ((bits >> f) & 1u && !m.neighbor(t, f).is_valid()) {
          m.set_face_tag(t, f, kTagCut);
          ++tagged;
        }
    }
  }
  std::size_t unreferenced = 0;
  for (std::uint32_t v = 0; v < np; ++v)
    if (m.incident_tets(VertexId(v)).empty()) ++unreferenced;
  if (report) {
    report->skipped_cells = raw.skipped_cells;
    report->reoriented_tets = reoriented;
    report->degenerate_tets = degenerate;
    report->unreferenced_vertices = unreferenced;
    report->tagged_boundary_faces = tagged;
    report->format = raw.format;
    report->cell_data.clear();
    for (auto& [name, values] : raw.cell_scalars) report->cell_data.push_back(Field{name, 1, std::move(values)});
  }
  m.discard_change();
  return m;
}

namespace {

FlatMesh flatten(const TetMesh& mesh, const MeshFields* fields) {
  FlatMesh f;
  const std::size_t vcap = mesh.vertex_capacity(), tcap = mesh.tet_capacity();
  if (fields && fields->points && fields->points->size() < vcap)
    throw InvalidArgument("write_tet_mesh_with_fields: points has " + std::to_string(fields->points->size()) +
                          " entries, the mesh has vertex capacity " + std::to_string(vcap));
  std::vector<std::uint32_t> vmap(vcap, 0xffffffffu);
  f.points.reserve(mesh.num_vertices());
  f.vertex_ids.reserve(mesh.num_vertices());
  for (std::uint32_t v = 0; v < vcap; ++v) {
    if (!mesh.is_alive(VertexId(v))) continue;
    vmap[v] = static_cast<std::uint32_t>(f.points.size());
    f.points.push_back(fields && fields->points ? (*fields->points)[v] : mesh.rest(VertexId(v)));
    if (!f.points.back().allFinite())
      throw InvalidArgument("vertex #" + std::to_string(v) + " has a non-finite position; files hold finite numbers only");
    f.vertex_ids.push_back(v);
  }
  f.tets.reserve(mesh.num_tets());
  f.labels.reserve(mesh.num_tets());
  f.tet_ids.reserve(mesh.num_tets());
  for (std::uint32_t ti = 0; ti < tcap; ++ti) {
    TetId t(ti);
    if (!mesh.is_alive(t)) continue;
    const auto& tv = mesh.tet_vertices(t);
    f.tets.push_back({vmap[tv[0].idx()], vmap[tv[1].idx()], vmap[tv[2].idx()], vmap[tv[3].idx()]});
    f.labels.push_back(mesh.label(t));
    f.tet_ids.push_back(ti);
    for (int k = 0; k < 4; ++k) {
      if (mesh.neighbor(t, k).is_valid()) continue;
      auto fv = mesh.face_vertices(t, k);
      f.faces.push_back({vmap[fv[0].idx()], vmap[fv[1].idx()], vmap[fv[2].idx()]});
      f.face_tags.push_back(mesh.face_tag(t, k));
    }
  }
  // Quadratic cells: the mid points follow the vertices; their point data follows the vertices' (ids vcap + m).
  std::vector<std::uint32_t> point_ids = f.vertex_ids;
  std::size_t pcap = vcap;
  if (fields && fields->mid_nodes && fields->mid_points) {
    const auto& mids = *fields->mid_points;
    const auto base = static_cast<std::uint32_t>(f.points.size());
    for (std::size_t m = 0; m < mids.size(); ++m) {
      if (!mids[m].allFinite()) throw InvalidArgument("mid-edge point #" + std::to_string(m) + " has a non-finite position");
      f.points.push_back(mids[m]);
      point_ids.push_back(static_cast<std::uint32_t>(vcap + m));
    }
    pcap = vcap + mids.size();
    f.mid.reserve(f.tet_ids.size());
    for (std::uint32_t ti : f.tet_ids) {
      std::array<std::uint32_t, 6> q{};
      for (std::size_t k = 0; k < 6; ++k) {
        const std::uint32_t m = (*fields->mid_nodes)[ti][k];
        if (m >= mids.size()) throw InvalidArgument("quadratic cells: tet #" + std::to_string(ti) + " names mid point " + std::to_string(m));
        q[k] = base + m;
      }
      f.mid.push_back(q);
    }
  }
  if (fields) {
    auto gather = [](const Field& in, const std::vector<std::uint32_t>& ids, std::size_t cap, const char* kind) {
      if (in.components < 1 || in.components > 9)
        throw InvalidArgument("field '" + in.name + "': components must be 1..9");
      if (in.values.size() != std::size_t(in.components) * cap)
        throw InvalidArgument("field '" + in.name + "': expected " + std::to_string(in.components * cap) + " " +
                              kind + " values, got " + std::to_string(in.values.size()));
      if (in.name.empty() || in.name.find_first_of(" \t\n\"<>&") != std::string::npos)
        throw InvalidArgument("field name '" + in.name + "' must be non-empty without blanks or XML specials");
      FlatMesh::DenseField d{in.name, in.components, {}};
      d.values.reserve(ids.size() * in.components);
      for (std::uint32_t id : ids)
        for (int c = 0; c < in.components; ++c) {
          const double x = in.values[std::size_t(id) * in.components + c];
          // Every reader refuses non-finite numbers: a file written with one could not be read back.
          if (!std::isfinite(x))
            throw InvalidArgument("field '" + in.name + "': " + kind + " #" + std::to_string(id) + " is " +
                                  std::to_string(x) + "; files hold finite numbers only (readers refuse the rest)");
          d.values.push_back(x);
        }
      return d;
    };
    for (const Field& pd : fields->point_data) f.point_data.push_back(gather(pd, point_ids, pcap, "point"));
    for (const Field& cd : fields->cell_data) f.cell_data.push_back(gather(cd, f.tet_ids, tcap, "cell"));
  }
  // VTU and VTK have no boundary triangles to carry tags: the cut faces go as each tet's mask
  // (bit k: its face opposite corner k), which the readers turn back into cut tags. Without
  // them a cut read back is surface, whose faces the improvement may move (and push one side of
  // the cut into the other, which coincides with it in the rest shape).
  const bool has_mask = fields && std::any_of(fields->cell_data.begin(), fields->cell_data.end(),
                                              [](const Field& cd) { return cd.name == "cut_face_mask"; });
  if (!has_mask) {
    FlatMesh::DenseField mask{"cut_face_mask", 1, std::vector<double>(f.tet_ids.size(), 0.0)};
    bool any = false;
    for (std::size_t i = 0; i < f.tet_ids.size(); ++i)
      for (int k = 0; k < 4; ++k) {
        const TetId t(f.tet_ids[i]);
        if (!mesh.neighbor(t, k).is_valid() && mesh.face_tag(t, k) == kTagCut) {
          mask.values[i] += double(1 << k);
          any = true;
        }
      }
    if (any) f.cell_data.push_back(std::move(mask));
  }
  return f;
}

bool is_surface_extension(const std::string& ext) {
  static const char* kSurface[] = {"off", "obj", "stl", "ply", "gltf", "glb", "fbx", "dae", "3ds", "x3d"};
  return std::any_of(std::begin(kSurface), std::end(kSurface), [&](const char* s) { return ext == s; });
}

// base.node / base.ele from either name.
std::string tetgen_base(const std::string& path) {
  std::string ext = lower_extension(path);
  if (ext == "node" || ext == "ele") return path.substr(0, path.size() - ext.size() - 1);
  return path;
}

TetFormat output_format(const std::string& path, const WriteOptions& options) {
  TetFormat format = options.format == TetFormat::Auto ? format_from_path(path) : options.format;
  if (format == TetFormat::Auto) {
    std::string ext = lower_extension(path);
    if (is_surface_extension(ext))
      io::throw_io(path, 0, "." + ext + " is a surface format: a tet mesh is written as .vtu, .msh, .mesh, .vtk or "
                            ".node/.ele (its boundary as ." + ext + ": incise convert MESH OUT." + ext +
                            ", or Python's write_surface)");
    io::throw_io(path, 0, "unknown tet mesh format '." + ext + "' (use .msh, .mesh, .vtk, .vtu, .node or .ele)");
  }
  return format;
}

std::vector<std::string> output_files(const std::string& path, TetFormat format) {
  if (format != TetFormat::TetGen) return {path};
  const std::string base = tetgen_base(path);
  return {base + ".node", base + ".ele"};
}

// Every write goes through a transaction: a TetGen pair is written whole or not at all.
void write_impl(const TetMesh& mesh, const std::string& path, const MeshFields* fields, const WriteOptions& options,
                OutputTransaction& tx) {
  const TetFormat format = output_format(path, options);
  if (fields && format != TetFormat::Vtu && format != TetFormat::VtkLegacy)
    throw InvalidArgument("fields can only be written to .vtu or .vtk, not " + path);
  if (fields && fields->mid_nodes && format != TetFormat::Vtu)
    throw InvalidArgument("quadratic cells are written to .vtu only, not " + path);
  const std::vector<std::string> files = output_files(path, format);
  FlatMesh flat = flatten(mesh, fields);
  switch (format) {
    case TetFormat::Gmsh22:
      write_gmsh22(flat, tx.open(files[0]), options);
      break;
    case TetFormat::Medit:
      write_medit(flat, tx.open(files[0]), options);
      break;
    case TetFormat::VtkLegacy:
      write_vtk_legacy(flat, tx.open(files[0]), options);
      break;
    case TetFormat::Vtu:
      write_vtu(flat, tx.open(files[0]), options);
      break;
    case TetFormat::TetGen: {
      AtomicFile& node = tx.open(files[0]);
      write_tetgen(flat, node, tx.open(files[1]), options);
      break;
    }
    case TetFormat::Auto:
      break;
  }
}

void write_impl(const TetMesh& mesh, const std::string& path, const MeshFields* fields, const WriteOptions& options) {
  OutputTransaction tx;
  write_impl(mesh, path, fields, options, tx);
  tx.commit();
}

}  // namespace
}  // namespace io

TetFormat format_from_path(const std::string& path) {
  std::string ext = io::lower_extension(path);
  if (ext == "msh") return TetFormat::Gmsh22;
  if (ext == "mesh") return TetFormat::Medit;
  if (ext == "vtk") return TetFormat::VtkLegacy;
  if (ext == "vtu") return TetFormat::Vtu;
  if (ext == "node" || ext == "ele") return TetFormat::TetGen;
  return TetFormat::Auto;
}

bool is_tet_mesh_path(const std::string& path) { return format_from_path(path) != TetFormat::Auto; }

TetMesh read_tet_mesh(const std::string& path, ReadReport* report) { return read_tet_mesh(path, ReadOptions{}, report); }

TetMesh read_tet_mesh(const std::string& path, const ReadOptions& options, ReadReport* report) {
  TetFormat format = format_from_path(path);
  std::string ext = io::lower_extension(path);
  if (format == TetFormat::Auto) {
    if (io::is_surface_extension(ext))
      io::throw_io(path, 0, "." + ext + " is a surface format, a volume (tetrahedral) mesh is needed");
    io::throw_io(path, 0, "unknown tet mesh format '." + ext + "' (use .msh, .mesh, .vtk, .vtu, .node or .ele)");
  }
  if (format == TetFormat::TetGen) {
    std::string base = io::tetgen_base(path);
    std::string node_file = base + ".node", ele_file = base + ".ele";
    std::string node_text = io::read_file_bytes(node_file);
    std::string ele_text = io::read_file_bytes(ele_file);
    io::RawMesh raw = io::parse_tetgen(node_file, node_text, ele_file, ele_text);
    return io::build_mesh(std::move(raw), node_file, report, options);
  }
  std::string text = io::read_file_bytes(path);
  if (text.empty()) io::throw_io(path, 0, "empty file");
  io::RawMesh raw;
  switch (format) {
    case TetFormat::Gmsh22: raw = io::parse_gmsh(path, text); break;
    case TetFormat::Medit: raw = io::parse_medit(path, text); break;
    case TetFormat::VtkLegacy: raw = io::parse_vtk_legacy(path, text); break;
    case TetFormat::Vtu: raw = io::parse_vtu(path, text); break;
    default: break;
  }
  text.clear();
  text.shrink_to_fit();
  return io::build_mesh(std::move(raw), path, report, options);
}

void write_tet_mesh(const TetMesh& mesh, const std::string& path, const WriteOptions& options) {
  io::write_impl(mesh, path, nullptr, options);
}

void write_tet_mesh(const TetMesh& mesh, const std::string& path, const WriteOptions& options, OutputTransaction& tx) {
  io::write_impl(mesh, path, nullptr, options, tx);
}

void forbid_tet_mesh_input(OutputTransaction& tx, const std::string& path) {
  tx.forbid_input(path);
  if (format_from_path(path) == TetFormat::TetGen)
    for (const std::string& f : io::output_files(path, TetFormat::TetGen)) tx.forbid_input(f);
}

void reserve_tet_mesh_output(OutputTransaction& tx, const std::string& path, const std::string& role) {
  for (const std::string& f : io::output_files(path, io::output_format(path, {}))) tx.reserve(f, role);
}

void write_tet_mesh_with_fields(const TetMesh& mesh, const std::string& path, const MeshFields& fields,
                                const WriteOptions& options) {
  io::write_impl(mesh, path, &fields, options);
}

}  // namespace incise
