#pragma once
// What is wrong with a triangle surface before it is meshed, and the benign clean-up.
//
// Policy (docs/tetra.md): welding duplicate vertices, dropping degenerate and duplicate
// faces, and flipping a surface whose enclosed volume is negative are always done, with a
// message. Open boundaries, non-manifold edges and self-intersections change the shape,
// so they are only fixed on request (--repair, see level_set.h); without it the pipeline
// refuses with exit 1 and a message suggesting --repair.
#include <string>
#include <vector>

#include "mesh/io/surface.h"

namespace incise {

struct SurfaceCheck {
  std::size_t vertices = 0;             // after welding
  std::size_t triangles = 0;            // as read
  std::size_t welded_vertices = 0;      // coincident vertices merged
  std::size_t degenerate_faces = 0;     // repeated vertex or zero area
  std::size_t duplicate_faces = 0;      // same vertex set as an earlier face
  std::size_t border_edges = 0;         // edges with one face: open boundary
  std::size_t holes = 0;                // loops of border edges
  double largest_hole_radius = 0;       // max over holes of the largest distance to the loop centroid
  std::size_t nonmanifold_edges = 0;    // edges with more than two faces
  std::size_t misoriented_edges = 0;    // edges whose two faces disagree on orientation
  std::size_t components = 0;           // shells (face-connected components)
  std::size_t self_intersections = 0;   // pairs of intersecting faces (0 when not checked)
  bool self_intersection_checked = false;
  double signed_volume = 0;             // enclosed volume; negative: inverted orientation
  double diagonal = 0;                  // bounding-box diagonal

  // Can CGAL mesh the cleaned surface as is?
  bool meshable() const {
    return triangles > 0 && border_edges == 0 && nonmanifold_edges == 0 && misoriented_edges == 0 &&
           self_intersections == 0 && signed_volume != 0;
  }
  // One message per finding ("3 holes (124 border edges), largest radius 0.8"), empty if clean.
  std::vector<std::string> findings() const;
  // The findings joined on one line, or "clean".
  std::string summary() const;
};

// Checks `surface` (after the benign clean-up, which `cleaned` receives when non-null).
// Self-intersections are tested when the surface is manifold enough to build a halfedge
// mesh (otherwise the surface is already not meshable).
SurfaceCheck check_surface(const SurfaceMesh& surface, SurfaceMesh* cleaned = nullptr);

// Closes every hole with a triangulated patch (CGAL PMP triangulate_hole: minimum-area,
// no new vertices), after splitting non-manifold vertices and making the orientation
// consistent where possible. Returns false and leaves `surface` unchanged when it cannot
// become a halfedge mesh or a hole cannot be filled; `filled` receives the holes closed.
bool fill_holes(SurfaceMesh& surface, std::size_t* filled = nullptr);

// Sampled distance between two surfaces: about `samples` points on each surface (area
// weighted, plus the vertices), distance to the other one. max is the symmetric
// (Hausdorff-like) maximum, mean the mean over all samples.
struct SurfaceDistance {
  double max = 0;
  double mean = 0;
};
SurfaceDistance surface_distance(const SurfaceMesh& a, const SurfaceMesh& b, std::size_t samples = 20000);

}  // namespace incise
