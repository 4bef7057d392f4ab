#pragma once
// SpringModel: the dynamic mass-spring backend, built from a TetMesh and kept in step with it
// through TopologyChange records (local updates, no rebuild).
//
//   m_i a_i = -gamma_i v_i + sum_j g_ij + sum_t h_ti + m_i g + f_i
//
//  - g_ij: a Hookean spring on every mesh edge, rest length = rest edge length,
//    g_ij = k_ij (l_ij - |x_i - x_j|) (x_i - x_j) / |x_i - x_j|.
//    With SpringOptions::across_faces (default), also a spring between the two apexes of every
//    interior face (the vertices the face's two tets do not share), with part of the tets'
//    stiffness.
//  - h_ti: volume terms (SpringOptions::volume_term) that carry the bulk stiffness edge
//    springs cannot: by default most of it averaged at the vertices (nodal_volume,
//    nodal_share), the rest a per-tet barrier that keeps every tet from collapsing and
//    inverting. docs/solver.md#springs-which-configuration-to-pick says why this default.
//  - m_i: lumped mass, each tet's density * rest volume split equally to its 4 vertices.
//  - gamma_i = damping * m_i (mass-proportional damping; `damping` in 1/s).
//  - Stiffness from E and nu by calibrate_springs() (see there for the rule and its source).
// State (positions, velocities) is indexed by VertexId; slots of dead vertices are
// unspecified. Vertices without tets (left isolated by TetMesh::remove_tet) have no mass and
// are frozen. A step costs O(springs + tets); apply() costs O(size of the change).
// TetMesh::compact() renumbers ids: build a new model after it.
#include <array>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <unordered_map>
#include <vector>

#include "mesh/change_follower.h"
#include "mesh/tet_mesh.h"
#include "mesh/topology_change.h"
#include "sim/springs/integrator.h"
#include "sim/material.h"
#include "sim/springs/spring_fit.h"

