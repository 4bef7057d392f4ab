#include "sim/fem/assembled_stiffness.h"

#include <chrono>
#include <cmath>

#include <Eigen/SparseCholesky>
#ifdef INCISE_HAVE_CHOLMOD
#include <Eigen/CholmodSupport>
#endif
#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include "mesh/clock.h"
#include "mesh/errors.h"

namespace incise {

void AssembledStiffness::rebuild() {
  k_ = model_->assemble();
  diag_ = k_.diagonal();
}

void AssembledStiffness::multiply(const Eigen::VectorXd& x, Eigen::VectorXd& y) const {
  if (x.size() != k_.cols()) throw InvalidArgument("assembled: K*x with a vector of the wrong size");
  y.resize(k_.rows());
  const auto* outer = k_.outerIndexPtr();
  const auto* inner = k_.innerIndexPtr();
  const double* val = k_.valuePtr();
  const double* xp = x.data();
  double* yp = y.data();
  tbb::parallel_for(tbb::blocked_range<Eigen::Index>(0, k_.outerSize(), 2048),
                    [&](const tbb::blocked_range<Eigen::Index>& r) {
                      for (Eigen::Index i = r.begin(); i != r.end(); ++i) {
                        double s = 0;
                        for (auto p = outer[i]; p < outer[i + 1]; ++p) s += val[p] * xp[inner[p]];
                        yp[i] = s;
                      }
                    });
}

struct DirectSolver::Impl {
  Eigen::SimplicialLDLT<Eigen::SparseMatrix<double>> ldlt;
#ifdef INCISE_HAVE_CHOLMOD
  std::unique_ptr<Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>>> llt;  // supernodal
#endif
  Eigen::SparseMatrix<double> a_fk;  // free rows, kept columns: moves prescribed values to the rhs
  std::vector<Eigen::Index> free_index, kept_index;
};

DirectSolver::DirectSolver(bool supernodal) : impl_(std::make_unique<Impl>()) {
#ifdef INCISE_HAVE_CHOLMOD
  if (supernodal) {
    impl_->llt = std::make_unique<Eigen::CholmodSupernodalLLT<Eigen::SparseMatrix<double>>>();
    impl_->llt->cholmod().print = 0;  // a failure is reported by info(), not on stdout
  }
#else
  (void)supernodal;
#endif
}
DirectSolver::~DirectSolver() = default;

void DirectSolver::compute(const Eigen::SparseMatrix<double>& a, const std::vector<std::uint8_t>& free) {
  const auto t0 = std::chrono::steady_clock::now();
  if (Eigen::Index(free.size()) != a.rows()) throw InvalidArgument("direct: free mask size does not match the matrix");
  auto& im = *impl_;
  std::vector<Eigen::Index> pos(free.size(), -1);
  im.free_index.clear();
  im.kept_index.clear();
  for (std::size_t i = 0; i < free.size(); ++i) {
    if (free[i]) {
      pos[i] = Eigen::Index(im.free_index.size());
      im.free_index.push_back(Eigen::Index(i));
    } else {
      pos[i] = -Eigen::Index(im.kept_index.size()) - 2;
      im.kept_index.push_back(Eigen::Index(i));
    }
  }
  std::vector<Eigen::Triplet<double>> ff, fk;
  for (Eigen::Index c = 0; c < a.outerSize(); ++c)
    for (Eigen::SparseMatrix<double>::InnerIterator it(a, c); it; ++it) {
      const Eigen::Index r = it.row(), col = it.col();
      if (pos[r] < 0) continue;
      if (pos[col] >= 0) ff.emplace_back(pos[r], pos[col], it.value());
      else fk.emplace_back(pos[r], -pos[col] - 2, it.value());
    }
  const Eigen::Index nf = Eigen::Index(im.free_index.size()), nk = Eigen::Index(im.kept_index.size());
  Eigen::SparseMatrix<double> aff(nf, nf);
  aff.setFromTriplets(ff.begin(), ff.end());
  im.a_fk.resize(nf, nk);
  im.a_fk.setFromTriplets(fk.begin(), fk.end());
#ifdef INCISE_HAVE_CHOLMOD
  if (im.llt) {
    im.llt->compute(aff);
    if (im.llt->info() != Eigen::Success)
      throw Error("direct solver: matrix is singular or indefinite on the free unknowns: too few fixed nodes for a "
                  "static solve?");
    factorize_ms_ = ms_since(t0);
    return;
  }
#endif
  im.ldlt.compute(aff);
  if (im.ldlt.info() != Eigen::Success)
    throw Error("direct solver: factorization failed (matrix singular on the free unknowns: too few fixed nodes?)");
  // SimplicialLDLT does not fail on a singular SPD-looking matrix: check the pivots.
  const auto d = im.ldlt.vectorD();
  const double dmax = d.size() ? d.cwiseAbs().maxCoeff() : 0;
  for (Eigen::Index i = 0; i < d.size(); ++i)
    if (!(d[i] > 1e-13 * dmax))
      throw Error("direct solver: matrix is singular or indefinite on the free unknowns (pivot " +
                  std::to_string(d[i]) + "): too few fixed nodes for a static solve?");
  factorize_ms_ = ms_since(t0);
}

void DirectSolver::solve(const Eigen::VectorXd& b, Eigen::VectorXd& x) const {
  const auto& im = *impl_;
  const Eigen::Index nf = Eigen::Index(im.free_index.size()), nk = Eigen::Index(im.kept_index.size());
  Eigen::VectorXd bf(nf), xk(nk);
  for (Eigen::Index i = 0; i < nf; ++i) bf[i] = b[im.free_index[i]];
  for (Eigen::Index i = 0; i < nk; ++i) xk[i] = x[im.kept_index[i]];
  if (nk) bf -= im.a_fk * xk;
#ifdef INCISE_HAVE_CHOLMOD
  const Eigen::VectorXd xf = im.llt ? Eigen::VectorXd(im.llt->solve(bf)) : Eigen::VectorXd(im.ldlt.solve(bf));
#else
  const Eigen::VectorXd xf = im.ldlt.solve(bf);
#endif
  for (Eigen::Index i = 0; i < nf; ++i) x[im.free_index[i]] = xf[i];
}

}  // namespace incise
