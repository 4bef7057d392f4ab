#pragma once
// FemModel: linear and corotational constant-strain tetrahedra on a TetMesh, and the
// matrix-free stiffness product K x driven by vertex -> incident-tet incidence.
//
// Unknowns are displacements indexed by VertexId: 3 * vertex_slots() doubles, (x,y,z) of vertex
// v at 3v..3v+2. vertex_slots() >= mesh.vertex_capacity() grows geometrically, so that edits
// adding vertices do not resize every vector each time; slots of dead vertices, of vertices
// without tets and beyond the mesh's capacity have zero rows and diagonal.
// Per-tet data (shape gradients, rest volume, Lame parameters, rotation) lives in arrays indexed
// by TetId that grow with tet_capacity(); dead slots are skipped. apply(change) recomputes only
// what a TopologyChange names (the added tets, the touched vertices' diagonal and mass).
//
// K x is matrix-free, colour by colour over slabs of tets (sim/fem/stiffness_kernel.h); the
// mesh must outlive the model and every edit batch must be fed to apply() before the next
// product. Corotational rotations, the NodalAveraged volumetric rows (nodal_b()) and the
// EdgeSmoothed edge table, with their equations and what apply() keeps local:
// docs/solver.md#the-model-in-equations.
#include <cstdint>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "mesh/tet_mesh.h"
#include "sim/linalg/linear_operator.h"
#include "sim/fem/edge_tet_lists.h"
#include "sim/fem/formulation.h"
#include "sim/fem/inversion_barrier.h"
#include "sim/material.h"
#include "sim/fem/rotation_extraction.h"
#include "sim/fem/stiffness_kernel.h"

namespace incise {

enum class FemKind { Linear, Corotational };

// Block (i, j) (3x3) of a constant-strain tet's stiffness matrix: rest inverse edge matrix bm,
// volume, Lame parameters, rotation r (identity for linear).
Eigen::Matrix3d element_block(const Eigen::Matrix3d& bm, double vol, double mu, double lambda, const Eigen::Matrix3d& r,
                              int i, int j);

// A copy of the per-tet data K depends on (by TetId, dead slots flagged), for work done off
// the frame thread, such as a background factorization. Taking it copies the arrays (the
// rotations rebuilt from their quaternions; NodalAveraged: also builds B, O(mesh), parallel).
struct FemElements {
  std::vector<std::uint8_t> alive;
  std::vector<std::array<std::uint32_t, 4>> verts;
  std::vector<Eigen::Matrix3d> bm, rot;
  std::vector<double> vol, mu, lambda;  // lambda: -2 mu / 3 for NodalAveraged (deviatoric blocks)
  // NodalAveraged: B (rows: vertex slots, columns: unknowns) with K = sum of blocks + B^T B;
  // edge-smoothed: the smoothed rows follow and the blocks are zero (mu = lambda = 0); empty
  // (0 x 0) for Standard.
  Eigen::SparseMatrix<double, Eigen::RowMajor> nodal_b;
  Eigen::Matrix3d block(std::size_t t, int i, int j) const {
    return element_block(bm[t], vol[t], mu[t], lambda[t], rot[t], i, j);
  }
};

// Work done by local updates (counted, not timed, so tests can check locality).
// The last update_rotations(): how many tets it refreshed and how many of them needed the exact
// decomposition (the warm-started iteration did not converge, or the exact path was chosen).
struct RotationStats {
  std::size_t tets = 0, exact = 0;
  int max_steps = 0;  // Newton steps of the slowest packet
};

struct FemWork {
  std::uint64_t updates = 0;           // apply() calls
  std::uint64_t tets_recomputed = 0;   // per-tet precomputations
  std::uint64_t vertices_updated = 0;  // diagonal / mass entries recomputed
  // Diagonal blocks recomputed besides those (NodalAveraged: the touched vertices' 1-ring,
  // whose volumetric block reads the touched vertices' V_a).
  std::uint64_t blocks_updated = 0;
  std::uint64_t edges_updated = 0;  // EdgeSmoothed: smoothing domains whose tets changed
  // update_rotations_partial: the vertices whose diagonal blocks it refreshed, and (nodal-
  // averaged, its kept rotation rhs valid) those whose volumetric rhs it summed again.
  std::uint64_t rotation_blocks = 0;
  std::uint64_t rotation_rhs_sums = 0;
};

class FemModel : public LinearOperator {
public:
  // `smooth_edges`: the strain smoothed over edge domains with each tet's own law (as
  // EdgeSmoothed does for the deviatoric part; the mixed solver's displacement block with
  // lambda = 0). EdgeSmoothed implies it.
  // O(mesh). Throws InvalidArgument for a bad material, or for Formulation::Mixed (not a
  // displacement-only model), and InvalidMesh for a degenerate tet.
  FemModel(const TetMesh& mesh, const MaterialTable& materials, FemKind kind = FemKind::Linear,
           Formulation formulation = Formulation::Standard, bool smooth_edges = false);
  // The model keeps a pointer to its mesh (local updates read it): a temporary would dangle.
  FemModel(TetMesh&&, const MaterialTable&, FemKind = FemKind::Linear, Formulation = Formulation::Standard,
           bool = false) = delete;