namespace incise {

// How a spring's constant is set: VanGelder: calibrate_springs()'s isotropic rule (below);
// Fitted: per tet, the constants closest to that tet's FEM stiffness (sim/springs/spring_fit.h),
// summed over the edge's tets. docs/solver.md#spring-stiffness compares them.
enum class SpringStiffness { VanGelder, Fitted };
inline constexpr const char* kSpringStiffnessNames = "van-gelder or fitted";
inline std::optional<SpringStiffness> parse_spring_stiffness(std::string_view s) {
  if (s == "van-gelder") return SpringStiffness::VanGelder;
  if (s == "fitted") return SpringStiffness::Fitted;
  return std::nullopt;
}

struct SpringOptions {
  SpringStiffness stiffness = SpringStiffness::VanGelder;
  // Mass-proportional damping c [1/s]: gamma_i = c * m_i, so every particle's velocity decays
  // at the same rate whatever the mesh resolution. 0 = undamped.
  double damping = 0.0;
  // Per-tet volume barrier W = kappa V0 (J - 1 - ln J), J = V / V0. Without it a tet can be
  // pushed through one of its faces and stay inverted at zero spring energy (reflection keeps
  // every edge length), and nu > 1/4 cannot be represented. Chosen over altitude springs
  // (vertex to opposite face, Cooper & Maddock 1997): one term per tet instead of four, no
  // degenerate case when a vertex projects outside its face, its linearization is exactly
  // the FEM lambda term (so it carries the bulk stiffness), and its energy is unbounded as
  // J -> 0, whereas any quadratic penalty (altitude or volume) resists with a finite force
  // that a large enough load overcomes.
  bool volume_term = true;
  // The volume term averaged at the vertices instead of per tet (as nodal-averaged FEM does
  // with its volumetric strain, sim/fem/fem_model.h): vertex a's volume ratio J_a = V_a / V0_a with
  // V_a = sum over its tets of V_t / 4, energy sum_a kappa_a V0_a (J_a - 1 - ln J_a), kappa_a
  // the volume-weighted kappa of its tets. Per tet, a near-incompressible body locks as
  // standard tets do (docs/solver.md#spring-volume-terms). Computed from the per-tet volumes
  // each step (one more pass), so edits stay local.
  bool nodal_volume = true;
  // With nodal_volume: the share of kappa averaged at the vertices; the rest, 1 - nodal_share,
  // stays in a per-tet barrier beside it (a blend, as stabilized nodal-pressure tets blend the
  // element's own volume change into the averaged one). 1: the nodal term alone. The per-tet
  // part keeps every tet from inversion (the nodal one only its vertices' stars) and stiffens
  // the spurious soft modes that nodal averaging leaves on coarse meshes; below 1 it also
  // brings back part of the locking. docs/solver.md#spring-volume-terms measures the share.
  double nodal_share = 0.9;
  // A per-tet guard beside the volume terms: each tet whose volume ratio J fell below
  // inversion_guard = j gets the energy kappa V0 j (J/j - 1 - ln(J/j)) (the barrier's shape,
  // moved to J = j), and none above it. At rest and under moderate strain it adds nothing, so
  // unlike the per-tet part of a blend it does not stiffen the small tets a cut makes; as
  // J -> 0 its energy grows without bound, so no tet is pushed through a face, which the nodal
  // term alone (it holds only each vertex's whole star) does not ensure. 0: none.
  // docs/solver.md#spring-volume-terms.
  double inversion_guard = 0;
  // Connectivity: besides the mesh's edges, a spring across every interior face, joining the
  // two apexes of its tets (Van Gelder's stiffness only). The edges of a lattice mesh (six tets
  // per cube) point along few directions, so the network is anisotropic: too stiff in tension
  // and too soft in shear whatever the resolution; springs across the faces add the missing
  // directions. Each tet's stiffness budget (c V_t, which calibrate_springs() sets) is shared:
  // face_share of it, a quarter per interior face, goes to the springs across its faces, the
  // rest to its six edges (a boundary face's quarter stays with the edges).
  // docs/solver.md#spring-connectivity measures both connectivities and the share.
  bool across_faces = true;
  double face_share = 0.65;
  // Kelvin-Voigt damping in every spring: a force c (v_rel . n) along it against its rate of
  // extension, c = viscosity x k (viscosity: a time constant [s]); 0: none. A material's own
  // `viscosity` (> 0) replaces it in its tets, and a spring takes its tets' mean; likewise
  // `stiffening`. Unlike `damping`
  // it leaves a rigid motion alone and damps the fast modes most (docs/solver.md#spring-options).
  double viscosity = 0;
  // Strain-stiffening springs (Fung's exponential law): tension k l0 (exp(b e) - 1) / b at the
  // strain e = (l - l0) / l0, tangent stiffness k exp(b e), b = stiffening; 0: Hookean.
  double stiffening = 0;
  // Floor of kappa / mu_s when nu < 1/4 (where the exact value lambda - mu would be negative):
  // keeps some barrier; the network then has Poisson's ratio (1 + r) / (2 (2 + r)).
  double min_volume_ratio = 0.1;
  // Below J = barrier_limit the barrier continues as its quadratic Taylor expansion, so a
  // step that overshoots past J = 0 gets a large finite restoring force instead of NaN.
  double barrier_limit = 0.01;
  // Implicit Euler: CG tolerance relative to the right-hand side and iteration cap.
  double cg_tolerance = 1e-8;
  int cg_max_iterations = 1000;
  // StepStats energies (one extra O(springs + tets) pass per step when true).
  bool compute_energy = true;
};

// The calibration rule for one material. Van Gelder (1998, "Approximate simulation of elastic
// membranes by triangulated spring meshes", J. Graphics Tools 3(2)) sets
// k_e = E * sum_{t contains e} V_t / l_e^2. Averaged over an isotropic distribution of edge
// directions a central-force network has energy density S/30 ((tr eps)^2 + 2 eps:eps) with
// S = sum_e k_e l_e^2 / V, i.e. lambda = mu = S/15 (the Cauchy relation: nu = 1/4 exactly), and
// Van Gelder's rule gives S = 6E, hence exactly E at nu = 1/4. We keep the rule with modulus
// c = 2.5 mu_s (k_e = sum_t c_t V_t / l_e^2) so the springs carry the shear modulus
// mu_s, and put the rest of lambda into the volume barrier, whose linearization is
// 0.5 kappa (tr eps)^2: kappa = lambda - mu. Then E and nu are both reproduced for
// nu >= 1/4. For nu < 1/4, kappa = r mu_s with r = min_volume_ratio and mu_s chosen so E is
// still exact (nu is then (1+r)/(2(2+r))). Without the volume term: c = E (Van Gelder), nu = 1/4.
// Real meshes are not isotropic; tests/sim/test_springs.cpp measures the uniaxial error.
struct SpringCalibration {
  double spring_modulus = 0;     // c [Pa] in k_e = sum_t c_t V_t / l_e^2
  double volume_modulus = 0;     // kappa [Pa] of the volume barrier (0 without it)
  double effective_poisson = 0;  // nu the (isotropic) network reproduces
};
SpringCalibration calibrate_springs(const Material& material, const SpringOptions& options);

// The connectivity a caller gets when it names none: SpringOptions' (across faces), except with
// fitted constants, which are per edge. The scene parser and the Python module both ask here.
inline bool default_across_faces(SpringStiffness stiffness) {
  return stiffness == SpringStiffness::VanGelder && SpringOptions{}.across_faces;
}

struct StepStats {
  double dt = 0;
  bool stable_step_exceeded = false;  // explicit integrator above stable_time_step(integrator)
  int cg_iterations = 0;              // implicit Euler only
  double cg_relative_residual = 0;    // implicit Euler only
  double kinetic_energy = 0;          // after the step
  // After the step: springs + volume barriers - work potential of gravity and external
  // forces (constant forces are conservative, so total energy is conserved without damping).
  double potential_energy = 0;
};

// Counters for the locality tests: entries visited by apply() (incident tets, springs, terms).
struct SpringUpdateCounters {
  std::uint64_t updates = 0;
  std::uint64_t visits = 0;
};

class SpringModel {
public:
  SpringModel(const TetMesh& mesh, const MaterialTable& materials, const SpringOptions& options = {});

