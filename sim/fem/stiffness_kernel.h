#pragma once
// The matrix-free K x kernel. Tets live in slabs along the mesh's longest axis, each slab a
// block of packets of per-tet data (struct of arrays: B = inverse rest edge matrix, V mu,
// V lambda, 4 vertex ids, plus R as a quaternion for corotational). Slabs are at least as wide as any tet, so
// slabs three apart share no vertex: the product runs the slabs of colour 0, 1, 2 (slab index
// mod 3) in turn, each slab serially on one thread and scattering its corner forces straight
// into y: no per-corner scratch, no gather pass, and each thread sweeps a contiguous region of
// x and y. On CPUs with AVX2 and FMA (chosen at run time) four tets run at once in vector
// registers: each corner's x is one masked vector load, a 4x4 transpose turns four corners into
// x, y and z across the tets and back, and each corner's force is one vector read-modify-write
// into a copy of y padded to 4 doubles per vertex (unpacked into y after the product).
// Elsewhere (the portable path) x is gathered, the arithmetic runs as plain loops over the
// packet's lanes that the compiler vectorizes, and y is scattered entry by entry. Tets wider than a slab (rare: edits that stretch elements) go to an
// overflow block run last, serially.
//
// Kept locally: add() puts a tet in the slab of its centroid (O(1)), remove() swaps the last
// tet of its block into its slot. Small meshes run serially (no threading overhead).
#include <array>
#include <cstdint>
#include <functional>
#include <vector>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include "mesh/tet_mesh.h"

namespace incise {

class StiffnessKernel {
public:
  explicit StiffnessKernel(bool corotational) : corot_(corotational) {}

  // Chooses the axis and the slabs from the mesh's extent and its widest tet (O(mesh)); call
  // once before the first add().
  void configure(const TetMesh& mesh);
  // Tet t with vertex ids v, inverse rest edge matrix bm, V mu, V lambda (rest positions read
  // from `mesh` to place it).
  // `volume` (V) is needed by the nodal pressure of multiply() and by divergence() only.
  void add(const TetMesh& mesh, std::uint32_t t, const std::array<std::uint32_t, 4>& v, const Eigen::Matrix3d& bm,
           double vmu, double vlambda, double volume = 0);
  void remove(std::uint32_t t);  // no-op for a tet not in the kernel
  void set_rotation(std::uint32_t t, const Eigen::Matrix3d& r);
  void set_rotation(std::uint32_t t, const Eigen::Quaterniond& q);  // unit

  // y = K x over `rows` unknowns (y is resized and overwritten). Not reentrant: one kernel
  // multiplies for one caller at a time (it keeps padded copies of x and y). With
  // `vertex_pressure` (one value per vertex), each tet's stress also gets V p I, p the mean of
  // its four vertices' values: the nodal-averaged volumetric forces (sim/fem/fem_model.cpp) in the
  // same sweep as the deviatoric ones.
  void multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y, Eigen::Index rows,
                const double* vertex_pressure = nullptr) const;
  // The nodal-averaged and edge-smoothed products around the kernel (sim/fem/fem_model.cpp), in
  // coloured sweeps like multiply() (no per-corner scratch): strain_sweep writes, given out,
  // out[6 t + c] = V/6 sym(R^T D B)_c for every tet t (c: xx, yy, zz, xy, xz, yz) and, given
  // sums, adds V tr(R^T D B) (the tet's volume times its rotated-frame divergence of x) at its
  // vertices; stress_forces overwrites y with the corner forces of the stresses V_t (S_t + p_t I),
  // S_t given as out is, p_t the mean of vertex_pressure at its corners (when given).
  void strain_sweep(const Eigen::VectorXd& x, double* out, double* sums) const;
  void stress_forces(const double* stress, const double* vertex_pressure, Eigen::VectorXd& y, Eigen::Index rows) const;

  // The AVX2 path (x86-64 CPUs with AVX2 and FMA, chosen at run time): used unless switched
  // off (tests compare both paths; the portable one is what other CPUs run).
  static bool simd_available();
  void set_simd(bool on) { simd_ = on; }
  bool simd() const { return simd_ && simd_available(); }  // the AVX2 paths run

  std::size_t slabs() const { return blocks_.size() - 1; }

  static constexpr std::size_t kLanes = 8;  // tets per packet (the best of 4, 8, 16, 32: docs/solver.md#behind-the-constants)
  // Struct of arrays per packet of kLanes tets (array of structs of arrays): a packet is what the
  // arithmetic loop reads, contiguous, in one piece. Unused lanes hold zeros.
  struct Packet {
    alignas(64) double b[9][kLanes];  // b[3j+m]: row j of the inverse rest edge matrix (grad N_{j+1})
    alignas(64) double mu[kLanes], lam[kLanes];  // V mu, V lambda
    alignas(64) double vol[kLanes];              // V
    std::uint32_t v[4][kLanes];
  };
  // Corotational: the rotation as a unit quaternion (w, x, y, z), 32 bytes per tet instead of
  // 72 for the matrix; the product is bound by memory, and rebuilding R in registers is cheap.
  struct Rotations {
    alignas(64) double q[4][kLanes];
  };

  std::size_t tets() const { return count_; }

  // Every packet once, as multiply() runs them: slabs three apart at the same time, each slab on
  // one thread, the overflow block last. fn(packet, its rotations (corotational; else null), its
  // tet ids, its live lanes) may rewrite the rotations and add into per-vertex arrays at the
  // packet's vertices without locks, and the order in which a vertex receives its tets' terms does
  // not depend on the thread count. (The corotational relinearization: FemModel.)
  using PacketVisitor = std::function<void(const Packet&, Rotations*, const std::uint32_t*, std::size_t)>;
  void for_each_packet(const PacketVisitor& fn);

private:
  struct Block {
    std::vector<Packet> packets;
    std::vector<Rotations> rotations;  // corotational only
    std::vector<std::uint32_t> tet;    // by slot
    std::size_t size() const { return tet.size(); }
  };
  bool parallel() const;  // enough tets and slabs for the coloured parallel passes
  void multiply_block(const Block& blk, std::size_t begin, std::size_t end, const double* x, double* y,
                      const double* pressure) const;
  void multiply_padded(const Block& blk, const double* x, double* y, const double* pressure) const;
  // Every block's corner forces into y over `rows` unknowns (overwritten): run(block, out) adds
  // them into out, which is y itself, or on the AVX2 path (padded) its copy with 4 doubles per
  // vertex, unpacked into y afterwards.
  void sweep_forces(Eigen::VectorXd& y, Eigen::Index rows, bool padded,
                    const std::function<void(const Block&, double*)>& run) const;

  bool corot_;
  std::vector<Block> blocks_;                 // slabs, then the overflow block
  std::vector<std::uint32_t> block_, slot_;   // by tet id; kNone when absent
  std::size_t count_ = 0;
  int axis_ = 0;
  double origin_ = 0, width_ = 1;
  bool simd_ = true;
  mutable std::vector<double> ypad_;  // y with 4 doubles per vertex (AVX2 path)
};

}  // namespace incise
