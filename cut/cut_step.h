#pragma once
// Internal to cut/: the edits of one subdivision cut step, piece by piece (see cutter.h for
// the algorithm). CutStep owns the step's scratch (candidate tets, current positions of the
// vertices it creates, the side of each vertex w.r.t. each piece), all sized by the region the
// blade touches, never by the mesh.
#include <array>
#include <functional>
#include <map>
#include <optional>
#include <span>
#include <unordered_map>
#include <unordered_set>
#include <utility>
#include <vector>

#include "cut/cut_piece.h"
#include "mesh/id_set.h"
#include "mesh/tet_mesh.h"

namespace incise::cut_detail {

struct FaceRef {
  TetId tet;
  int local = 0;
};
// An interior face the cut surface runs through: both sides.
struct CutFacePair {
  FaceRef a, b;
};

// What a progressive cut keeps from step to step for one sheet (cut/sheet.h): the side of each
// vertex once decided, and the snap length measured when the cut first saw the vertex. Later
// splits around a vertex shorten its edges; measuring again would make whether it snaps depend
// on how many steps came before.
struct CutMemory {
  IdMap<int> side;
  IdMap<double> snap_len;
  void forget(VertexId v) {
    side.erase(v.idx());
    snap_len.erase(v.idx());
  }
};

// side() of a vertex near the sheet's plane whose star the blade's front still reaches: whether
// it snaps is not known yet, so the tets around it wait.
constexpr int kUndecided = 2;

class CutStep {
public:
  using PositionFn = std::function<Vec3(VertexId)>;
  // memory: a progressive sheet's decisions (read and extended). provisional: the sheet's front
  // is where the blade is now, so only tets whose section lies inside the swept polygon and
  // whose vertices' sides are final are cut (committed); the rest waits for later steps or
  // for the sheet's finish (provisional = false, which embeds the boundary and cuts the rest).
  CutStep(TetMesh& mesh, const PositionFn& positions, double snap, CutMemory* memory = nullptr,
          bool provisional = false);

  // Vertices that never move (CutOptions::frozen): snapping leaves them where they are.
  void set_fixed(std::span<const VertexId> fixed) {
    for (VertexId v : fixed) fixed_.insert(v.idx());
  }
  // A sheet's finish whose front [a, b] becomes the next sheet's crease (CutStep::side puts a
  // vertex a hair from both the plane and the front on the sheet).
  void set_crease_front(const Vec3& a, const Vec3& b) { crease_front_ = {a, b}; }

  // Current position of a vertex (created this step, or given by the caller, or rest).
  Vec3 position(VertexId v) const;
  // Snapped vertices stay where they are (the cut bends through them): a provisional cut's
  // edits are taken back, and a rest-position move cannot be (TetMesh::undo).
  void set_no_moves() { no_moves_ = true; }

  // Tets that may touch the piece, found by a walk from `seeds` through face neighbours;
  // when no seed touches it, `fallback` is called for seeds (the first contact). Then the walk
  // goes on from those of `more` it did not reach (parts of the body the piece reaches apart
  // from the seeds'); a walk that reached them all is the walk from `seeds` alone.
  void collect(const Piece& piece, std::span<const TetId> seeds, const std::function<std::vector<TetId>()>& fallback,
               std::span<const TetId> more = {});
  // Makes the piece's boundary segments unions of mesh edges (tet, face, edge splits).
  void embed_boundary(const Piece& piece);
  // Splits every edge crossing the piece inside its region.
  void split_crossings(const Piece& piece);
  // After all pieces: the interior faces lying on a piece, with the two tets on its two sides.
  std::vector<CutFacePair> cut_faces(std::span<const Piece> pieces);

  // At a crease (fa, fb) between the drag's previous sheet and this one: the faces of the tets
  // `around` it that lie on the two sheets' union and have its two sides on their two sides,
  // each vertex's side taken from the sheet on its side of the plane halving the angle at the
  // crease. Each sheet alone judges a face by its own plane, and near the crease the two need
  // not agree: a face on the previous sheet beside a tet the next one cut (or left whole
  // beyond the crease) is a cut face that neither opens (docs/cut.md#curved-paths).
  struct CreaseSides {
    const Piece& piece;
    const IdMap<int>& sides;  // the sheet's decided vertices
  };
  std::vector<CutFacePair> crease_faces(const CreaseSides& prev, const CreaseSides& next, const Vec3& fa, const Vec3& fb,
                                        std::span<const TetId> around) const;
  // Live candidate tets (where the next step's walk starts, and the improvement seeds).
  std::vector<TetId> live_candidates() const;
  // Adds tets to the candidates (a sheet's waiting tets and closed cut faces).
  void add_candidates(std::span<const TetId> tets);

