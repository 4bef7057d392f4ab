#include "quality/multi_face_removal.h"

#include <algorithm>

namespace incise {

namespace {

// The tet across the face of t that does not contain `off`, and that tet's vertex opposite the face.
std::pair<TetId, VertexId> across(const TetMesh& mesh, TetId t, VertexId off) {
  const int l = mesh.local_index(t, off);
  const TetId x = mesh.neighbor(t, l);
  if (!x.is_valid()) return {x, VertexId()};
  for (int k = 0; k < 4; ++k)
    if (mesh.neighbor(x, k) == t) return {x, mesh.tet_vertices(x)[k]};
  return {TetId(), VertexId()};
}

class Sandwich {
public:
  Sandwich(const TetMesh& mesh, VertexId u, VertexId w, int label, const ImproveScope& scope, int budget)
      : mesh_(mesh), u_(u), w_(w), label_(label), scope_(scope), budget_(budget) {}

  // A rim edge (p,q) of an explored face (oriented towards w) and what lies beyond it.
  struct Edge {
    AngleQuality value;  // worst new tet beyond (p,q) in the best choice
    int next = -1;       // index of the grown face in faces_, or -1: stop here, tet (p,q,u,w)
    int left = -1, right = -1;  // the grown face's other two edges
  };

  // Explores beyond directed edge (p,q) of the face whose tets are tu (with u) and tw (with w).
  int edge(VertexId p, VertexId q, TetId tu, TetId tw, VertexId z) {
    Edge e;
    e.value = angle_quality(mesh_.rest(p), mesh_.rest(q), mesh_.rest(u_), mesh_.rest(w_), scope_.targets);
    const int id = static_cast<int>(edges_.size());
    edges_.push_back(e);
    // The face across (p,q) is sandwiched when the tets across tu's face (p,q,u) and tw's face
    // (p,q,w) share their fourth vertex r: then (q,p,r) has the tets (q,p,r,u) and (q,p,r,w).
    const auto [xu, r] = across(mesh_, tu, z);
    const auto [xw, r2] = across(mesh_, tw, z);
    if (!xu.is_valid() || !xw.is_valid() || r != r2 || r == u_ || r == w_ || !taken(xu) || !taken(xw)) return id;
    std::array<std::uint32_t, 3> key{p.idx(), q.idx(), r.idx()};
    std::sort(key.begin(), key.end());
    // Each face once: a face reached twice (faces around an inner vertex) is not grown again.
    if (budget_ <= 0 || std::find(keys_.begin(), keys_.end(), key) != keys_.end()) return id;
    --budget_;
    keys_.push_back(key);
    const int face = static_cast<int>(faces_.size());
    faces_.push_back({{q, p, r}, xu, xw});
    const int l = edge(p, r, xu, xw, q), rr = edge(r, q, xu, xw, p);
    AngleQuality grown = edges_[l].value;
    grown.combine(edges_[rr].value);
    if (grown.q > edges_[id].value.q) {
      edges_[id].value = grown;
      edges_[id].next = face;
      edges_[id].left = l;
      edges_[id].right = rr;
    }
    return id;
  }

  void start(TetId tu, TetId tw, const std::array<VertexId, 3>& x) {
    std::array<std::uint32_t, 3> key{x[0].idx(), x[1].idx(), x[2].idx()};
    std::sort(key.begin(), key.end());
    keys_.push_back(key);
    faces_.push_back({x, tu, tw});
  }

  // Appends the faces and tets of the best choice beyond edge e.
  void collect(int e, MultiFacePlan& plan) const {
    const Edge& x = edges_[e];
    if (x.next < 0) return;
    const Face& f = faces_[x.next];
    plan.faces.push_back(f.v);
    plan.removed.push_back(f.tu);
    plan.removed.push_back(f.tw);
    collect(x.left, plan);
    collect(x.right, plan);
  }

  const Edge& at(int e) const { return edges_[e]; }

private:
  struct Face {
    std::array<VertexId, 3> v;
    TetId tu, tw;
  };
  bool taken(TetId x) const { return mesh_.label(x) == label_ && scope_.contains(x); }

  const TetMesh& mesh_;
  VertexId u_, w_;
  int label_;
  const ImproveScope& scope_;
  int budget_;
  std::vector<Edge> edges_;
  std::vector<Face> faces_;
  std::vector<std::array<std::uint32_t, 3>> keys_;
};

}  // namespace

std::optional<MultiFacePlan> best_multi_face_removal(const TetMesh& mesh, TetId t, int f, const ImproveScope& scope,
                                                     int max_faces) {
  const TetId n = mesh.neighbor(t, f);
  if (!n.is_valid() || !scope.contains(t) || !scope.contains(n) || mesh.label(n) != mesh.label(t)) return std::nullopt;
  const VertexId u = mesh.tet_vertices(t)[f];
  VertexId w;
  for (int k = 0; k < 4; ++k)
    if (mesh.neighbor(n, k) == t) w = mesh.tet_vertices(n)[k];
  // Oriented out of t, towards w: (x_k, x_k+1, u, w) is positive, as TetMesh::flip23 builds it.
  const auto x = mesh.face_vertices(t, f);
  Sandwich s(mesh, u, w, mesh.label(t), scope, max_faces);
  s.start(t, n, x);
  int e[3];
  for (int k = 0; k < 3; ++k) e[k] = s.edge(x[k], x[(k + 1) % 3], t, n, x[(k + 2) % 3]);
  MultiFacePlan plan;
  plan.u = u;
  plan.w = w;
  plan.faces.push_back(x);
  plan.removed = {t, n};
  for (int k = 0; k < 3; ++k) {
    plan.after.combine(s.at(e[k]).value);
    s.collect(e[k], plan);
  }
  return plan;
}

}  // namespace incise
