#pragma once
// TetMesh: the tetrahedral mesh every part of incise edits and reads.
//
// Conventions
//  - A tet (v0,v1,v2,v3) is positively oriented when det(v1-v0, v2-v0, v3-v0) > 0;
//    validate() requires it for every live tet.
//  - Local face f of a tet is the face opposite local vertex f. face_vertices(t, f)
//    returns it ordered so that its right-hand normal points out of t:
//      f=0: (v1,v2,v3)  f=1: (v0,v3,v2)  f=2: (v0,v1,v3)  f=3: (v0,v2,v1)
//    For a boundary face this is the outward orientation of the mesh boundary.
//  - neighbor(t, f) is the tet across face f, or an invalid TetId on the boundary.
//  - Removed elements are marked dead and recycled through a free list; ids of live
//    elements never change until compact().
//  - Every edit updates incidence in time proportional to the elements it touches and
//    appends to the pending TopologyChange, which take_change() hands out.
#include <array>
#include <cstdint>
#include <span>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "mesh/handles.h"
#include "mesh/id_set.h"
#include "mesh/topology_change.h"

namespace incise {

using Vec3 = Eigen::Vector3d;

// Boundary face tags (user values >= 16 are free to use).
enum FaceTag : std::uint16_t {
  kTagNone = 0,     // interior face, or boundary exposed by a plain remove_tet()
  kTagSurface = 1,  // original surface of the organ
  kTagCut = 2,      // created by a cut
};

constexpr std::array<std::array<int, 3>, 4> kFaceLocal = {{{1, 2, 3}, {0, 3, 2}, {0, 1, 3}, {0, 2, 1}}};

struct BoundaryFace {
  TetId tet;
  int local = 0;                     // local face index in tet
  std::array<VertexId, 3> vertices;  // outward orientation
  std::uint16_t tag = kTagNone;
};

// Old -> new id maps returned by compact(); dead elements map to an invalid id.
struct CompactMaps {
  std::vector<VertexId> vertex;
  std::vector<TetId> tet;
};

// Counters for the locality tests: how many incidence entries edits have visited.
struct EditCounters {
  std::uint64_t edits = 0;
  std::uint64_t visits = 0;
};

class TetMesh {
public:
  TetMesh() = default;

  // ---- sizes and liveness ---------------------------------------------------------
  std::size_t num_vertices() const { return vertex_alive_count_; }  // live vertices
  std::size_t num_tets() const { return tet_alive_count_; }         // live tets
  std::size_t vertex_capacity() const { return rest_.size(); }      // ids are < capacity
  std::size_t tet_capacity() const { return tet_v_.size(); }
  bool is_alive(VertexId v) const { return v.is_valid() && v.idx() < rest_.size() && vertex_alive_[v.idx()]; }
  bool is_alive(TetId t) const { return t.is_valid() && t.idx() < tet_v_.size() && tet_alive_[t.idx()]; }

  // Live ids in increasing order (O(capacity); not for per-frame paths).
  std::vector<VertexId> vertices() const;
  std::vector<TetId> tets() const;

  // ---- geometry and attributes ----------------------------------------------------
  const Vec3& rest(VertexId v) const { return rest_[v.idx()]; }
  void set_rest(VertexId v, const Vec3& p) { rest_[v.idx()] = p; }
  const std::array<VertexId, 4>& tet_vertices(TetId t) const { return tet_v_[t.idx()]; }
  TetId neighbor(TetId t, int f) const { return tet_n_[t.idx()][f]; }
  int label(TetId t) const { return label_[t.idx()]; }
  void set_label(TetId t, int label) { label_[t.idx()] = label; }
  std::uint16_t face_tag(TetId t, int f) const { return face_tag_[t.idx()][f]; }
  void set_face_tag(TetId t, int f, std::uint16_t tag) { face_tag_[t.idx()][f] = tag; }
  std::span<const TetId> incident_tets(VertexId v) const { return vertex_tets_[v.idx()]; }

