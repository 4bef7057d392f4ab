// The light half of tetrahedralize.h: option parsing, statistics and small geometry.
#include "mesh/tetrahedralize/tetrahedralize.h"

#include <algorithm>
#include <cctype>
#include <cstring>
#include <map>
#include <cmath>
#include <sstream>

#include "mesh/errors.h"

namespace incise {

Length Length::parse(const std::string& text) {
  std::string s = text;
  s.erase(std::remove_if(s.begin(), s.end(), [](unsigned char c) { return std::isspace(c); }), s.end());
  Length l;
  if (!s.empty() && s.back() == '%') {
    l.relative = true;
    s.pop_back();
  }
  std::size_t used = 0;
  double v = 0;
  try {
    v = std::stod(s, &used);
  } catch (const std::exception&) {
    used = 0;
  }
  if (s.empty() || used != s.size() || !std::isfinite(v) || v <= 0)
    throw InvalidArgument("bad length '" + text + "': expected a positive number (absolute) or a percentage like 5%");
  l.value = l.relative ? v / 100 : v;
  return l;
}

std::string Length::str() const {
  std::ostringstream os;
  if (relative)
    os << value * 100 << "%";
  else
    os << value;
  return os.str();
}

unsigned parse_optimize(const std::string& text) {
  if (text == "none" || text.empty()) return kOptimizeNone;
  unsigned flags = 0;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item == "odt")
      flags |= kOptimizeOdt;
    else if (item == "lloyd")
      flags |= kOptimizeLloyd;
    else if (item == "perturb")
      flags |= kOptimizePerturb;
    else if (item == "exude")
      flags |= kOptimizeExude;
    else
      throw InvalidArgument("bad --optimize item '" + item + "': expected odt, lloyd, perturb, exude or none");
  }
  return flags;
}

std::string optimize_str(unsigned flags) {
  std::string s;
  for (auto [f, n] : {std::pair{kOptimizeOdt, "odt"}, {kOptimizeLloyd, "lloyd"}, {kOptimizePerturb, "perturb"},
                      {kOptimizeExude, "exude"}})
    if (flags & f) {
      if (!s.empty()) s += ',';
      s += n;
    }
  return s.empty() ? "none" : s;
}

std::string TetraStats::summary() const {
  std::ostringstream os;
  os.precision(4);
  os << engine << ": " << tets << " tets, " << vertices << " vertices, dihedral " << min_dihedral << ".." << max_dihedral
     << " deg, volume " << volume;
  if (input_volume > 0) os << " (" << std::showpos << 100 * (volume - input_volume) / input_volume << std::noshowpos << "% vs input)";
  os << ", " << seconds << " s";
  if (time_limit_hit) os << " (an optimizer hit its time limit: not repeatable)";
  for (const std::string& n : notes) os << "; " << n;
  return os.str();
}

namespace {

// Every edge with two triangles: its length and the cosine of the angle between the normals.
std::vector<std::pair<double, double>> edge_bends(const SurfaceMesh& s) {
  std::map<std::pair<int, int>, std::vector<int>> faces;
  for (std::size_t f = 0; f < s.triangles.size(); ++f)
    for (int k = 0; k < 3; ++k) {
      auto e = std::minmax(s.triangles[f][k], s.triangles[f][(k + 1) % 3]);
      faces[e].push_back(int(f));
    }
  auto normal = [&](int f) {
    const auto& t = s.triangles[f];
    return (s.vertices[t[1]] - s.vertices[t[0]]).cross(s.vertices[t[2]] - s.vertices[t[0]]).normalized();
  };
  std::vector<std::pair<double, double>> bends;
  for (const auto& [e, fs] : faces) {
    if (fs.size() != 2) continue;
    bends.emplace_back((s.vertices[e.second] - s.vertices[e.first]).norm(), normal(fs[0]).dot(normal(fs[1])));
  }
  return bends;
}

}  // namespace

double auto_features_angle(const SurfaceMesh& s) {
  std::size_t n40 = 0, n60 = 0, edges = 0;
  const double c40 = std::cos(40 * M_PI / 180), c60 = std::cos(60 * M_PI / 180);
  for (const auto& [length, c] : edge_bends(s)) {
    ++edges;
    if (c < c40) ++n40;
    if (c < c60) ++n60;
  }
  const bool crisp = n60 > 0 && 2 * n60 >= n40 && 10 * n60 <= edges;
  return crisp ? 60.0 : 0.0;
}

double feature_length(const SurfaceMesh& s, double angle) {
  const double c = std::cos(angle * M_PI / 180);
  double length = 0;
  for (const auto& [l, cb] : edge_bends(s))
    if (cb < c) length += l;
  return length;
}

std::size_t split_pinched_vertices(TetMesh& mesh) {
  std::size_t added = 0;
  const std::size_t n = mesh.vertex_capacity();
  for (std::size_t i = 0; i < n; ++i) {
    const VertexId v(static_cast<std::uint32_t>(i));
    if (!mesh.is_alive(v)) continue;
    const std::vector<TetId> star(mesh.incident_tets(v).begin(), mesh.incident_tets(v).end());
    if (star.size() < 2) continue;
    // Flood the star through faces containing v (faces opposite the other vertices).
    std::vector<int> comp(star.size(), -1);
    auto index_of = [&](TetId t) {
      for (std::size_t k = 0; k < star.size(); ++k)
        if (star[k] == t) return int(k);
      return -1;
    };
    int ncomp = 0;
    for (std::size_t s0 = 0; s0 < star.size(); ++s0) {
      if (comp[s0] >= 0) continue;
      std::vector<std::size_t> stack{s0};
      comp[s0] = ncomp;
      while (!stack.empty()) {
        const TetId t = star[stack.back()];
        stack.pop_back();
        const int lv = mesh.local_index(t, v);
        for (int f = 0; f < 4; ++f) {
          if (f == lv) continue;
          const TetId nb = mesh.neighbor(t, f);
          if (!nb.is_valid()) continue;
          const int k = index_of(nb);
          if (k >= 0 && comp[k] < 0) {
            comp[k] = ncomp;
            stack.push_back(std::size_t(k));
          }
        }
      }
      ++ncomp;
    }
    for (int c = 1; c < ncomp; ++c) {
      const VertexId nv = mesh.add_vertex(mesh.rest(v));
      ++added;
      for (std::size_t k = 0; k < star.size(); ++k)
        if (comp[k] == c) mesh.replace_vertex(star[k], v, nv);
    }
  }
  mesh.discard_change();
  return added;
}