  FemKind kind() const { return kind_; }
  Formulation formulation() const { return formulation_; }
  // The volumetric strain averaged at the vertices (NodalAveraged and EdgeSmoothed).
  bool nodal_averaged() const {
    return formulation_ == Formulation::NodalAveraged || formulation_ == Formulation::EdgeSmoothed;
  }
  bool edge_smoothed() const { return smooth_; }
  // Vertex v's pressure per unit of the divergence sum `s` = sum over its tets of V_t div_t.
  double nodal_pressure(std::size_t v, double s) const {
    return nvol_[v] > 0 ? nkv_[v] * (s / 4) / (nvol_[v] * nvol_[v]) : 0.0;
  }
  // EdgeSmoothed: edges (smoothing domains) in the table; 0 otherwise.
  std::size_t num_edges() const { return edge_index_.size(); }
  const TetMesh& mesh() const { return *mesh_; }
  const MaterialTable& materials() const { return materials_; }
  std::size_t num_dofs() const { return 3 * vertex_capacity_; }
  std::size_t vertex_slots() const { return vertex_capacity_; }

  // Local update after an edit batch: O(size of the change).
  void apply(const TopologyChange& change);
  const FemWork& work() const { return work_; }
  void reset_work() { work_ = {}; }

  // ---- LinearOperator: y = K x (K_R for corotational), parallel --------------------
  Eigen::Index rows() const override { return Eigen::Index(num_dofs()); }
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const override;
  // The matrix-free kernel's AVX2 path (default where the CPU has it); off: the portable
  // path other CPUs run (benchmarks compare the two).
  void set_kernel_simd(bool on) { kernel_.set_simd(on); }
  const Eigen::VectorXd& diagonal() const override { return diag_; }
  // Per vertex: the 3x3 diagonal block of K (K_R), kept current with the diagonal.
  const std::vector<Eigen::Matrix3d>& diagonal_blocks() const override { return blocks_; }

  // Lumped mass per unknown (density * V / 4 per tet corner, repeated on x,y,z).
  const Eigen::VectorXd& lumped_mass() const { return mass_; }

  // Corotational: the inversion barrier (sim/fem/inversion_barrier.h; j_min 0: off, the default).
  // Its held tets are chosen at each update_rotations(); apply() drops them until the next.
  void set_inversion_barrier(const InversionBarrierOptions& o) { barrier_.set_options(o); }
  const InversionBarrier& inversion_barrier() const { return barrier_; }

  // Corotational: per-tet rotations from displacement u (O(mesh), parallel); also refreshes
  // the diagonal. No-op for Linear.
  void update_rotations(const Eigen::VectorXd& u);
  // The same for a share of the tets only: the packets [first, first + count) (modulo
  // rotation_packets(); kLanes = 8 consecutive tet ids each), and the diagonal blocks of their
  // vertices. Calls with consecutive ranges refresh every tet in turn (a budgeted frame that
  // cannot afford all of them: FemSimulation). After a whole cycle at a fixed u the model
  // equals a full update's.
  void update_rotations_partial(const Eigen::VectorXd& u, std::size_t first, std::size_t count);
  std::size_t rotation_packets() const;
  // Off: every tet's rotation from scratch (polar_rotation), the path before warm starts
  // (benchmarks and tests compare the two).
  void set_warm_started_rotations(bool on) { warm_rotations_ = on; }
  void set_rotation_refinement(const RotationRefinement& r) { refinement_ = r; }
  const RotationStats& rotation_stats() const { return rotation_stats_; }
  // b_R = sum_t V R sigma(sym(I - R^T)) g: the right-hand side term of the linearized
  // corotational force (zero for Linear). Adds into b: O(vertices), it is summed by
  // update_rotations (and apply()) with the diagonal.
  void add_rotation_rhs(Eigen::VectorXd& b) const;
  // f_int(u) with the current rotations (call update_rotations(u) first for corotational).
  void internal_forces(const Eigen::VectorXd& u, Eigen::VectorXd& f) const;
  // Von Mises stress per tet (by TetId; dead slots 0) for displacement u (corotational: each
  // tet's rotation from u, exactly; the model's stored rotations are left as they are).
  // NodalAveraged: the deviatoric stress plus the tet's averaged pressure (von Mises does not
  // see the pressure, so it is the deviatoric stress's).
  std::vector<double> von_mises(const Eigen::VectorXd& u) const;
  // Mean stress tr(sigma) / 3 per tet (by TetId): kappa tr(eps) for Standard, the mean of its
  // vertices' kappa_a theta_a for NodalAveraged.
  std::vector<double> pressure(const Eigen::VectorXd& u) const;