  std::array<VertexId, 3> face_vertices(TetId t, int f) const;
  // Local index (0..3) of v in t, or -1.
  int local_index(TetId t, VertexId v) const;
  // Signed volume with rest positions (positive for a correctly oriented tet).
  double volume(TetId t) const;
  double total_volume() const;  // O(mesh)
  std::vector<BoundaryFace> boundary_faces() const;  // O(mesh)

  // Tets containing edge (a,b). For an interior edge they are ordered around the edge so
  // that (a, b, ring[i], ring[i+1]) is positively oriented for each returned tet i;
  // `closed` tells whether the ring closes (interior edge) or not (boundary edge).
  struct EdgeStar {
    std::vector<TetId> tets;
    std::vector<VertexId> ring;  // ring.size() == tets.size() (+1 when open)
    bool closed = false;
  };
  // Throws InvalidMesh when the tets around the edge form more than one fan (possible after
  // remove_tet); split_edge does not need the order and handles that case.
  EdgeStar edge_star(VertexId a, VertexId b) const;

  // ---- basic edits ------------------------------------------------------------------
  void reserve(std::size_t vertices, std::size_t tets);
  VertexId add_vertex(const Vec3& rest);
  // A vertex whose rest position is interpolated from parents; recorded as such in the
  // TopologyChange (weights need not sum to 1 only for duplication, where it is {1}).
  VertexId add_vertex_interpolated(std::span<const VertexId> parents, std::span<const double> weights);
  // Moves v's rest position to sum_k weights[k] * rest(parents[k]), where parents/weights are
  // the barycentric coordinates of the new position in a tet of the mesh before the move
  // (usually one of v's own tets). Recorded in TopologyChange::moved_vertices, and v's tets as
  // removed + added. Does not check orientation: callers check first (is_move_ok).
  void move_vertex(VertexId v, std::span<const VertexId> parents, std::span<const double> weights);
  // True when moving v to p keeps every incident tet's signed volume above
  // min_volume_fraction times its current volume (and positive).
  bool is_move_ok(VertexId v, const Vec3& p, double min_volume_fraction = 0.0) const;
  // Removes an isolated vertex (throws InvalidMesh if tets still use it).
  void remove_vertex(VertexId v);
  // Adds a tet and links it to its face neighbours. Throws InvalidMesh for a repeated
  // vertex, a dead vertex, or a face that already has tets on both sides.
  TetId add_tet(VertexId a, VertexId b, VertexId c, VertexId d, int label = 0);
  // Removes a tet; faces it shared become boundary faces of its neighbours (tag None).
  void remove_tet(TetId t);
  // Replaces a tet's vertex in place (same id), relinking neighbours; used by cutting to
  // move a tet onto a duplicated vertex. Recorded as remove + add of t.
  void replace_vertex(TetId t, VertexId old_v, VertexId new_v);

  // ---- refinement (always valid on a valid mesh; they only subdivide) ------------------
  // Inserts a vertex at (1-s)*a + s*b (0<s<1) and splits every tet around the edge.
  VertexId split_edge(VertexId a, VertexId b, double s = 0.5);
  // Inserts a vertex at barycentric w (all > 0) in face f of t, splitting t and the tet
  // across the face (1 -> 3 each).
  VertexId split_face(TetId t, int f, const std::array<double, 3>& w = {1.0 / 3, 1.0 / 3, 1.0 / 3});
  // Inserts a vertex at barycentric w (all > 0) in t, splitting it 1 -> 4.
  VertexId split_tet(TetId t, const std::array<double, 4>& w = {0.25, 0.25, 0.25, 0.25});