namespace {

// Boundary vertices whose link (the boundary edges opposite them) is not one cycle.
std::vector<VertexId> nonmanifold_boundary_vertices(const TetMesh& mesh) {
  std::map<std::uint32_t, std::vector<std::pair<std::uint32_t, std::uint32_t>>> link;
  for (const BoundaryFace& f : mesh.boundary_faces())
    for (int k = 0; k < 3; ++k)
      link[f.vertices[k].idx()].emplace_back(f.vertices[(k + 1) % 3].idx(), f.vertices[(k + 2) % 3].idx());
  std::vector<VertexId> bad;
  for (auto& [v, edges] : link) {
    std::map<std::uint32_t, std::vector<std::uint32_t>> adj;
    for (auto [a, b] : edges) {
      adj[a].push_back(b);
      adj[b].push_back(a);
    }
    bool ok = true;
    for (auto& [w, ns] : adj) ok = ok && ns.size() == 2;
    if (ok) {  // one cycle: walk it
      std::uint32_t prev = adj.begin()->first, cur = adj.begin()->second[0];
      std::size_t steps = 1;
      while (cur != adj.begin()->first && steps <= adj.size()) {
        const auto& ns = adj[cur];
        const std::uint32_t next = ns[0] == prev ? ns[1] : ns[0];
        prev = cur;
        cur = next;
        ++steps;
      }
      ok = steps == adj.size();
    }
    if (!ok) bad.push_back(VertexId(v));
  }
  return bad;
}

}  // namespace

std::size_t make_boundary_manifold(TetMesh& mesh, int rounds) {
  std::size_t removed = 0;
  for (int r = 0; r <= rounds; ++r) {
    split_pinched_vertices(mesh);
    const std::vector<VertexId> bad = nonmanifold_boundary_vertices(mesh);
    if (bad.empty()) {
      for (VertexId v : mesh.vertices())
        if (mesh.incident_tets(v).empty()) mesh.remove_vertex(v);
      mesh.compact();
      mesh.discard_change();
      return removed;
    }
    if (r == rounds) break;
    for (VertexId v : bad) {
      const std::vector<TetId> star(mesh.incident_tets(v).begin(), mesh.incident_tets(v).end());
      for (TetId t : star) {
        mesh.remove_tet(t);
        ++removed;
      }
    }
  }
  throw Error("tetrahedralize: could not make the boundary manifold; try another --size or --seed");
}

double estimate_tet_count(double volume, double size) {
  // Mesh_3 cells at circumradius bound `size` average about 0.18 size^3 in volume (the
  // regular tet with that circumradius has 0.51 size^3; refinement overshoots the bound).
  return volume / (0.18 * size * size * size);
}

std::pair<double, double> dihedral_range(const TetMesh& mesh) {
  double lo = 180, hi = 0;
  for (TetId t : mesh.tets()) {
    const auto& v = mesh.tet_vertices(t);
    const Vec3 p[4] = {mesh.rest(v[0]), mesh.rest(v[1]), mesh.rest(v[2]), mesh.rest(v[3])};
    // Outward face normals; the dihedral at edge (i,j) is pi minus the angle between the
    // normals of the two faces containing it (the faces opposite the other two vertices).
    Vec3 n[4];
    for (int f = 0; f < 4; ++f) {
      const auto& fl = kFaceLocal[f];
      n[f] = (p[fl[1]] - p[fl[0]]).cross(p[fl[2]] - p[fl[0]]);
      const double len = n[f].norm();
      n[f] = len > 0 ? Vec3(n[f] / len) : Vec3::Zero();
    }
    for (int a = 0; a < 4; ++a)
      for (int b = a + 1; b < 4; ++b) {
        const double c = std::clamp(-n[a].dot(n[b]), -1.0, 1.0);
        const double ang = std::acos(c) * 180 / M_PI;
        lo = std::min(lo, ang);
        hi = std::max(hi, ang);
      }
  }
  if (mesh.num_tets() == 0) return {0, 0};
  return {lo, hi};
}

double enclosed_volume(const SurfaceMesh& s) {
  if (s.vertices.empty()) return 0;
  const Vec3 o = s.vertices.front();  // shift for accuracy far from the origin
  double v = 0;
  for (const auto& t : s.triangles)
    v += (s.vertices[t[0]] - o).dot((s.vertices[t[1]] - o).cross(s.vertices[t[2]] - o));
  return v / 6;
}

bool is_image_path(const std::string& path) {
  std::string p = path;
  std::transform(p.begin(), p.end(), p.begin(), [](unsigned char c) { return std::tolower(c); });
  for (const char* ext : {".inr", ".inr.gz", ".hdr", ".img", ".img.gz", ".gis"})
    if (p.size() >= std::strlen(ext) && p.compare(p.size() - std::strlen(ext), std::string::npos, ext) == 0) return true;
  return false;
}

}  // namespace incise
