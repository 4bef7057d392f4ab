#include "sim/linalg/preconditioner.h"

#include <cmath>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "mesh/errors.h"

namespace incise {

const char* to_string(Preconditioner p) {
  switch (p) {
    case Preconditioner::None: return "none";
    case Preconditioner::Jacobi: return "jacobi";
    case Preconditioner::BlockJacobi: return "block-jacobi";
    case Preconditioner::Cholesky: return "cholesky";
    case Preconditioner::Amg: return "amg";
  }
  return "?";
}

Preconditioner parse_preconditioner(const std::string& name) {
  for (Preconditioner p :
       {Preconditioner::None, Preconditioner::Jacobi, Preconditioner::BlockJacobi, Preconditioner::Cholesky,
        Preconditioner::Amg})
    if (name == to_string(p)) return p;
  throw InvalidArgument("expected \"jacobi\", \"block-jacobi\", \"cholesky\", \"amg\" or \"none\", got \"" + name + "\"");
}

namespace {

bool is_free(const std::vector<std::uint8_t>* free, Eigen::Index i) { return !free || (*free)[std::size_t(i)]; }

class Identity : public CgPreconditioner {
public:
  void setup(const LinearOperator&, const std::vector<std::uint8_t>* free) override { free_ = free; }
  void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const override {
    z = r;
    if (free_)
      for (Eigen::Index i = 0; i < z.size(); ++i)
        if (!(*free_)[std::size_t(i)]) z[i] = 0;
  }

private:
  const std::vector<std::uint8_t>* free_ = nullptr;
};

class Jacobi : public CgPreconditioner {
public:
  void setup(const LinearOperator& a, const std::vector<std::uint8_t>* free) override {
    const Eigen::VectorXd& d = a.diagonal();
    inv_.resize(a.rows());
    for (Eigen::Index i = 0; i < inv_.size(); ++i) {
      const bool f = is_free(free, i);
      inv_[i] = (f && d[i] > 0) ? 1.0 / d[i] : (f ? 1.0 : 0.0);
    }
  }
  void apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const override { z = inv_.cwiseProduct(r); }

private:
  Eigen::VectorXd inv_;
};

}  // namespace

namespace {

// The inverse of a symmetric 3x3 block (its lower triangle) by the adjugate, when Sylvester's
// criterion says it is positive definite. About 40 flops: an LLT and a solve against the
// identity per block cost a noticeable share of a frame that sets the blocks up again each
// time the rotations change (docs/solver.md, "The coarse factor").
bool spd_inverse(const Eigen::Matrix3d& m, Eigen::Matrix3d& inv) {
  const double a = m(0, 0), b = m(1, 0), c = m(2, 0), d = m(1, 1), e = m(2, 1), f = m(2, 2);
  const double ca = d * f - e * e, cb = c * e - b * f, cc = b * e - c * d;
  const double det = a * ca + b * cb + c * cc;
  if (!(a > 0 && a * d - b * b > 0 && det > 0) || !std::isfinite(det)) return false;
  const double s = 1.0 / det;
  inv << ca, cb, cc, cb, a * f - c * c, b * c - a * e, cc, b * c - a * e, a * d - b * b;
  inv *= s;
  return true;
}

}  // namespace

void BlockJacobi::setup(const LinearOperator& a, const std::vector<std::uint8_t>* free) {
  const Eigen::VectorXd& d = a.diagonal();
  const auto& blocks = a.diagonal_blocks();
  const std::size_t nv = std::size_t(a.rows() / 3);
  inv_.resize(nv);
  auto vertex = [&](std::size_t v) {
    const Eigen::Index i = Eigen::Index(3 * v);
    Eigen::Matrix3d& m = inv_[v];
    const bool all_free = is_free(free, i) && is_free(free, i + 1) && is_free(free, i + 2);
    if (all_free && v < blocks.size() && spd_inverse(blocks[v], m)) return;
    m.setZero();
    for (int c = 0; c < 3; ++c)
      if (is_free(free, i + c)) m(c, c) = d[i + c] > 0 ? 1.0 / d[i + c] : 1.0;
  };
  if (nv < 4096) {
    for (std::size_t v = 0; v < nv; ++v) vertex(v);
    return;
  }
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, nv, 1024), [&](const tbb::blocked_range<std::size_t>& rg) {
    for (std::size_t v = rg.begin(); v != rg.end(); ++v) vertex(v);
  });
}

void BlockJacobi::apply_vertex(std::size_t v, const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
  z.segment<3>(Eigen::Index(3 * v)).noalias() = inv_[v] * r.segment<3>(Eigen::Index(3 * v));
}

void BlockJacobi::apply(const Eigen::VectorXd& r, Eigen::VectorXd& z) const {
  z.resize(r.size());
  for (std::size_t v = 0; v < inv_.size(); ++v) apply_vertex(v, r, z);
}

std::unique_ptr<CgPreconditioner> make_preconditioner(Preconditioner kind) {
  switch (kind) {
    case Preconditioner::None: return std::make_unique<Identity>();
    case Preconditioner::Jacobi: return std::make_unique<Jacobi>();
    case Preconditioner::BlockJacobi:
    case Preconditioner::Cholesky:
    case Preconditioner::Amg: return std::make_unique<BlockJacobi>();
  }
  return std::make_unique<Jacobi>();
}

}  // namespace incise