  // The assembled K (K_R) as a sparse matrix of num_dofs() rows; O(mesh). The assembled
  // backend and the direct solver use it.
  // NodalAveraged: K_dev + B^T B, the 2-ring pattern.
  Eigen::SparseMatrix<double> assemble() const;
  FemElements elements() const;
  // NodalAveraged: B of K = K_dev + B^T B (one row per vertex slot, see above); O(mesh).
  // Edge-smoothed: the vertex rows (if nodal-averaged), then the smoothed rows; K = B^T B.
  Eigen::SparseMatrix<double, Eigen::RowMajor> nodal_b() const;
  // Row a of B as (vertex w, 3 entries) pairs, one per vertex of a's 1-ring (a itself
  // included); empty for a vertex without tets or for Standard. O(incident tets).
  void nodal_b_row(std::uint32_t a, std::vector<std::pair<std::uint32_t, Eigen::Vector3d>>& row) const;
  // Per vertex: V_a and kappa_a V_a (NodalAveraged; zero otherwise).
  double nodal_volume(VertexId v) const { return v.idx() < nvol_.size() ? nvol_[v.idx()] : 0.0; }
  double nodal_kappa_volume(VertexId v) const { return v.idx() < nkv_.size() ? nkv_[v.idx()] : 0.0; }

