#pragma once
// An inversion barrier for corotational tets (docs/solver.md#inversion-barrier-inversion_barrier-in-scenes), off unless
// asked for. The corotational element already pushes an inverted tet back (its rotation is the
// closest proper one, Irving, Teran & Fedkiw 2004), but with a force of its own size: a small
// tet on a cut face, or one whose strain a smoothed formulation averages with its neighbours',
// stays inverted where they pull harder. The barrier gives every tet whose volume ratio
// J = det F fell below `j_min` the energy
//   k V (j_min - J(u))^2,   k = stiffness x (kappa + 4 mu / 3) of the tet (its P-wave modulus),
// with J linearized where the tets were last relinearized (u_k): J(u) ~ J_k + g . (u - u_k),
// g = dJ/du = cof(F) grad N_j per corner. Per such tet that is a rank-one term
//   K += w g g^T,   b += w g (j_min - J_k + g . u_k),   w = 2 k V,
// in the product, the right-hand side and the internal forces, O(those tets). Which tets carry
// it is decided at each relinearization (lagged, as the rotations are), over every tet. A held
// tet stays held until J is back above 2 j_min, its J held where it is meanwhile (the target is
// max(j_min, J_k)): released as soon as J passed j_min, a tet alternated between inverted and
// held from frame to frame.
// The preconditioners do not see it (a rank-one term costs CG about one iteration).
#include <array>
#include <cstdint>
#include <vector>

#include <Eigen/Core>
#include <Eigen/SparseCore>

#include "mesh/topology_change.h"

namespace incise {

class FemModel;

// j_min where a caller turns the barrier on without one (a scene's `true`): see docs/solver.md.
constexpr double kDefaultBarrierJMin = 0.2;

struct InversionBarrierOptions {
  double j_min = 0;       // volume ratio below which a tet is held; 0: off
  double stiffness = 100;  // k over the tet's P-wave modulus (docs/solver.md#inversion-barrier-inversion_barrier-in-scenes)
};

class InversionBarrier {
public:
  void set_options(const InversionBarrierOptions& o) { opt_ = o; }
  const InversionBarrierOptions& options() const { return opt_; }
  bool enabled() const { return opt_.j_min > 0; }
  // Re-selects the held tets at displacement u: O(tets), parallel.
  void update(const FemModel& model, const Eigen::VectorXd& u);
  // The mesh changed (FemModel::apply): the removed tets are let go, and the terms wait for the
  // next update().
  void apply(const TopologyChange& change);
  std::size_t held() const { return terms_.size(); }

  void add_product(const Eigen::VectorXd& x, Eigen::VectorXd& y) const;  // y += K_b x
  void add_rhs(Eigen::VectorXd& b) const;                                 // b += b_b
  void add_internal_forces(const Eigen::VectorXd& u, Eigen::VectorXd& f) const;  // f += b_b - K_b u
  void add_to(Eigen::SparseMatrix<double>& k) const;                      // k += K_b (its pattern holds it)

private:
  struct Term {
    std::uint32_t tet = 0;
    std::array<std::uint32_t, 4> v;
    Eigen::Matrix<double, 12, 1> g;  // dJ/du at the corners
    double w = 0;                    // 2 k V
    double c = 0;                    // j_min - J_k + g . u_k
  };
  InversionBarrierOptions opt_;
  std::vector<Term> terms_;
  std::vector<std::uint8_t> held_;  // per tet slot
};

}  // namespace incise