  // Consumes one TopologyChange of `mesh` (already applied to it): updates the springs, volume
  // terms, masses and stability bounds it touches and adds state for new vertices: position
  // and velocity interpolated from the parents with the change's weights. A new vertex is
  // fixed when all its parents are, prescribed (to the interpolated target) when all are.
  void apply(const TetMesh& mesh, const TopologyChange& change);

  void set_fixed(VertexId v, bool fixed);                 // fixed: never moves, zero velocity
  void set_prescribed(VertexId v, const Vec3& position);  // reaches `position` at the next step
  void clear_prescribed(VertexId v);
  void set_external_force(VertexId v, const Vec3& f);     // constant until changed [N]
  void set_gravity(const Vec3& g);                        // acceleration [m/s^2]
  void set_position(VertexId v, const Vec3& x);           // initial conditions
  void set_velocity(VertexId v, const Vec3& u);

  // Advances by dt. Explicit integrators above the stable step's bound still step and set
  // stable_step_exceeded; above the step estimated from the state (checked when the bound is
  // first exceeded) they also warn once on stderr ("incise: warn: ...").
  StepStats step(double dt, Integrator integrator);

  // Stable step of symplectic Euler and Verlet: the largest dt with w^2 dt^2 + 2 c dt < 4
  // (2/w_max without damping), w_max^2 bounded by Gershgorin's row sums of M^-1 K at rest,
  // kept per vertex and updated locally. The barrier stiffens compressed tets beyond it.
  double stable_time_step() const;
  // Per integrator: explicit Euler needs damping: dt < min(c / w_max^2, 2 / c) (0 when c = 0:
  // undamped, it gains energy at any step); implicit Euler returns infinity.
  double stable_time_step(Integrator integrator) const;
  double max_angular_frequency() const;  // the bound w_max [rad/s]
  // The same at the current state from an estimate of its fastest mode (Lanczos on the tangent
  // M^-1/2 K M^-1/2 over the free dofs, `iterations` products, the Ritz value's residual added
  // so it errs short; sim/springs/spring_stability.cpp). Gershgorin's bound above holds at
  // rest and costs nothing to keep, but it is loose, and a squeezed tet's barrier stiffens
  // past it; this one is tight and sees the state: O(iterations x (springs + tets)), for
  // reports (after a cut), not for every step. docs/solver.md#spring-stable-step.
  double estimated_max_angular_frequency(int iterations = 60);
  double estimated_stable_time_step(Integrator integrator = Integrator::SymplecticEuler, int iterations = 60);

  const std::vector<Vec3>& positions() const { return x_; }
  const std::vector<Vec3>& velocities() const { return v_; }
  double mass(VertexId v) const { return mass_[v.idx()]; }
  bool is_fixed(VertexId v) const { return fixed_[v.idx()] != 0; }
  std::size_t num_springs() const { return springs_.size(); }
  std::size_t num_volume_terms() const { return volumes_.size(); }
  const SpringOptions& options() const { return opt_; }