  // Vertices on a piece's boundary (the blade front and the cut's rim): improvement keeps them.
  const std::vector<VertexId>& boundary_vertices() const { return boundary_vertices_; }
  std::size_t tets_cut() const { return destroyed_.size(); }
  // A segment already made of mesh edges (the previous step's front): pieces with it as a
  // boundary segment reuse its vertices instead of embedding it again.
  void add_known_segment(const Vec3& a, const Vec3& b, std::vector<VertexId> vertices);
  // Vertices on an embedded boundary segment (e.g. this step's front).
  std::vector<VertexId> segment_vertices(const Vec3& a, const Vec3& b) const;
  // Those of `vertices` that are alive and on the segment (a, b): a list of a segment's
  // vertices kept across steps may name ids the mesh has given to other vertices since.
  std::vector<VertexId> on_segment(std::span<const VertexId> vertices, const Vec3& a, const Vec3& b) const;
  // Current positions of the vertices this step created.
  const IdMap<Vec3>& created_positions() const { return created_pos_; }
  // Records the current position of a vertex created outside (duplicates).
  void set_position(VertexId v, const Vec3& x) { created_pos_[v.idx()] = x; }

private:
  // split_crossings()'s parts (cut_step.cpp).
  struct EdgeSplit {
    VertexId a, b;
    double s;
  };
  void pin_flattened(const Piece& piece, IdSet& pinned);
  bool collect_crossings(const Piece& piece, IdSet& pinned,
                         std::map<std::pair<std::uint32_t, std::uint32_t>, EdgeSplit>& edges);
  bool section_inside(const Piece& piece, TetId t);
  // embed_boundary()'s parts (cut_step.cpp): vertex -> the piece's boundary segments it lies on
  // (bit i: segment i).
  using SegmentMarks = IdMap<std::uint32_t>;
  void mark_on_segments(SegmentMarks& marks, VertexId v, std::uint32_t segments);
  std::vector<bool> reuse_known_segments(const Piece& piece, SegmentMarks& marks);
  void embed_corners(const Piece& piece, const std::vector<bool>& known, SegmentMarks& marks);
  void embed_segment(const Piece& piece, std::size_t si, SegmentMarks& marks);
  int side(const Piece& piece, std::size_t piece_index, VertexId v);
  double snap_length(VertexId v);
  // Moves a snapped vertex onto the piece's plane (cut/snap_move.h); false where it may not.
  bool move_snapped(const Piece& piece, std::size_t k, VertexId v);
  // Whether x lies within `reach` of the crease front (set_crease_front), beside the segment.
  bool near_crease_front(const Vec3& x, double reach) const;
  // Whether v is on the boundary and every other vertex of its boundary faces lies beyond the
  // snap distance on one side of the piece's plane (the plane would only touch the surface at v).
  bool touches_surface_only(const Piece& piece, VertexId v);
  double vertex_radius(VertexId v);
  double star_radius(VertexId v) const;  // longest edge at v
  bool on_segment(VertexId v, const Vec3& a, const Vec3& b) const;
  double mean_incident_edge(VertexId v) const;
  bool edge_split_ok(VertexId a, VertexId b, double s) const;
  // edge_split_ok() for collect_crossings(), which asks it once per tet around each crossing
  // edge: an answer holds while the mesh is not edited (the same edge, split at the same point).
  bool edge_split_ok_cached(VertexId a, VertexId b, double s);
  struct SplitAnswer {
    double s;
    bool ok;
  };
  std::unordered_map<std::uint64_t, SplitAnswer> split_ok_;
  std::uint64_t split_ok_edits_ = ~std::uint64_t(0);
  // Inserts the point with barycentric w in t, snapping small weights to zero; returns the
  // vertex now at that point (existing or new).
  VertexId insert_point(TetId t, std::array<double, 4> w);
  // A face point (three weights) a hair from one of its face's edges (kEdgeSnap) is put on that
  // edge: kept in the face, the boundary segment crossing the next face a hair beyond the edge and
  // the sheet crossing the edge itself made three vertices a thousandth of an edge apart, and
  // flat tets between them that no operation could take once the cut was open.
  void on_nearby_edge(TetId t, std::array<double, 4>& w, int& nz) const;
  // insert_point()'s parts: the vertex within its snap radius of the point, if any (else the
  // radius the new vertex will get); the point put on an edge, a face or inside t (nullopt
  // where a child would be flat).
  std::optional<VertexId> snap_to_vertex(TetId t, const std::array<double, 4>& w);
  std::optional<VertexId> split_on_edge(TetId t, const std::array<double, 4>& w);
  std::optional<VertexId> split_on_face(TetId t, const std::array<double, 4>& w);
  std::optional<VertexId> split_in_tet(TetId t, const std::array<double, 4>& w);
  void note_destroyed(TetId t);
  void note_new_vertex(VertexId p);
  std::array<Vec3, 4> tet_positions(TetId t) const;

  TetMesh& mesh_;
  PositionFn positions_;
  double snap_;
  CutMemory* memory_;
  bool provisional_;
  bool no_moves_ = false;
  void decide(std::size_t k, VertexId v, int s);
  IdSet fixed_;
  std::optional<std::array<Vec3, 2>> crease_front_;
  std::vector<TetId> cand_;
  IdSet in_cand_;
  IdMap<Vec3> created_pos_;
  IdMap<double> snap_len_;
  IdMap<double> radius_;  // snap radius of vertices made this step
  double pending_radius_ = 0;
  IdSet born_, destroyed_;
  // Per piece: vertices created on it (exactly on it by construction) and cached sides.
  std::vector<IdSet> on_piece_;
  std::vector<IdMap<int>> side_cache_;
  // Vertices side() found undecided, with the mesh's edit count then: the answer depends on
  // the vertex's position and its star only, so it holds until the mesh is edited (a split
  // or a snap move); side() is asked about each vertex once per tet around it.
  std::vector<IdMap<std::uint64_t>> undecided_;
  std::size_t current_piece_ = 0;
  std::vector<VertexId> boundary_vertices_;
  struct EmbeddedSegment {
    Vec3 a, b;
    std::vector<VertexId> vertices;
  };
  std::vector<EmbeddedSegment> embedded_;
};

}  // namespace incise::cut_detail