  // Per-tet access (tests, benchmarks).
  bool tet_alive(TetId t) const { return t.idx() < alive_.size() && alive_[t.idx()]; }
  double tet_volume(TetId t) const { return vol_[t.idx()]; }
  Eigen::Matrix3d rotation(TetId t) const { return quat_[t.idx()].toRotationMatrix(); }
  // What a tet's element matrix is made of, without the copy elements() takes: a coarse
  // operator assembled per frame (sim/fem/aggregation_amg.h) reads these in place.
  const std::array<std::uint32_t, 4>& tet_vertex_ids(TetId t) const { return verts_[t.idx()]; }
  const Eigen::Matrix3d& tet_shape_matrix(TetId t) const { return bm_[t.idx()]; }  // row j-1: grad N_j
  double tet_mu(TetId t) const { return mu_[t.idx()]; }
  double tet_lambda(TetId t) const { return lambda_[t.idx()]; }  // -2 mu / 3 for NodalAveraged
  double tet_kappa(TetId t) const { return kappa_[t.idx()]; }    // bulk modulus lambda + 2 mu / 3
  const Eigen::Quaterniond& tet_quaternion(TetId t) const { return quat_[t.idx()]; }

private:
  void grow();
  void compute_tet(std::uint32_t t);
  void compute_vertex(std::uint32_t v);  // corner slots, mass, diagonal from incident tets
  void vertex_block(std::uint32_t v);    // the diagonal block and b_R from its tets' rotations
  void smoothed_product(const Eigen::VectorXd& x, Eigen::VectorXd& y) const;
  void update_rotations_exact(const Eigen::VectorXd& u);
  void update_rotations_warm(const Eigen::VectorXd& u);
  void relinearize(const Eigen::VectorXd& u, bool exact);  // every tet, in the kernel's order
  void update_rotation_packets(const Eigen::VectorXd& u, bool exact, std::size_t begin, std::size_t end);
  Eigen::Matrix3d tet_stress(std::uint32_t t, const Eigen::VectorXd& x, bool subtract_rotation,
                             const Eigen::Matrix3d& r) const;  // r: the tet's rotation
  void gather(Eigen::VectorXd& y, bool accumulate) const;
  // The forces of vertex vi's corners summed in slot order (gather's and the kept rhs's sum).
  Eigen::Vector3d corner_sum(const std::vector<Eigen::Matrix<double, 3, 4>>& forces, std::size_t vi) const;
  // Columns j = 1..3: sign V_t p R_t grad N_j (corner 0: minus their sum), p a tet's mean pressure.
  Eigen::Matrix3d volumetric_corner_block(std::size_t ti, double p, double sign) const;
  void nodal_volume_of(std::uint32_t v);     // nvol_, nkv_ from the incident tets
  void refresh_ring(const TopologyChange& change);  // diagonal blocks of the touched 1-ring
  void volumetric_block(std::uint32_t v, Eigen::Matrix3d& blk) const;  // adds B^T B's block (v, v)
  // EdgeSmoothed: the smoothed deviatoric part's block (v, v) at rest, into sblock_[v], and
  // rotated by v's rotation (the mean of its tets') into blk, which it overwrites.
  void smoothed_rest_block(std::uint32_t v);
  void smoothed_block(std::uint32_t v, Eigen::Matrix3d& blk) const;
  void volume_gradients(std::uint32_t t);  // vgrad_ of a tet from its rotation
  void build_ring(std::uint32_t v);        // ring_, ring_at_ from the vertex's corner slots
  // The nodal-averaged volumetric term in three passes. Per tet div_t: of x (R^T H_t(x) traced)
  // when x is given, plus tr(R_t) - 3 (the rotation's own volumetric strain) when `rotation`.
  // Leaves per tet pbar_t in pbar_ and adds the corner forces sign V_t pbar_t R_t grad N_j
  // into *y when y is given.
  void volumetric_pass(const Eigen::VectorXd* x, bool rotation, double sign, Eigen::VectorXd* y) const;
  // The same pass for the rotations' own strain (add_rotation_rhs), kept per vertex in vrhs_:
  // computed in full when stale (after a full relinearization or an edit), then refreshed
  // where a partial relinearization changed rotations (refresh_rotation_volumetric), so that a
  // budgeted frame's right-hand side is not O(mesh). The same operations in the same order as
  // volumetric_pass, so the sums are the same bit for bit.
  void rotation_volumetric_rhs(Eigen::VectorXd& b) const;
  void refresh_rotation_volumetric(const std::vector<std::uint32_t>& tets, const std::vector<std::uint32_t>& verts);
  void rotation_corner_forces(std::size_t ti) const;  // rforce_ of a tet from rtheta_
  void rotation_vertex_sum(std::size_t vi) const;     // vrhs_ of a vertex from rforce_
  // EdgeSmoothed: the deviatoric term in three passes (see the header comment), with the stored
  // rotations or `rot` (per tet, by TetId). Per tet (V_t / 6) eps_t of x when x is given, plus
  // sym(R^T - I) when `rotation`; per edge sigma_e; per tet sigma_bar_t (left in tsig_) and the
  // corner forces sign V_t R_t sigma_bar_t grad N_j, added into *y when given.
  void deviatoric_pass(const Eigen::VectorXd* x, bool rotation, double sign, Eigen::VectorXd* y,
                       const std::vector<Eigen::Matrix3d>* rot = nullptr) const;
  void register_tet(std::uint32_t t);    // the tet into its six edges' lists
  void unregister_tet(std::uint32_t t);  // and out
  void edge_moduli(std::uint32_t e);     // V_e and the volume-weighted mu, lambda
  // C with K_smoothed = C^T C, up to 7 rows per edge (nodal_b() stacks it under the vertex rows).
  Eigen::SparseMatrix<double> smoothed_rows() const;

  const TetMesh* mesh_;
  MaterialTable materials_;
  FemKind kind_;
  Formulation formulation_;
  bool smooth_;  // edge_smoothed()
  std::size_t vertex_capacity_ = 0, tet_capacity_ = 0;

  // Per tet (by TetId).
  std::vector<std::uint8_t> alive_;
  std::vector<std::array<std::uint32_t, 4>> verts_;
  std::vector<Eigen::Matrix3d> bm_;   // inverse rest edge matrix: row j-1 is grad N_j (j=1..3)
  std::vector<double> vol_, mu_, lambda_, rho_;
  std::vector<double> kappa_;  // bulk modulus; lambda_ is then the deviatoric element's -2 mu / 3
  // R as a unit quaternion (identity for Linear): 32 bytes a tet to write each frame instead of
  // 72, the next frame's start; the passes that need R rebuild it (a few flops).
  std::vector<Eigen::Quaterniond> quat_;
  bool warm_rotations_ = true;
  RotationRefinement refinement_;
  RotationStats rotation_stats_;
  mutable std::vector<Eigen::Matrix<double, 3, 4>> force_;  // pass-1 scratch: per-corner force