  struct SpringInfo {
    VertexId a, b;  // a < b
    double rest_length = 0;
    double stiffness = 0;  // [N/m]
    double viscosity = 0, stiffening = 0;  // Kelvin-Voigt time constant [s], stiffening exponent
    bool across_faces = false;             // a spring across faces (SpringOptions::across_faces)
  };
  std::optional<SpringInfo> spring(VertexId a, VertexId b) const;  // O(1): the edge's
  std::optional<SpringInfo> spring_across_faces(VertexId a, VertexId b) const;  // O(1)
  // O(springs), sorted by (a, b), an edge's before the one across faces between the same two.
  std::vector<SpringInfo> springs() const;
  struct VolumeInfo {
    TetId tet;
    double rest_volume = 0;
    double kappa = 0;
  };
  std::optional<VolumeInfo> volume_term(TetId t) const;  // O(1)

  double kinetic_energy() const;
  double potential_energy() const;

  const SpringUpdateCounters& counters() const { return counters_; }
  void reset_counters() { counters_ = {}; }

private:
  struct Spring {
    std::uint32_t a, b;
    double rest, k;
    double tau = 0, stiffening = 0;  // per spring: the volume-weighted mean of its tets' materials
    std::uint64_t key = 0;           // in spring_index_: edge_key, or face_key for one across faces
  };
  struct Volume {
    std::array<std::uint32_t, 4> v;
    double rest_volume, kappa;
    std::uint32_t tet;
  };
  static constexpr std::uint32_t kNone = 0xffffffffu;
  static std::uint64_t edge_key(std::uint32_t a, std::uint32_t b) {
    return a < b ? (std::uint64_t(a) << 32 | b) : (std::uint64_t(b) << 32 | a);
  }
  // A spring across faces between a and b (ids below 2^31): its own key beside an edge's.
  static constexpr std::uint64_t kFaceBit = std::uint64_t(1) << 63;
  static std::uint64_t face_key(std::uint32_t a, std::uint32_t b) { return edge_key(a, b) | kFaceBit; }

  void grow(std::size_t vertices, std::size_t tets);
  void grow_tree(std::size_t vertices);
  // A spring's material: the volume-weighted mean viscosity and stiffening of its tets (a
  // material's own value, else the options').
  struct SpringMix {
    double vol = 0, tau = 0, stiff = 0;
    void add(const Material& m, double v, const SpringOptions& o) {
      vol += v;
      tau += v * (m.viscosity > 0 ? m.viscosity : o.viscosity);
      stiff += v * (m.stiffening > 0 ? m.stiffening : o.stiffening);
    }
  };
  void store_spring(const Spring& sp);  // inserts or replaces the spring at sp.key
  void update_edge(const TetMesh& mesh, std::uint32_t a, std::uint32_t b);
  // across_faces: the spring between a and b from the interior faces whose apexes they are
  // (none: removed); the share of a tet's budget its edges keep.
  void update_face_pair(const TetMesh& mesh, std::uint32_t a, std::uint32_t b);
  double edge_share(const TetMesh& mesh, TetId t) const;
  // across_faces, per live tet and local face: the apex across that face (kNone on the
  // boundary) as the springs were last built, so apply() finds the springs of removed tets.
  std::vector<std::array<std::uint32_t, 4>> tet_partner_;
  std::uint32_t apex_across(const TetMesh& mesh, TetId t, int f) const;
  void remove_spring(std::uint64_t key);
  void add_volume(const TetMesh& mesh, TetId t);
  void remove_volume(TetId t);
  void update_mass(const TetMesh& mesh, std::uint32_t v);
  void update_bound(const TetMesh& mesh, std::uint32_t v);
  void set_bound(std::uint32_t v, double b);
  const SpringCalibration& calibration(int label) const;
  bool active(std::uint32_t i) const { return alive_[i] && mass_[i] > 0; }
  // The shares of each tet's kappa in its own barrier and in its vertices' nodal terms.
  double tet_part() const { return opt_.nodal_volume ? 1.0 - opt_.nodal_share : 1.0; }
  double nodal_part() const { return opt_.nodal_volume ? opt_.nodal_share : 0.0; }
  bool free_dof(std::uint32_t i) const { return active(i) && !fixed_[i] && !prescribed_[i]; }
  void invalidate() { acc_valid_ = false; }

