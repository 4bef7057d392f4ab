// The preparation pipeline (pipeline.h) and the stuffing engine.
#include "mesh/tetrahedralize/pipeline.h"

#include <chrono>
#include <cmath>
#include <filesystem>
#include <iostream>
#include <sstream>

#include <Eigen/Eigenvalues>

#include "mesh/errors.h"
#include "mesh/io/surface.h"
#include "mesh/generate.h"
#include "mesh/isosurface_stuffing.h"

namespace incise {
namespace {

std::string fmt(double v) {
  std::ostringstream os;
  os.precision(4);
  os << v;
  return os.str();
}

}  // namespace

TetMesh tetrahedralize_stuffing(const SignedDistance& sdf, const TetraOptions& opt, TetraStats* stats) {
  const auto t0 = std::chrono::steady_clock::now();
  const Vec3 lo = sdf.lo(), hi = sdf.hi();
  const double diag = (hi - lo).norm();
  StuffingOptions so;
  // `size` is a circumradius bound for CGAL; the BCC cube edge h gives tets whose
  // circumradius is about 0.56 h (the interior BCC tet), so h = size / 0.56 meshes at the
  // same resolution as CGAL with the same --size.
  so.cell_size = opt.size.resolve(diag) / 0.56;
  if (!(so.cell_size > 0)) throw InvalidArgument("stuffing: --size must be positive");
  if (opt.size.resolve(diag) > diag / 4)
    throw InvalidArgument("stuffing: --size " + fmt(opt.size.resolve(diag)) + " is larger than the model allows (use at most " +
                          fmt(diag / 4) + ")");
  so.max_tets = opt.max_tets;
  so.graded = opt.graded;
  if (opt.progress) std::cerr << "tetra: isosurface stuffing, lattice spacing " << so.cell_size << "\n";
  TetMesh mesh = isosurface_stuffing([&sdf](const Vec3& p) { return sdf(p); }, lo, hi, so);
  // Where the lattice does not resolve thin parts the boundary can pinch; removing the few
  // tets around such vertices keeps the angle bounds (no tet is changed) and the manifold.
  const std::size_t removed = make_boundary_manifold(mesh);
  tag_boundary(mesh, kTagSurface);
  if (stats && removed) stats->notes.push_back(std::to_string(removed) + " tets removed to make the boundary manifold");
  if (stats) {
    stats->tets = mesh.num_tets();
    stats->vertices = mesh.num_vertices();
    std::tie(stats->min_dihedral, stats->max_dihedral) = dihedral_range(mesh);
    stats->volume = mesh.total_volume();
    stats->size = opt.size.resolve(diag);
    stats->seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    stats->engine = "stuffing";
  }
  return mesh;
}

namespace {

// Whether every point lies within a billionth of the diagonal of one plane (the plane through
// the centroid normal to the direction of least spread).
bool is_flat(const SurfaceMesh& s) {
  if (s.vertices.empty()) return true;
  Vec3 c = Vec3::Zero();
  for (const Vec3& p : s.vertices) c += p;
  c /= double(s.vertices.size());
  Eigen::Matrix3d cov = Eigen::Matrix3d::Zero();
  Eigen::AlignedBox3d box;
  for (const Vec3& p : s.vertices) {
    cov += (p - c) * (p - c).transpose();
    box.extend(p);
  }
  const Vec3 n = Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d>(cov).eigenvectors().col(0);
  double off = 0;
  for (const Vec3& p : s.vertices) off = std::max(off, std::abs((p - c).dot(n)));
  return off <= 1e-9 * box.diagonal().norm();
}

}  // namespace

TetMesh mesh_surface(const SurfaceMesh& input, const PipelineOptions& opt, PipelineReport* report,
                     const std::function<void(const std::string&)>& log) {
  PipelineReport local;
  PipelineReport& rep = report ? *report : local;
  auto say = [&](const std::string& m) {
    rep.messages.push_back(m);
    if (log) log(m);
  };
  SurfaceMesh surface;
  rep.check = check_surface(input, &surface);
  const SurfaceCheck& c = rep.check;
  if (c.triangles == 0 || surface.triangles.empty()) throw InvalidArgument("the surface has no (non-degenerate) triangles");
  say("check: " + std::to_string(c.vertices) + " vertices, " + std::to_string(surface.triangles.size()) +
      " triangles: " + c.summary());
  if (c.border_edges == surface.triangles.size() * 3)
    throw InvalidArgument("the surface encloses no volume (every edge is a border edge: a single sheet of " +
                          std::to_string(surface.triangles.size()) + " triangles)");

  if (is_flat(surface))
    throw InvalidArgument("the surface is flat (its " + std::to_string(surface.vertices.size()) +
                          " points lie in one plane): it encloses no volume to mesh, with or without --repair");

  double input_volume = std::abs(c.signed_volume);
  if (!c.meshable() && !opt.repair)
    throw InvalidArgument("the surface cannot be meshed as is (" + c.summary() +
                          "); rerun with --repair to rebuild it through a level set");

  const auto t0 = std::chrono::steady_clock::now();
  // Holes first get a minimum-area patch (shape-preserving) when the surface is a manifold
  // halfedge mesh; the level-set closing is the fallback, as it also fills concave gaps.
  bool holes_left = c.holes > 0;
  const SurfaceMesh original = surface;
  if (opt.repair && c.holes && opt.level_set.closing_radius < 0) {
    std::size_t filled = 0;
    if (fill_holes(surface, &filled)) {
      holes_left = false;
      say("repair: filled " + std::to_string(filled) + " holes with triangulated patches");
    }
  }
  TetMesh mesh;
  if (opt.engine == TetraEngine::Stuffing) {
    LevelSetOptions lo = opt.level_set;
    if (lo.closing_radius < 0) lo.closing_radius = (opt.repair && holes_left) ? c.largest_hole_radius : 0;
    if (lo.closing_radius > 0 && opt.level_set.closing_radius < 0) lo.closing_radius += 2 * lo.voxel.resolve(c.diagonal);
    SignedDistance sdf(surface, lo);
    say("level set: voxel " + fmt(sdf.voxel()) +
        (sdf.closing_radius() > 0 ? ", holes closed with radius " + fmt(sdf.closing_radius()) : std::string()));
    if (opt.repair) {
      rep.repaired = true;
      SurfaceMesh zero = sdf.zero_surface();
      rep.repair.voxel = sdf.voxel();
      rep.repair.closing_radius = sdf.closing_radius();
      rep.repair.input_triangles = surface.triangles.size();
      rep.repair.output_triangles = zero.triangles.size();
      rep.repair.distance = surface_distance(zero, original);
      input_volume = std::abs(enclosed_volume(zero));
      say(rep.repair.summary());
    }
    mesh = tetrahedralize_stuffing(sdf, opt.tetra, &rep.stats);
  } else {
    const SurfaceMesh* to_mesh = &surface;
    SurfaceMesh repaired;
    if (opt.repair) {
      LevelSetOptions lo = opt.level_set;
      if (lo.closing_radius < 0)
        lo.closing_radius = holes_left ? c.largest_hole_radius + 2 * lo.voxel.resolve(c.diagonal) : 0;
      repaired = repair_surface(surface, lo, &rep.repair);
      rep.repair.distance = surface_distance(repaired, original);
      rep.repaired = true;
      say(rep.repair.summary());
      const SurfaceCheck rc = check_surface(repaired, &repaired);
      if (!rc.meshable()) throw Error("repair: the rebuilt surface is still not meshable (" + rc.summary() + ")");
      input_volume = std::abs(rc.signed_volume);
      to_mesh = &repaired;
    }
    TetraOptions to = opt.tetra;
    // A level-set surface has no sharp features, only voxel-scale creases that must not
    // be protected as features.
    if (opt.repair) to.features_angle = 0;
    mesh = tetrahedralize_surface(*to_mesh, to, &rep.stats);
  }
  rep.stats.input_volume = input_volume;
  rep.stats.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  mesh.validate({true, true});
  rep.messages.push_back(rep.stats.summary());  // not logged: callers print it with the output
  return mesh;
}

TetMesh mesh_file(const std::string& path, const PipelineOptions& opt, PipelineReport* report,
                  const std::function<void(const std::string&)>& log) {
  PipelineReport local;
  PipelineReport& rep = report ? *report : local;
  rep.input = path;
  if (!std::filesystem::exists(path)) throw IoError(path, 0, "no such file");
  if (is_image_path(path)) {
    rep.image = true;
    if (opt.engine == TetraEngine::Stuffing)
      throw InvalidArgument(path + ": the stuffing engine meshes surfaces; use --engine cgal for labeled images");
    if (opt.repair) {
      rep.messages.push_back("repair: not needed for a labeled image (ignored)");
      if (log) log(rep.messages.back());
    }
    TetMesh mesh = tetrahedralize_image(path, opt.tetra, &rep.stats);
    mesh.validate({true, true});
    rep.messages.push_back(rep.stats.summary());  // not logged: callers print it with the output
    return mesh;
  }
  SurfaceMesh surface = read_surface(path);
  try {
    return mesh_surface(surface, opt, &rep, log);
  } catch (const IoError&) {
    throw;
  } catch (const InvalidArgument& e) {
    throw InvalidArgument(path + ": " + e.what());
  }
}

}  // namespace incise
