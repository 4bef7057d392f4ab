// incise improve against CGAL's tetrahedral_isotropic_remeshing (libcgal-dev) on the same
// meshes: min/max dihedral, min radius ratio, tet count and time, with the input as the
// baseline and the time ratio CGAL / incise. CGAL remeshes to a target edge length (the
// input's mean edge length here) and may move the surface within its feature detection;
// incise keeps the connectivity mostly and the surface on its old faces.
// Usage: bench_improve_vs_cgal MESH ...   (needs a build with CGAL)
#include <cstdio>
#include <map>
#include <string>
#include <vector>

#include "bench/bench_common.h"
#include "mesh/io/tet_io.h"
#include "quality/improve.h"
#include "quality/metrics.h"

#ifdef INCISE_HAVE_TETRA
#include <CGAL/Exact_predicates_inexact_constructions_kernel.h>
#include <CGAL/Mesh_3/tet_soup_to_c3t3.h>
#include <CGAL/Tetrahedral_remeshing/Remeshing_triangulation_3.h>
#include <CGAL/tetrahedral_remeshing.h>
#endif

using namespace incise;

namespace {

struct Figures {
  double min_dih = 180, max_dih = 0, min_rr = 1;
  std::size_t tets = 0;
  void add(const TetQuality& q) {
    min_dih = std::min(min_dih, q.min_dihedral);
    max_dih = std::max(max_dih, q.max_dihedral);
    min_rr = std::min(min_rr, q.radius_ratio);
    ++tets;
  }
};

void print(const std::string& name, const char* who, const Figures& f, double ms) {
  std::printf("%-22s %-8s dihedral %6.2f..%6.2f  rr %.3f  tets %7zu  %9.1f ms\n", name.c_str(), who, f.min_dih,
              f.max_dih, f.min_rr, f.tets, ms);
}

Figures figures(const TetMesh& m) {
  Figures f;
  for (TetId t : m.tets()) f.add(tet_quality(m, t));
  return f;
}

#ifdef INCISE_HAVE_TETRA
using K = CGAL::Exact_predicates_inexact_constructions_kernel;
using Tr = CGAL::Tetrahedral_remeshing::Remeshing_triangulation_3<K>;

// CGAL remeshing of the mesh (labels as subdomains, which must be > 0); its figures.
Figures cgal_remesh(const TetMesh& m, int iterations, double& ms) {
  std::vector<K::Point_3> points;
  std::map<std::uint32_t, int> index;
  for (VertexId v : m.vertices()) {
    index[v.idx()] = static_cast<int>(points.size());
    points.emplace_back(m.rest(v).x(), m.rest(v).y(), m.rest(v).z());
  }
  std::vector<std::array<int, 5>> cells;
  double edge_sum = 0;
  std::size_t edges = 0;
  for (TetId t : m.tets()) {
    const auto& tv = m.tet_vertices(t);
    cells.push_back({index[tv[0].idx()], index[tv[1].idx()], index[tv[2].idx()], index[tv[3].idx()],
                     std::max(1, m.label(t))});
    for (int i = 0; i < 4; ++i)
      for (int j = i + 1; j < 4; ++j, ++edges) edge_sum += (m.rest(tv[i]) - m.rest(tv[j])).norm();
  }
  const double t0 = bench::now_ms();
  Tr tr;
  std::vector<Tr::Vertex_handle> handles;
  const std::map<std::array<int, 3>, int> no_facets;
  CGAL::build_triangulation<Tr, true>(tr, points, cells, no_facets, handles);
  CGAL::tetrahedral_isotropic_remeshing(tr, edge_sum / double(edges),
                                        CGAL::parameters::number_of_iterations(iterations));
  ms = bench::now_ms() - t0;
  Figures f;
  for (auto c : tr.finite_cell_handles()) {
    if (c->subdomain_index() == 0) continue;
    auto p = [&](int k) {
      const auto& x = c->vertex(k)->point();
      return Vec3(x.x(), x.y(), x.z());
    };
    f.add(tet_quality(p(0), p(1), p(2), p(3)));
  }
  return f;
}
#endif

}  // namespace

int main(int argc, char** argv) {
  bench::Args args(argc, argv);
#ifndef INCISE_HAVE_TETRA
  std::printf("bench_improve_vs_cgal: this build has no CGAL (configure with -DINCISE_WITH_CGAL=ON)\n");
  return 0;
#else
  std::printf("# input (baseline), incise improve (curved sliding, 30 s limit), CGAL tetrahedral_isotropic_remeshing (1 and 5 iterations, target = mean edge)\n");
  for (const std::string& f : args.argv) {
    const std::string name = std::filesystem::path(f).filename().string();
    TetMesh m = read_tet_mesh(f);
    m.discard_change();
    print(name, "input", figures(m), 0);
    TetMesh ours = m;
    ImproveOptions o;
    o.time_limit_s = 30;
    o.slide_curved = true;
    const double t0 = bench::now_ms();
    improve(ours, o);
    const double ms_ours = bench::now_ms() - t0;
    print(name, "incise", figures(ours), ms_ours);
    for (int it : {1, 5}) {
      double ms_cgal = 0;
      const Figures c = cgal_remesh(m, it, ms_cgal);
      print(name, it == 1 ? "cgal-1it" : "cgal-5it", c, ms_cgal);
      std::printf("%-22s time cgal (%d iterations) / incise = %.2f\n", name.c_str(), it,
                  ms_cgal / std::max(ms_ours, 1e-3));
    }
  }
  return 0;
#endif
}
