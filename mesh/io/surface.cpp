// Triangle surfaces: assimp for reading, a few plain text formats for writing.
#include "mesh/io/surface.h"

#include <cstring>
#include <assimp/Importer.hpp>
#include <assimp/scene.h>
#include <sys/stat.h>

#include <cctype>
#include <cstdlib>
#include <cerrno>
#include <cstdint>
#include <fstream>
#include <sstream>

#include "mesh/errors.h"
#include "mesh/io/atomic_file.h"
#include "mesh/io/formats.h"
#include "mesh/io/input_file.h"
#include "mesh/io/parse_util.h"
#include "mesh/io/tet_io.h"

namespace incise {

namespace {
// assimp's PLY importer loops forever on some malformed headers (found by fuzz_surface), so
// the header is checked here first: known keywords, well-formed element and property lines.
void check_ply_header(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string line;
  long n = 0;
  auto fail = [&](const std::string& why) { io::throw_io(path, n, "bad PLY header: " + why); };
  static const char* kTypes[] = {"char",  "uchar", "short",  "ushort",  "int",     "uint",   "float",  "double", "int8",
                                 "uint8", "int16", "uint16", "int32",   "uint32",  "float32", "float64"};
  auto is_type = [&](const std::string& t) {
    for (const char* k : kTypes)
      if (t == k) return true;
    return false;
  };
  while (std::getline(in, line)) {
    ++n;
    if (n > 10000) fail("no end_header in the first 10000 lines");
    if (!line.empty() && line.back() == '\r') line.pop_back();
    // A vertical tab or form feed ends a word for us but not a line for assimp, which then
    // reads the data as header and never stops (found by fuzz_surface): none in the header.
    for (char ch : line)
      if (static_cast<unsigned char>(ch) < 0x20 && ch != '\t') fail("a control character in the header");
    std::istringstream ls(line);
    std::string kw;
    ls >> kw;
    if (n == 1) {
      if (kw != "ply") fail("the first line must be 'ply'");
      continue;
    }
    if (kw == "end_header") {
      std::string rest;
      if (ls >> rest) fail("text after end_header");
      return;
    }
    if (kw == "comment" || kw == "obj_info") continue;
    std::vector<std::string> w;
    for (std::string t; ls >> t;) w.push_back(t);
    if (kw == "format") {
      if (w.size() != 2 || (w[0] != "ascii" && w[0] != "binary_little_endian" && w[0] != "binary_big_endian"))
        fail("bad format line");
    } else if (kw == "element") {
      if (w.size() != 2 || w[1].find_first_not_of("0123456789") != std::string::npos || w[1].size() > 10)
        fail("bad element line");
    } else if (kw == "property") {
      bool ok = (w.size() == 2 && is_type(w[0])) || (w.size() == 4 && w[0] == "list" && is_type(w[1]) && is_type(w[2]));
      if (!ok) fail("bad property line");
    } else {
      fail("unknown keyword '" + io::Cursor::shorten(kw) + "'");
    }
  }
  fail("no end_header");
}

// OFF is read here, not by assimp: its importer clamped a face index past the vertex count
// to the last vertex (`3 0 1 9` became a valid triangle; the OBJ importer refuses the same
// mistake), reserved memory by the header's counts (a 40-digit count took 2 GB) and crashed on
// malformed files, all found by fuzzing. The format: an optional keyword ([ST][C][N]OFF; the
// extra per-vertex and per-face fields are skipped), the counts `V F [E]`, V lines of
// coordinates, F lines `k i_1 .. i_k`; `#` starts a comment. Polygons are fan-triangulated and
// faces of fewer than 3 vertices dropped, like the other formats.
SurfaceMesh read_off(const std::string& path, std::uintmax_t file_size) {
  std::ifstream in(path, std::ios::binary);
  if (!in) io::throw_io(path, 0, std::string("cannot open: ") + std::strerror(errno));
  std::string line;
  long n = 0;
  std::istringstream ss;
  // The next line with content, its comment stripped.
  auto next = [&]() {
    while (std::getline(in, line)) {
      ++n;
      const auto hash = line.find('#');
      if (hash != std::string::npos) line.resize(hash);
      if (line.find_first_not_of(" \t\r") == std::string::npos) continue;
      ss.clear();
      ss.str(line);
      return true;
    }
    return false;
  };
  if (!next()) io::throw_io(path, n, "no OFF header");
  std::string tok;
  ss >> tok;
  if (tok.size() >= 3 && tok.compare(tok.size() - 3, 3, "OFF") == 0) {
    if (tok.find_first_of("4n") != std::string::npos)
      io::throw_io(path, n, "'" + io::Cursor::shorten(tok) + "': only 3D OFF is read");
    if (!(ss >> tok)) {
      if (!next()) io::throw_io(path, n, "the file ends before the vertex and face counts");
      ss >> tok;
    }
  }
  const long header_line = n;
  auto integer = [&](const std::string& t, long line_no, const std::string& what) {
    char* end = nullptr;
    errno = 0;
    const long c = std::strtol(t.c_str(), &end, 10);
    if (t.empty() || *end != '\0' || errno == ERANGE || c < 0)
      io::throw_io(path, line_no, what + " '" + io::Cursor::shorten(t) + "' is not a count");
    return c;
  };
  const long nv = integer(tok, header_line, "vertex count");
  std::string tf;
  if (!(ss >> tf)) io::throw_io(path, header_line, "no face count after the vertex count");
  const long nf = integer(tf, header_line, "face count");
  if (std::uintmax_t(nv) + std::uintmax_t(nf) > file_size)
    io::throw_io(path, header_line, "the header announces " + tok + " vertices and " + tf + " faces, more than a file of " +
                                        std::to_string(file_size) + " bytes can hold");
  SurfaceMesh s;
  s.vertices.reserve(std::size_t(nv));
  for (long v = 0; v < nv; ++v) {
    if (!next()) io::throw_io(path, n, "the file ends after " + std::to_string(v) + " of its " + std::to_string(nv) + " vertices");
    Vec3 p;
    for (int d = 0; d < 3; ++d) {
      std::string c;
      if (!(ss >> c)) io::throw_io(path, n, "a vertex needs 3 coordinates");
      char* end = nullptr;
      p[d] = std::strtod(c.c_str(), &end);
      if (*end != '\0') io::throw_io(path, n, "coordinate '" + io::Cursor::shorten(c) + "' is not a number");
    }
    if (!p.allFinite()) io::throw_io(path, n, "non-finite vertex coordinate");
    s.vertices.push_back(p);
  }
  std::vector<int> face;
  for (long f = 0; f < nf; ++f) {
    if (!next()) io::throw_io(path, n, "the file ends after " + std::to_string(f) + " of its " + std::to_string(nf) + " faces");
    std::string kt;
    ss >> kt;
    const long k = integer(kt, n, "face size");
    if (std::uintmax_t(k) > file_size) io::throw_io(path, n, "face size " + kt + " is more than the file can hold");
    face.clear();
    for (long i = 0; i < k; ++i) {
      std::string t;
      if (!(ss >> t)) io::throw_io(path, n, "face has " + std::to_string(i) + " of its " + std::to_string(k) + " vertex indices");
      char* end = nullptr;
      errno = 0;
      const long idx = std::strtol(t.c_str(), &end, 10);
      if (*end != '\0' || errno == ERANGE)
        io::throw_io(path, n, "face vertex index '" + io::Cursor::shorten(t) + "' is not an integer");
      if (idx < 0 || idx >= nv)
        io::throw_io(path, n, "face vertex index " + t + " out of range (" + std::to_string(nv) + " vertices)");
      face.push_back(int(idx));
    }
    for (std::size_t i = 1; i + 1 < face.size(); ++i) s.triangles.push_back({face[0], face[i], face[i + 1]});
  }
  if (s.triangles.empty()) io::throw_io(path, 0, "no triangles in the file");
  return s;
}

}  // namespace

SurfaceMesh read_surface(const std::string& path) {
  const std::uintmax_t size = check_input_file(path);
  if (size == 0) io::throw_io(path, 0, "empty file");
  if (io::lower_extension(path) == "ply") check_ply_header(path);
  if (io::lower_extension(path) == "off") return read_off(path, size);
  if (is_tet_mesh_path(path))
    io::throw_io(path, 0, "is a tetrahedral mesh format; a surface is needed here (OBJ, STL, PLY, OFF, glTF, ...)");
  Assimp::Importer importer;
  // No assimp post-processing: its steps assert (abort) on malformed input, e.g. a face
  // with no vertices in TriangulateProcess. Polygons are fan-triangulated and node
  // transforms applied here instead.
  const aiScene* scene = importer.ReadFile(path, 0);
  if (!scene) {
    std::string why = importer.GetErrorString();
    while (!why.empty() && (why.back() == '\n' || why.back() == '\r')) why.pop_back();
    for (char& c : why)
      if (c == '\n' || c == '\r') c = ' ';
    io::throw_io(path, 0, "cannot read surface: " + (why.empty() ? std::string("unknown format") : why));
  }
  SurfaceMesh s;
  auto add_mesh = [&](const aiMesh* mesh, const aiMatrix4x4& transform) {
    if (!mesh || !mesh->mVertices || !mesh->mFaces) return;
    const int base = static_cast<int>(s.vertices.size());
    bool any = false;
    for (unsigned f = 0; f < mesh->mNumFaces; ++f) {
      const aiFace& face = mesh->mFaces[f];
      if (face.mNumIndices < 3 || !face.mIndices) continue;  // points and lines
      for (unsigned k = 0; k < face.mNumIndices; ++k)
        if (face.mIndices[k] >= mesh->mNumVertices) io::throw_io(path, 0, "face index out of range");
      for (unsigned k = 1; k + 1 < face.mNumIndices; ++k)
        s.triangles.push_back({base + static_cast<int>(face.mIndices[0]), base + static_cast<int>(face.mIndices[k]),
                               base + static_cast<int>(face.mIndices[k + 1])});
      any = true;
    }
    if (!any) return;
    for (unsigned v = 0; v < mesh->mNumVertices; ++v) {
      const aiVector3D p = transform * mesh->mVertices[v];
      Vec3 q(p.x, p.y, p.z);
      if (!q.allFinite()) io::throw_io(path, 0, "non-finite vertex coordinate");
      s.vertices.push_back(q);
    }
  };
  if (scene->mRootNode) {
    struct Item {
      const aiNode* node;
      aiMatrix4x4 parent;
    };
    std::vector<Item> stack{{scene->mRootNode, aiMatrix4x4()}};
    std::size_t visited = 0;
    while (!stack.empty()) {
      Item it = stack.back();
      stack.pop_back();
      if (!it.node) continue;
      if (++visited > 1000000) io::throw_io(path, 0, "scene graph too large or cyclic");
      const aiMatrix4x4 m = it.parent * it.node->mTransformation;
      for (unsigned i = 0; i < it.node->mNumMeshes; ++i)
        if (it.node->mMeshes && it.node->mMeshes[i] < scene->mNumMeshes) add_mesh(scene->mMeshes[it.node->mMeshes[i]], m);
      for (unsigned c = 0; c < it.node->mNumChildren; ++c)
        if (it.node->mChildren) stack.push_back({it.node->mChildren[c], m});
    }
  } else {
    for (unsigned i = 0; i < scene->mNumMeshes; ++i) add_mesh(scene->mMeshes[i], aiMatrix4x4());
  }
  if (s.triangles.empty()) io::throw_io(path, 0, "no triangles in the file");
  return s;
}

void write_surface(const SurfaceMesh& surface, const std::string& path) {
  const std::string ext = io::lower_extension(path);
  if (ext != "off" && ext != "obj" && ext != "stl")
    io::throw_io(path, 0, "unknown surface format '." + ext + "' (write .off, .obj or .stl)");
  const int nv = static_cast<int>(surface.vertices.size());
  for (const auto& t : surface.triangles)
    for (int v : t)
      if (v < 0 || v >= nv) throw InvalidArgument("write_surface: triangle index " + std::to_string(v) + " out of range");
  AtomicFile out(path);
  std::string b;
  auto vec = [&](const Vec3& p) {
    for (int d = 0; d < 3; ++d) {
      b += ' ';
      io::append_real(b, p[d]);
    }
  };
  if (ext == "off") {
    b += "OFF\n" + std::to_string(nv) + " " + std::to_string(surface.triangles.size()) + " 0\n";
    for (const Vec3& p : surface.vertices) {
      vec(p);
      b += '\n';
      out.flush_if_large(b);
    }
    for (const auto& t : surface.triangles) {
      b += "3 " + std::to_string(t[0]) + " " + std::to_string(t[1]) + " " + std::to_string(t[2]) + "\n";
      out.flush_if_large(b);
    }
  } else if (ext == "obj") {
    b += "# incise surface\n";
    for (const Vec3& p : surface.vertices) {
      b += 'v';
      vec(p);
      b += '\n';
      out.flush_if_large(b);
    }
    for (const auto& t : surface.triangles) {
      b += "f " + std::to_string(t[0] + 1) + " " + std::to_string(t[1] + 1) + " " + std::to_string(t[2] + 1) + "\n";
      out.flush_if_large(b);
    }
  } else {
    b += "solid incise\n";
    for (const auto& t : surface.triangles) {
      const Vec3 &a = surface.vertices[t[0]], &c = surface.vertices[t[1]], &d = surface.vertices[t[2]];
      Vec3 n = (c - a).cross(d - a);
      double len = n.norm();
      if (len > 0) n /= len;
      b += "facet normal";
      vec(n);
      b += "\nouter loop\n";
      for (const Vec3* p : {&a, &c, &d}) {
        b += "vertex";
        vec(*p);
        b += '\n';
      }
      b += "endloop\nendfacet\n";
      out.flush_if_large(b);
    }
    b += "endsolid incise\n";
  }
  out.write(b);
  out.commit();
}

SurfaceMesh boundary_surface(const TetMesh& mesh) {
  SurfaceMesh s;
  std::vector<int> map(mesh.vertex_capacity(), -1);
  std::vector<std::array<VertexId, 3>> faces;
  for (std::uint32_t ti = 0; ti < mesh.tet_capacity(); ++ti) {
    TetId t(ti);
    if (!mesh.is_alive(t)) continue;
    for (int f = 0; f < 4; ++f)
      if (!mesh.neighbor(t, f).is_valid()) {
        faces.push_back(mesh.face_vertices(t, f));
        for (VertexId v : faces.back()) map[v.idx()] = 0;
      }
  }
  // Increasing VertexId order, so the numbering does not depend on face order.
  for (std::uint32_t v = 0; v < map.size(); ++v)
    if (map[v] == 0) {
      map[v] = static_cast<int>(s.vertices.size()) + 1;
      s.vertices.push_back(mesh.rest(VertexId(v)));
    }
  s.triangles.reserve(faces.size());
  for (const auto& f : faces) s.triangles.push_back({map[f[0].idx()] - 1, map[f[1].idx()] - 1, map[f[2].idx()] - 1});
  return s;
}

}  // namespace incise
