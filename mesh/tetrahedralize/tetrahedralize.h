#pragma once
// Tetrahedral meshing of closed surfaces and labeled 3D images with CGAL Mesh_3
// (Delaunay refinement, then the optional ODT / Lloyd / perturb / exude optimizers).
//
// Contract: the returned TetMesh passes validate({true, true}); every tet is positively
// oriented; tets carry region labels (1 for a surface, the image label for an image);
// every boundary face is tagged kTagSurface. Output is repeatable for the same input,
// options and seed as long as no optimizer stops on its time limit (TetraStats says so).
//
// Sizes: a Length is absolute (model units) or relative to the bounding-box diagonal of
// the input ("0.05" is 0.05 units, "5%" is 5% of the diagonal). `size` bounds the
// circumradius of the tets (CGAL cell_size) and the surface facets (facet_size, and
// edge_size along sharp features).
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

#include "mesh/io/surface.h"
#include "mesh/tet_mesh.h"

namespace incise {

struct Length {
  double value = 0;       // absolute length, or fraction of the diagonal when relative
  bool relative = false;  // value is a fraction of the bounding-box diagonal
  double resolve(double diagonal) const { return relative ? value * diagonal : value; }
  // "0.05" -> absolute 0.05; "5%" -> relative 0.05. Throws InvalidArgument otherwise.
  static Length parse(const std::string& text);
  std::string str() const;  // the form parse() reads
};

enum OptimizeFlags : unsigned {
  kOptimizeNone = 0,
  kOptimizeOdt = 1,
  kOptimizeLloyd = 2,
  kOptimizePerturb = 4,
  kOptimizeExude = 8,
};
// "odt,lloyd,perturb,exude" in any order and subset, or "none". Throws InvalidArgument.
unsigned parse_optimize(const std::string& text);
std::string optimize_str(unsigned flags);

struct TetraOptions {
  Length size{0.03, true};            // tet/facet circumradius bound: 3% of the diagonal
  Length facet_distance{0, false};    // surface approximation bound; 0: size / 6
  double facet_angle = 25;            // minimum surface triangle angle, degrees (<= 30)
  double radius_edge = 2.5;           // tet circumradius / shortest edge bound (>= 2)
  double features_angle = -1;         // crease threshold: angle between face normals, degrees;
                                      // 0: off; < 0: auto (auto_features_angle())
  Length edge_size{0, false};         // sampling of sharp features (protecting balls); 0: size
  unsigned optimize = kOptimizePerturb | kOptimizeExude;  // optimizers run after refinement
  double optimize_time = 20;          // seconds per optimizer (a safety net, not a target)
  double sliver_bound = 15;           // perturb/exude target min dihedral, degrees; 0: best effort
  std::uint32_t seed = 0;             // CGAL random seed: same seed, same mesh
  std::map<int, double> label_sizes;  // images: absolute size per label (overrides `size`)
  std::size_t max_tets = 30'000'000;  // refuse sizes whose estimated tet count exceeds this
  bool progress = false;              // progress lines on stderr
  bool graded = false;                // stuffing engine: octree-graded lattice (fewer, larger
                                      // tets inside; `size` holds at the surface)
};

struct TetraStats {
  std::size_t tets = 0;
  std::size_t vertices = 0;
  double min_dihedral = 0;    // degrees
  double max_dihedral = 0;    // degrees
  double volume = 0;          // of the tet mesh
  double input_volume = 0;    // enclosed by the input surface (0 for images)
  double size = 0;            // resolved absolute size used
  double seconds = 0;         // wall time of meshing + optimization
  bool time_limit_hit = false;  // an optimizer stopped on its time limit (not repeatable)
  double features_angle = 0;  // feature angle used (0: none)
  std::vector<std::string> notes;  // e.g. an optimizer step undone because it broke the boundary
  std::string engine;         // "cgal" or "stuffing"
  std::string summary() const;  // one line: tets, dihedral range, volume, time
};

// Meshes the inside of a closed, manifold, self-intersection-free, consistently oriented
// surface (check_surface().meshable()). Several disjoint shells are fine (nested shells
// make cavities). Throws InvalidArgument for bad sizes (with an estimate of the tet count
// when too small) and Error when meshing yields no tets.
TetMesh tetrahedralize_surface(const SurfaceMesh& surface, const TetraOptions& options = {},
                               TetraStats* stats = nullptr);

// Meshes a labeled 3D image (.inr, .inr.gz, and whatever CGAL Image_3 reads): label 0 is
// outside, every other label becomes a region. Throws IoError for unreadable images.
TetMesh tetrahedralize_image(const std::string& path, const TetraOptions& options = {},
                             TetraStats* stats = nullptr);

// True for the image extensions tetrahedralize_image() reads (.inr, .inr.gz, Analyze .hdr/.img, .gis).
bool is_image_path(const std::string& path);

// The feature angle the auto mode picks: 60 degrees (CGAL's default) when the surface has
// crisp creases (the edges sharper than 60 degrees are at least half of those sharper than
// 40, and at most a tenth of all edges: a CAD part), else 0. Smooth organs and their noisy
// triangulations get no protected features, which would only cost element quality.
double auto_features_angle(const SurfaceMesh& surface);

// Total length of the surface's edges whose faces' normals differ by more than `angle`
// degrees: the sharp features Mesh_3 protects at that angle.
double feature_length(const SurfaceMesh& surface, double angle);

// Splits every vertex whose incident tets fall into several face-connected groups (two
// regions touching only at a point, as Mesh_3 leaves on labeled images) into one vertex per
// group, at the same position, so the boundary becomes manifold there. Returns the number
// of vertices added. Discards the pending TopologyChange (meant for fresh meshes).
std::size_t split_pinched_vertices(TetMesh& mesh);

// Makes the boundary a closed manifold: splits pinched vertices, then removes the tets
// around any boundary vertex whose link is still not a single cycle, up to `rounds`
// times, and compacts. Returns the number of tets removed. Throws Error if it does not
// converge.
std::size_t make_boundary_manifold(TetMesh& mesh, int rounds = 8);

// Estimated tet count for a volume meshed at circumradius bound `size`.
double estimate_tet_count(double volume, double size);

// Dihedral angle range (degrees) over live tets: {min, max}.
std::pair<double, double> dihedral_range(const TetMesh& mesh);

// Signed volume enclosed by a triangle surface (positive for outward orientation).
double enclosed_volume(const SurfaceMesh& surface);

}  // namespace incise
