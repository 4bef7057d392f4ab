// Level sets with OpenVDB: signed distance of a (possibly dirty) surface, hole closing,
// zero-set extraction. See level_set.h for the construction.
#include "mesh/tetrahedralize/level_set.h"

#include <cmath>
#include <deque>
#include <limits>
#include <mutex>
#include <sstream>

#include <openvdb/openvdb.h>
#include <openvdb/tools/Interpolation.h>
#include <openvdb/tools/MeshToVolume.h>
#include <openvdb/tools/VolumeToMesh.h>

#include "mesh/errors.h"

namespace incise {
namespace {

struct VdbMesh {
  std::vector<openvdb::Vec3s> points;
  std::vector<openvdb::Vec3I> tris;
  std::vector<openvdb::Vec4I> quads;
};

void init_openvdb() {
  static std::once_flag once;
  std::call_once(once, [] { openvdb::initialize(); });
}

// Surface -> OpenVDB mesh in normalized coordinates (p - center) / unit: float precision
// and OpenVDB's transform limits are then relative to the model, whatever its scale and
// distance from the origin.
VdbMesh to_vdb(const SurfaceMesh& s, const Vec3& center, double unit) {
  VdbMesh m;
  m.points.reserve(s.vertices.size());
  for (const Vec3& p : s.vertices) {
    const Vec3 q = (p - center) / unit;
    m.points.emplace_back(float(q.x()), float(q.y()), float(q.z()));
  }
  m.tris.reserve(s.triangles.size());
  for (auto& t : s.triangles) m.tris.emplace_back(t[0], t[1], t[2]);
  return m;
}

// Extracts the isosurface `iso` of `grid` as triangles (quads split on the shorter
// diagonal), back in world coordinates (p * unit + center), outward oriented.
SurfaceMesh extract(const openvdb::FloatGrid& grid, double iso, const Vec3& center, double unit) {
  std::vector<openvdb::Vec3s> pts;
  std::vector<openvdb::Vec3I> tris;
  std::vector<openvdb::Vec4I> quads;
  openvdb::tools::volumeToMesh(grid, pts, tris, quads, iso, 0.0, true);
  SurfaceMesh s;
  s.vertices.reserve(pts.size());
  for (auto& p : pts) s.vertices.push_back(Vec3(p.x(), p.y(), p.z()) * unit + center);
  for (auto& t : tris) s.triangles.push_back({int(t[0]), int(t[1]), int(t[2])});
  for (auto& q : quads) {
    const double d02 = (s.vertices[q[0]] - s.vertices[q[2]]).squaredNorm();
    const double d13 = (s.vertices[q[1]] - s.vertices[q[3]]).squaredNorm();
    if (d02 <= d13) {
      s.triangles.push_back({int(q[0]), int(q[1]), int(q[2])});
      s.triangles.push_back({int(q[0]), int(q[2]), int(q[3])});
    } else {
      s.triangles.push_back({int(q[0]), int(q[1]), int(q[3])});
      s.triangles.push_back({int(q[1]), int(q[2]), int(q[3])});
    }
  }
  if (enclosed_volume(s) < 0)
    for (auto& t : s.triangles) std::swap(t[1], t[2]);
  return s;
}

// Largest distance from the centroid of a group of border edges to its vertices.
double largest_hole_radius(const SurfaceMesh& s) {
  SurfaceCheck c = check_surface(s);
  return c.holes ? c.largest_hole_radius : 0.0;
}

}  // namespace

struct SignedDistance::Impl {
  openvdb::FloatGrid::Ptr grid;
  Vec3 center = Vec3::Zero();
  double unit = 1;  // grid coordinates are (world - center) / unit
  Vec3 lo = Vec3::Zero(), hi = Vec3::Zero();
  double voxel = 0;
  double shift = 0;  // sdf = (grid value + shift) * unit (shift: the closing's erosion)
  double r = 0;
};

SignedDistance::SignedDistance(const SurfaceMesh& surface, const LevelSetOptions& opt) : impl_(std::make_unique<Impl>()) {
  init_openvdb();
  if (surface.triangles.empty() || surface.vertices.empty())
    throw InvalidArgument("level set: the surface has no triangles");
  Eigen::AlignedBox3d box;
  for (const Vec3& p : surface.vertices) box.extend(p);
  const double diag = box.diagonal().norm();
  if (!(diag > 0) || !std::isfinite(diag)) throw InvalidArgument("level set: the surface has no extent");
  Impl& m = *impl_;
  m.center = box.center();
  m.unit = diag;
  m.voxel = opt.voxel.resolve(diag);
  if (!(m.voxel > 0)) throw InvalidArgument("level set: --voxel must be positive");
  m.r = opt.closing_radius >= 0 ? opt.closing_radius : [&] {
    const double h = largest_hole_radius(surface);
    return h > 0 ? h + 2 * m.voxel : 0.0;
  }();
  const Vec3 ext = box.sizes() + Vec3::Constant(2 * (m.r + 4 * m.voxel));
  const double cells = (ext.x() / m.voxel) * (ext.y() / m.voxel) * (ext.z() / m.voxel);
  if (cells > 2e9) {
    std::ostringstream os;
    os << "level set: voxel " << m.voxel << " would need " << cells << " voxels; use a larger --voxel";
    throw InvalidArgument(os.str());
  }
  m.lo = box.min() - Vec3::Constant(m.r + 2 * m.voxel);
  m.hi = box.max() + Vec3::Constant(m.r + 2 * m.voxel);

  const auto xform = openvdb::math::Transform::createLinearTransform(m.voxel / m.unit);
  const float ex_band = opt.exterior_band > 0 ? float(opt.exterior_band / m.voxel) : 3.0f;
  const float in_band = opt.interior_band > 0    ? float(opt.interior_band / m.voxel)
                        : opt.interior_band == 0 ? 3.0f
                                                 : std::numeric_limits<float>::max();
  VdbMesh mesh = to_vdb(surface, m.center, m.unit);

  if (m.r <= 0) {
    m.grid = openvdb::tools::meshToSignedDistanceField<openvdb::FloatGrid>(*xform, mesh.points, mesh.tris, mesh.quads,
                                                                           ex_band, in_band);
    return;
  }

  // Morphological closing. 1) unsigned distance u in a band wide enough to hold r.
  const float rv = float(m.r / m.voxel);
  auto u = openvdb::tools::meshToUnsignedDistanceField<openvdb::FloatGrid>(*xform, mesh.points, mesh.tris, mesh.quads,
                                                                          rv + 3.0f);
  const float bg = u->background();
  // 2) flood the outside {u > r} from a corner of a box one voxel beyond the band.
  const openvdb::CoordBBox bb = [&] {
    openvdb::CoordBBox b = u->evalActiveVoxelBoundingBox();
    b.expand(2);
    return b;
  }();
  const openvdb::Coord dim = bb.dim();
  const std::size_t nx = dim.x(), ny = dim.y(), nz = dim.z(), n = nx * ny * nz;
  auto at = [&](std::size_t i, std::size_t j, std::size_t k) { return (k * ny + j) * nx + i; };
  std::vector<float> val(n);
  {
    auto acc = u->getConstAccessor();
    for (std::size_t k = 0; k < nz; ++k)
      for (std::size_t j = 0; j < ny; ++j)
        for (std::size_t i = 0; i < nx; ++i)
          val[at(i, j, k)] = acc.getValue(bb.min().offsetBy(int(i), int(j), int(k)));
  }
  const float rw = float(m.r / m.unit);
  std::vector<char> outside(n, 0);
  std::deque<std::size_t> queue{0};
  outside[0] = 1;
  while (!queue.empty()) {
    const std::size_t c = queue.front();
    queue.pop_front();
    const std::size_t i = c % nx, j = (c / nx) % ny, k = c / (nx * ny);
    auto visit = [&](std::size_t ii, std::size_t jj, std::size_t kk) {
      const std::size_t q = at(ii, jj, kk);
      if (!outside[q] && val[q] > rw) {
        outside[q] = 1;
        queue.push_back(q);
      }
    };
    if (i > 0) visit(i - 1, j, k);
    if (i + 1 < nx) visit(i + 1, j, k);
    if (j > 0) visit(i, j - 1, k);
    if (j + 1 < ny) visit(i, j + 1, k);
    if (k > 0) visit(i, j, k - 1);
    if (k + 1 < nz) visit(i, j, k + 1);
  }
  // 3) the dilated solid's distance near its boundary is u - r on both sides; deep inside
  // (u > r but not reached from outside) it is simply "inside".
  auto dilated = openvdb::FloatGrid::create(bg);
  dilated->setTransform(xform);
  dilated->setGridClass(openvdb::GRID_LEVEL_SET);
  {
    auto acc = dilated->getAccessor();
    for (std::size_t k = 0; k < nz; ++k)
      for (std::size_t j = 0; j < ny; ++j)
        for (std::size_t i = 0; i < nx; ++i) {
          const std::size_t c = at(i, j, k);
          const float v = outside[c] ? val[c] - rw : (val[c] <= rw ? val[c] - rw : -bg);
          if (std::abs(v) < bg) acc.setValue(bb.min().offsetBy(int(i), int(j), int(k)), v);
          else if (v < 0) acc.setValueOff(bb.min().offsetBy(int(i), int(j), int(k)), -bg);
        }
  }
  val.clear();
  outside.clear();
  const SurfaceMesh dilated_surface = extract(*dilated, 0.0, Vec3::Zero(), 1.0);
  dilated.reset();
  if (dilated_surface.triangles.empty()) throw Error("level set: the closing produced an empty surface");
  // 4) erode by r: the signed distance of the dilated surface, read at -r.
  VdbMesh dm = to_vdb(dilated_surface, Vec3::Zero(), 1.0);
  const float in2 = opt.interior_band >= 0 ? in_band + rv + 1.0f : std::numeric_limits<float>::max();
  m.grid = openvdb::tools::meshToSignedDistanceField<openvdb::FloatGrid>(*xform, dm.points, dm.tris, dm.quads,
                                                                         std::max(ex_band - rv, 3.0f), std::max(in2, rv + 3.0f));
  m.shift = m.r / m.unit;
}

SignedDistance::~SignedDistance() = default;
SignedDistance::SignedDistance(SignedDistance&&) noexcept = default;
SignedDistance& SignedDistance::operator=(SignedDistance&&) noexcept = default;

double SignedDistance::operator()(const Vec3& p) const {
  const Vec3 q = (p - impl_->center) / impl_->unit;
  const openvdb::Vec3d idx = impl_->grid->transform().worldToIndex(openvdb::Vec3d(q.x(), q.y(), q.z()));
  return (double(openvdb::tools::BoxSampler::sample(impl_->grid->tree(), idx)) + impl_->shift) * impl_->unit;
}

SurfaceMesh SignedDistance::zero_surface() const {
  return extract(*impl_->grid, -impl_->shift, impl_->center, impl_->unit);
}
Vec3 SignedDistance::lo() const { return impl_->lo; }
Vec3 SignedDistance::hi() const { return impl_->hi; }
double SignedDistance::voxel() const { return impl_->voxel; }
double SignedDistance::closing_radius() const { return impl_->r; }

std::string RepairReport::summary() const {
  std::ostringstream os;
  os.precision(4);
  os << "repaired through a level set (voxel " << voxel;
  if (closing_radius > 0) os << ", holes closed with radius " << closing_radius;
  os << "): " << input_triangles << " -> " << output_triangles << " triangles, distance to input max "
     << distance.max << " mean " << distance.mean;
  return os.str();
}

SurfaceMesh repair_surface(const SurfaceMesh& surface, const LevelSetOptions& options, RepairReport* report) {
  LevelSetOptions o = options;
  if (o.interior_band < 0) o.interior_band = 0;  // only the zero set is needed: keep the band thin
  SignedDistance sdf(surface, o);
  SurfaceMesh out = sdf.zero_surface();
  if (out.triangles.empty()) throw Error("repair: the level set has no surface (is --voxel larger than the model?)");
  if (report) {
    report->voxel = sdf.voxel();
    report->closing_radius = sdf.closing_radius();
    report->input_triangles = surface.triangles.size();
    report->output_triangles = out.triangles.size();
    report->distance = surface_distance(out, surface);
  }
  return out;
}

}  // namespace incise