  // The product's own copy of the per-tet data, coloured for a conflict-free scatter.
  StiffnessKernel kernel_;

  // Per vertex: its incident corners as slots 4 * tet + local, so the gather pass reads only
  // the per-corner forces and vertex_block() its corners (one indirection, no local-index
  // search). Rebuilt with the vertex.
  std::vector<std::vector<std::uint32_t>> corner_slots_;

  // Per unknown.
  Eigen::VectorXd diag_, mass_;
  std::vector<Eigen::Matrix3d> blocks_;  // per vertex
  std::vector<Eigen::Matrix3d> sblock_;  // EdgeSmoothed, per vertex: the smoothed block at rest
  std::vector<double> iso_;              // per vertex: sum of V mu |grad N|^2 over its corners
  Eigen::VectorXd rhs_;  // b_R, summed per vertex with the diagonal blocks (deviatoric part)
  // NodalAveraged, per vertex: V_a and kappa_a V_a; scratch of the volumetric passes.
  std::vector<double> nvol_, nkv_;
  mutable std::vector<double> div_, pbar_;  // per tet
  // Per corner (slot 4 t + j): (V_t / 4) R_t grad N_j, the terms the volumetric blocks and B's rows
  // sum (each tet's four once per relinearization, not once per vertex of its 2-ring).
  std::vector<Eigen::Vector3d> vgrad_;
  // Per vertex: the vertices of its star (ring_), and per corner slot the positions in ring_ of
  // the slot's tet's four vertices (ring_at_, four a slot): the volumetric block sums each
  // corner's gradient by position, with no lookup by vertex id. Rebuilt with the corner slots.
  std::vector<std::vector<std::uint32_t>> ring_;
  std::vector<std::vector<std::uint16_t>> ring_at_;
  std::vector<std::uint8_t> vertex_mark_;    // update_rotations_partial: vertices already listed
  mutable std::vector<double> ptheta_;      // per vertex: kappa_a theta_a
  // rotation_volumetric_rhs's state: per tet tr(R) - 3 and the corner forces, per vertex
  // kappa_a theta_a and the summed force (vrhs_, 3 a vertex); valid until the next full
  // relinearization or edit.
  mutable std::vector<double> rdiv_, rtheta_;
  mutable std::vector<Eigen::Matrix<double, 3, 4>> rforce_;
  mutable Eigen::VectorXd vrhs_;
  mutable bool vrhs_valid_ = false;
  std::vector<std::uint8_t> tet_mark_;  // refresh_rotation_volumetric: tets already listed
  std::vector<std::uint8_t> ring_mark_;     // per vertex, all clear between apply() calls
  // EdgeSmoothed: the edges. Ids are reused (free list); an edge lives while a tet holds it.
  std::unordered_map<std::uint64_t, std::uint32_t> edge_index_;  // (min, max) vertex ids -> edge
  EdgeTetLists edge_tets_;                                       // per edge: its tets
  std::vector<double> edge_vol_, edge_mu_, edge_lambda_;         // per edge
  std::vector<std::uint32_t> free_edges_;
  std::vector<std::array<std::uint32_t, 6>> tet_edges_;  // per tet
  std::vector<std::uint8_t> registered_;                 // per tet: in its edges' lists
  mutable std::vector<Eigen::Matrix3d> teps_, esig_, tsig_;  // per tet, per edge, per tet
  // The fused edge-smoothed product's symmetric tensors (xx, yy, zz, xy, xz, yz): per tet
  // (V/6) eps_t, per edge sigma_e, per tet sigma_bar_t.
  mutable std::vector<double> tsym_, esym_, tbar_;
  InversionBarrier barrier_;
  FemWork work_;
};

// Grows `field` (3 per vertex) to at least `vertex_slots` vertices and gives each added vertex
// the weighted combination of its parents' values; removed vertices get 0. O(size of the
// change) when no growth is needed (pass FemModel::vertex_slots()).
void interpolate_added_vertices(const TopologyChange& change, std::size_t vertex_slots, Eigen::VectorXd& field);

// Von Mises equivalent of a symmetric stress tensor.
double von_mises_of(const Eigen::Matrix3d& s);

}  // namespace incise