  // ---- flips: check, then act. The check is purely local and uses rest positions ------
  // 2-3: t and its neighbour across face f become three tets around the new edge joining
  // their apexes.
  bool is_flip23_ok(TetId t, int f) const;
  std::array<TetId, 3> flip23(TetId t, int f);
  // Edge removal: the tets around interior edge (a,b) are replaced by 2(n-2) tets built on
  // a triangulation of its ring; `triangles` index into edge_star(a,b).ring and must be a
  // triangulation of that polygon. flip32 (n=3) and flip44 (n=4) are the small cases.
  bool is_edge_removal_ok(VertexId a, VertexId b, std::span<const std::array<int, 3>> triangles) const;
  std::vector<TetId> remove_edge(VertexId a, VertexId b, std::span<const std::array<int, 3>> triangles);
  bool is_flip32_ok(VertexId a, VertexId b) const;
  std::array<TetId, 2> flip32(VertexId a, VertexId b);
  // 4-4: the four tets around (a,b) become four around the diagonal ring[k]-ring[k+2]
  // (k = 0 or 1).
  bool is_flip44_ok(VertexId a, VertexId b, int k) const;
  std::array<TetId, 4> flip44(VertexId a, VertexId b, int k);
  // Multi-face removal, the inverse of edge removal: m faces sandwiched between vertices u and
  // w (each face has one tet with u and one with w, all of one label) that form a disc with
  // every vertex on its rim are removed with their 2m tets, replaced by the m+2 tets
  // (rim edge, u, w) around the new edge u-w. `faces` are vertex triples in any order and
  // orientation; flip23 is the case m = 1. The boundary is unchanged: the removed faces are
  // interior. remove_faces returns the new tets in rim order.
  bool is_multi_face_removal_ok(VertexId u, VertexId w, std::span<const std::array<VertexId, 3>> faces) const;
  std::vector<TetId> remove_faces(VertexId u, VertexId w, std::span<const std::array<VertexId, 3>> faces);

  // Cavity insertion (Bowyer-Watson style; Stellar's vertex insertion): the tets `cavity` (one
  // label, each once) are removed and a new vertex, at sum_k weights[k] * rest(parents[k]), is
  // joined to every face of the cavity's boundary. Valid when the boundary is edge-manifold,
  // every cavity vertex lies on it (none would be orphaned) and every new tet is clearly
  // positive: the cones of a closed surface from a point that sees each face from inside tile
  // exactly the region the surface bounds. Boundary and interface faces are kept with their
  // tags. Recorded as an added vertex (parents: normally a cavity tet holding the point; when
  // a parent moved earlier in the batch, the cavity tet that holds it best at the positions the
  // batch started from, since consumers apply added vertices before moves). Same for the
  // boundary version.
  bool is_cavity_insertion_ok(std::span<const TetId> cavity, const Vec3& p) const;
  VertexId insert_in_cavity(std::span<const TetId> cavity, std::span<const VertexId> parents,
                            std::span<const double> weights);
  // Boundary insertion: the same with the new vertex on the mesh boundary, at weights (all > 0)
  // of 3 parents (inside the boundary face they span) or 2 (on the boundary edge, inside its two
  // boundary faces). Those faces are split (in three, or two each), every part keeping its
  // face's tag, so the boundary keeps its shape exactly; the vertex is joined to the cavity's
  // other boundary faces, which must all be seen from it.
  bool is_boundary_cavity_insertion_ok(std::span<const TetId> cavity, std::span<const VertexId> parents,
                                       std::span<const double> weights) const;
  VertexId insert_in_cavity_on_boundary(std::span<const TetId> cavity, std::span<const VertexId> parents,
                                        std::span<const double> weights);
  // The cavity's boundary faces, oriented towards the inside: a new tet is (face, p), positive
  // when p sees the face from inside. Empty when `cavity` is not a set of live tets of one label.
  std::vector<std::array<VertexId, 3>> cavity_boundary(std::span<const TetId> cavity) const;