  // Forces at (x, v) into f (sized like x_).
  void compute_forces(const std::vector<Vec3>& x, const std::vector<Vec3>& v, std::vector<Vec3>& f) const;
  void finish_constraints(double dt);
  std::array<Vec3, 4> volume_gradient_of(const Volume& vol) const;  // dV/dx_k at the current x
  double barrier_energy(double J, double kappa, double V0) const;
  double barrier_slope(double J, double kappa, double V0) const;  // dW/dJ
  double barrier_curvature(double J, double kappa, double V0) const;  // d2W/dJ2
  // The inversion guard's energy, dW/dJ and d2W/dJ2 (zero for J >= inversion_guard).
  double guard_energy(double J, double kappa, double V0) const;
  double guard_slope(double J, double kappa, double V0) const;
  double guard_curvature(double J, double kappa, double V0) const;
  // A spring's tension (k l0 e Hookean, k l0 (exp(b e) - 1) / b stiffening), its energy and its
  // axial tangent over k, at length l.
  double spring_tension(const Spring& s, double l) const;
  double spring_energy(const Spring& s, double l) const;
  double spring_axial(const Spring& s, double l) const;
  int implicit_step(double dt, double& relative_residual);
  // The tangent at x_ into the scratch below (spring_integrators.cpp), and its product.
  void linearize();
  void apply_tangent(const std::vector<Vec3>& p, std::vector<Vec3>& y, double a, double b, double c);
  void warn_once(Integrator integrator, double dt, double limit);

  SpringOptions opt_;
  MaterialTable materials_;
  mutable std::unordered_map<int, SpringCalibration> calib_;

  // Per vertex, by VertexId index.
  std::vector<Vec3> x_, v_, f_ext_, target_, acc_;
  std::vector<double> mass_;
  std::vector<std::uint8_t> alive_, fixed_, prescribed_, mark_;
  Vec3 gravity_ = Vec3::Zero();

  // Springs stored densely (swap-remove) and found through the edge map.
  std::vector<Spring> springs_;
  std::unordered_map<std::uint64_t, std::uint32_t> spring_index_;
  // Volume terms stored densely; volume_slot_ by TetId index (kNone when absent).
  std::vector<Volume> volumes_;
  std::vector<std::uint32_t> volume_slot_;
  // Copy of each live tet's vertices (by TetId): apply() needs the edges of removed tets.
  std::vector<std::array<VertexId, 4>> tet_v_;
  std::vector<std::uint8_t> tet_alive_;
  // SpringStiffness::Fitted: each live tet's constants (by TetId), fitted when it is added.
  std::vector<TetSpringFit> tet_fit_;
  void fit_tet(const TetMesh& mesh, TetId t);

  // Per-vertex Gershgorin row bound on w^2 and a max segment tree over it (O(log n) updates).
  std::vector<double> bound_;
  std::vector<double> bound_tree_;
  std::size_t bound_leaves_ = 0;

  // Scratch for steps and the implicit solve.
  std::vector<Vec3> force_, dv_, r_, z_, p_, ap_, diag_;
  std::vector<Vec3> spring_n_;
  std::vector<double> spring_alpha_, volume_beta_;
  std::vector<double> spring_axial_;  // implicit: axial tangent over k (exp(b e); 1 Hookean)
  double max_tau_ = 0;  // the largest spring viscosity so far (the stable step's bound)
  // nodal_volume: per vertex, summed from the per-tet volumes (scratch of the passes).
  struct NodalVolume {
    double rest = 0, kappa_rest = 0, current = 0;  // V0_a, kappa_a V0_a, V_a
    double slope = 0;                              // dW_a/dJ_a / V0_a (forces)
    double beta = 0;                               // d2W_a/dJ_a2 / V0_a^2 (implicit Gauss-Newton)
  };
  mutable std::vector<NodalVolume> nodal_;
  std::vector<double> nodal_dot_;  // implicit product: per vertex beta_a g_a . p
  std::vector<double> tet_dot_;    // implicit product: per tet g_t . p
  void nodal_volumes(const std::vector<Vec3>& x) const;  // fills nodal_ at x
  std::vector<std::array<Vec3, 4>> volume_grad_;
  std::vector<std::uint32_t> touched_, scratch_;
  std::vector<std::uint64_t> edge_scratch_;
  bool acc_valid_ = false;
  unsigned warned_ = 0;  // bit per Integrator
  // Per Integrator: the stable step estimated when a step first exceeded the bound (warn_once).
  struct EstimateCheck {
    double bound = -1, dt = 0, estimate = 0;
  };
  std::array<EstimateCheck, 4> checked_{};

  SpringUpdateCounters counters_;
  ChangeFollower follower_;  // apply() takes the mesh's changes in order, each once
};

}  // namespace incise
