#include "cut/local_deformation.h"

#include <Eigen/Dense>
#include <unordered_set>
#include <vector>

namespace incise::cut_detail {

std::optional<LocalDeformation> fit_local_deformation(const TetMesh& mesh, std::span<const TetId> tets,
                                                      const std::function<Vec3(VertexId)>& positions) {
  std::vector<VertexId> verts;
  IdSet seen;
  for (TetId t : tets)
    if (mesh.is_alive(t))
      for (VertexId v : mesh.tet_vertices(t))
        if (seen.insert(v.idx()).second) verts.push_back(v);
  if (verts.empty()) return std::nullopt;
  bool moved = false;
  Vec3 rest_mean = Vec3::Zero(), cur_mean = Vec3::Zero();
  std::vector<Vec3> cur(verts.size());
  for (std::size_t i = 0; i < verts.size(); ++i) {
    cur[i] = positions(verts[i]);
    moved = moved || !(cur[i] == mesh.rest(verts[i]));
    rest_mean += mesh.rest(verts[i]);
    cur_mean += cur[i];
  }
  if (!moved) return std::nullopt;
  rest_mean /= double(verts.size());
  cur_mean /= double(verts.size());
  Eigen::Matrix3d sxx = Eigen::Matrix3d::Zero(), syx = Eigen::Matrix3d::Zero();
  for (std::size_t i = 0; i < verts.size(); ++i) {
    const Vec3 X = mesh.rest(verts[i]) - rest_mean, x = cur[i] - cur_mean;
    sxx += X * X.transpose();
    syx += x * X.transpose();
  }
  LocalDeformation d;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> eig(sxx);
  const Vec3 ev = eig.eigenvalues();  // ascending
  if (ev[0] > 1e-10 * ev[2] && ev[2] > 0) {
    const Eigen::Matrix3d A = syx * sxx.inverse();
    // A fit that inverts or nearly flattens the region is no deformation of tissue: translate only.
    const double det = A.determinant();
    const Eigen::JacobiSVD<Eigen::Matrix3d> svd(A);
    const Vec3 sv = svd.singularValues();
    if (det > 0 && sv[2] > 1e-6 * sv[0]) d.A = A;
  }
  d.t = cur_mean - d.A * rest_mean;
  return d;
}

}  // namespace incise::cut_detail