  // ---- taking edits back (a progressive cut's provisional pieces, cut/provisional.h) -------
  // Between begin_undo_log() and end_undo_log() the mesh keeps, for every tet an edit removes
  // or rewrites, the tet as it was, and lists the tets and vertices the edits add. undo(), in a
  // later batch, removes what the logged edits added and puts the kept tets back (under new
  // ids): the mesh is then the one before the log, up to tet ids. Rest-position moves are not
  // logged: a log with one cannot be undone. Edits made after the log are allowed as long as
  // they left the logged edits' tets as they were (another blade cutting elsewhere).
  struct UndoLog {
    struct SavedTet {
      TetId id;
      std::array<VertexId, 4> vertices;
      std::array<std::uint16_t, 4> tags;
      int label = 0;
    };
    std::vector<SavedTet> saved;
    std::vector<TetId> added;         // ids given a tet (it may be dead again by the end)
    std::vector<VertexId> vertices;   // vertices added
    // The logged edits' tets when the log ended: undo() needs them as they were.
    std::vector<std::pair<TetId, std::array<VertexId, 4>>> pieces;
    bool moved = false;               // a rest position moved: not undoable
    bool empty() const { return saved.empty() && added.empty() && vertices.empty(); }
  };
  void begin_undo_log();
  UndoLog end_undo_log();
  // Whether undo() can take the log back: no move in it, and its pieces and vertices as they
  // were when it ended (O(log)).
  bool can_undo(const UndoLog& log) const;
  // Takes the logged edits back; returns the kept tets' (old id, new id). Throws InvalidArgument
  // unless can_undo(log).
  std::vector<std::pair<TetId, TetId>> undo(const UndoLog& log);

  // ---- batches ------------------------------------------------------------------------
  // Returns everything edited since the last call, normalized (see TopologyChange), and
  // starts a new batch. O(size of the batch).
  TopologyChange take_change();
  bool has_pending_change() const { return !pending_.empty(); }
  // Of the pending batch (what take_change() would hand out): the tets it added that are alive,
  // in take_change()'s order (O(batch)); the vertices it removed and moved so far.
  std::vector<TetId> pending_added_tets() const;
  const std::vector<VertexId>& pending_removed_vertices() const { return pending_removed_vertices_; }
  const std::vector<VertexOrigin>& pending_moved_vertices() const { return pending_moved_; }
  // Drops the pending record (readers and generators call it: a fresh mesh starts clean).
  void discard_change();
  // This mesh's identity (a copy gets a new one) and how many changes take_change() has
  // stamped: what TopologyChange::mesh and ::serial say (mesh/change_follower.h).
  std::uint64_t id() const { return identity_.id; }
  std::uint64_t changes_taken() const { return changes_taken_; }

  // ---- maintenance (explicit, outside the frame loop) ----------------------------------
  // Renumbers live elements densely, keeping relative order; clears free lists.
  CompactMaps compact();
  // Renumbers live elements densely along a space-filling (Morton) curve: vertices by rest
  // position, tets by centroid, so elements near in space are near in memory. Solvers read
  // each tet's corners and scatter to them every product; in a mesher's order (CGAL's is
  // scattered) most of those reads miss the cache (docs/solver.md, "Numbering"). Clears free
  // lists.
  CompactMaps compact_spatially();
  // Checks every invariant; throws InvalidMesh naming the element and the broken rule.
  //  check_orientation: every live tet has positive volume.
  //  check_manifold_boundary: the boundary surface is closed and edge-manifold.
  struct ValidateOptions {
    bool check_orientation = true;
    bool check_manifold_boundary = false;
  };
  void validate() const { validate(ValidateOptions{}); }
  void validate(const ValidateOptions& opt) const;

  const EditCounters& counters() const { return counters_; }
  void reset_counters() { counters_ = {}; }

private:
  // Live elements renumbered so that new id i is old id vertex_order[i] (tet_order[i]).
  CompactMaps renumber(const std::vector<std::uint32_t>& vertex_order, const std::vector<std::uint32_t>& tet_order);
  struct Event {
    enum Kind : std::uint8_t { AddTet, RemoveTet } kind;
    TetId tet;
  };
  void link_faces(TetId t);
  void unlink_tet(TetId t);
  void touch(VertexId v);
  // Splits t by point p (barycentric w in t): one child per vertex slot with w > 0, the
  // slot replaced by p. Face tags go to the child faces lying in the parent's faces.
  void star_split(TetId t, VertexId p, const std::array<double, 4>& w);
  // Removes `old_tets` and adds `new_tets` (vertex quadruples), copying boundary-face tags
  // from old faces to new faces with the same vertex set.
  std::vector<TetId> retriangulate(std::span<const TetId> old_tets,
                                   std::span<const std::array<VertexId, 4>> new_tets);
  std::vector<std::array<VertexId, 4>> edge_removal_tets(const EdgeStar& star, VertexId a, VertexId b,
                                                         std::span<const std::array<int, 3>> triangles) const;
  // The old and new tets of a multi-face removal, or false when the faces are not a sandwiched
  // disc (orientation of the new tets not checked).
  bool multi_face_removal_tets(VertexId u, VertexId w, std::span<const std::array<VertexId, 3>> faces,
                               std::vector<TetId>& old_tets, std::vector<std::array<VertexId, 4>>& new_tets) const;
  double signed_volume(const std::array<VertexId, 4>& v) const;
  // The pending record of vertex `o` (just added at p) re-expressed, when one of its parents
  // moved earlier in the batch, in the tet of `around` that best holds p at the positions the
  // batch started from: consumers apply added vertices before moves, so the record must be
  // exact there (an improvement pass smooths before it inserts).
  void express_before_moves(VertexOrigin& o, std::span<const std::array<VertexId, 4>> around, const Vec3& p) const;

  std::vector<Vec3> rest_;
  std::vector<std::uint8_t> vertex_alive_;
  std::vector<std::vector<TetId>> vertex_tets_;
  std::vector<VertexId> free_vertices_;
  std::size_t vertex_alive_count_ = 0;

  std::vector<std::array<VertexId, 4>> tet_v_;
  std::vector<std::array<TetId, 4>> tet_n_;
  std::vector<std::array<std::uint16_t, 4>> face_tag_;
  std::vector<int> label_;
  std::vector<std::uint8_t> tet_alive_;
  std::vector<TetId> free_tets_;
  std::size_t tet_alive_count_ = 0;

  // Pending batch.
  std::vector<Event> events_;
  std::vector<VertexOrigin> pending_vertices_;
  std::vector<VertexOrigin> pending_moved_;
  std::vector<VertexId> pending_removed_vertices_;
  std::vector<VertexId> pending_touched_;
  // Rest positions before the batch's first move of each vertex moved in it (added vertices:
  // where they were added).
  IdMap<Vec3> batch_origin_;
  std::vector<std::uint8_t> touched_mark_;  // per vertex: already in pending_touched_
  struct PendingFlag {
    bool empty() const { return !any; }
    bool any = false;
  } pending_;

  // A process-wide number per mesh object: copying a mesh makes a new one.
  struct Identity {
    std::uint64_t id = next();
    Identity() = default;
    Identity(const Identity&) : id(next()) {}
    Identity& operator=(const Identity&) {
      id = next();
      return *this;
    }
    Identity(Identity&&) noexcept = default;
    Identity& operator=(Identity&&) noexcept = default;
    static std::uint64_t next();
  };
  Identity identity_;
  std::uint64_t changes_taken_ = 0;
  // The undo log being recorded (begin_undo_log), with the tets it added or saved.
  bool logging_ = false;
  UndoLog log_;
  IdSet log_added_, log_saved_;
  void log_before_rewrite(TetId t);  // keeps t as it is, once, unless the log added it
  EditCounters counters_;
};

} // namespace incise
