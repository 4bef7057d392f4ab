// incise info FILE [--json]: what a mesh file holds (counts, format, extent, volume, labels,
// boundary tags, and what the reader had to skip or repair).
#include <cstdio>
#include <iostream>
#include <map>

#include <nlohmann/json.hpp>

#include "cli/commands.h"
#include "mesh/io/surface.h"
#include "mesh/io/tet_io.h"
#include "mesh/rest_bounds.h"

namespace incise::cli {

namespace {

nlohmann::json bbox_json(const Vec3& lo, const Vec3& hi) {
  return {{"min", {lo.x(), lo.y(), lo.z()}}, {"max", {hi.x(), hi.y(), hi.z()}}};
}

std::string fmt3(const Vec3& v) {
  char buf[128];
  std::snprintf(buf, sizeof buf, "(%.9g, %.9g, %.9g)", v.x(), v.y(), v.z());
  return buf;
}

void info_tet(const std::string& file, bool json) {
  ReadReport report;
  TetMesh m = read_tet_mesh(file, &report);
  const RestBounds box = rest_bounds(m);
  const Vec3 lo = box.lo, hi = box.hi;
  std::map<int, std::size_t> labels;
  double volume = 0, min_volume = std::numeric_limits<double>::infinity();
  for (TetId t : m.tets()) {
    ++labels[m.label(t)];
    double v = m.volume(t);
    volume += v;
    min_volume = std::min(min_volume, v);
  }
  std::map<int, std::size_t> tags;
  auto faces = m.boundary_faces();
  for (const auto& f : faces) ++tags[f.tag];
  if (json) {
    nlohmann::json j;
    j["file"] = file;
    j["kind"] = "tetrahedral mesh";
    j["format"] = report.format;
    j["vertices"] = m.num_vertices();
    j["tets"] = m.num_tets();
    j["boundary_faces"] = faces.size();
    j["bounding_box"] = bbox_json(lo, hi);
    j["volume"] = volume;
    j["min_tet_volume"] = min_volume;
    auto& jl = j["labels"] = nlohmann::json::object();
    for (auto [l, n] : labels) jl[std::to_string(l)] = n;
    auto& jt = j["boundary_tags"] = nlohmann::json::object();
    for (auto [t, n] : tags) jt[std::to_string(t)] = n;
    j["skipped_cells"] = report.skipped_cells;
    j["reoriented_tets"] = report.reoriented_tets;
    j["degenerate_tets"] = report.degenerate_tets;
    j["unreferenced_vertices"] = report.unreferenced_vertices;
    // Faces whose tag the file carried (msh / medit boundary triangles, a frame's cut mask); the
    // others got kTagSurface on reading. "boundary_tags" counts every face by its tag.
    j["boundary_faces_tagged_by_file"] = report.tagged_boundary_faces;
    std::cout << j.dump(2) << "\n";
    return;
  }
  std::cout << file << ": tetrahedral mesh (" << report.format << ")\n"
            << "  vertices               " << m.num_vertices() << "\n"
            << "  tets                   " << m.num_tets() << "\n"
            << "  boundary faces         " << faces.size() << "\n"
            << "  bounding box min       " << fmt3(lo) << "\n"
            << "  bounding box max       " << fmt3(hi) << "\n";
  char buf[64];
  std::snprintf(buf, sizeof buf, "%.9g", volume);
  std::cout << "  volume                 " << buf << "\n";
  std::snprintf(buf, sizeof buf, "%.9g", min_volume);
  std::cout << "  smallest tet volume    " << buf << "\n";
  std::cout << "  labels (tets)         ";
  for (auto [l, n] : labels) std::cout << " " << l << ":" << n;
  std::cout << "\n  boundary tags (faces) ";
  for (auto [t, n] : tags) std::cout << " " << t << ":" << n;
  std::cout << "\n  skipped cells          " << report.skipped_cells << "\n"
            << "  reoriented tets        " << report.reoriented_tets << "\n"
            << "  degenerate tets        " << report.degenerate_tets << "\n"
            << "  unreferenced vertices  " << report.unreferenced_vertices << "\n"
            << "  tags from the file     " << report.tagged_boundary_faces << " faces (the rest: 1, surface)\n";
}

void info_surface(const std::string& file, bool json) {
  SurfaceMesh s = read_surface(file);
  Vec3 lo = Vec3::Constant(std::numeric_limits<double>::infinity()), hi = -lo;
  for (const Vec3& p : s.vertices) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  double area = 0, volume = 0;
  for (const auto& t : s.triangles) {
    const Vec3 &a = s.vertices[t[0]], &b = s.vertices[t[1]], &c = s.vertices[t[2]];
    area += 0.5 * (b - a).cross(c - a).norm();
    volume += a.dot(b.cross(c)) / 6;  // divergence theorem; meaningful for a closed surface
  }
  if (json) {
    nlohmann::json j;
    j["file"] = file;
    j["kind"] = "surface";
    j["vertices"] = s.vertices.size();
    j["triangles"] = s.triangles.size();
    j["bounding_box"] = bbox_json(lo, hi);
    j["area"] = area;
    j["enclosed_volume"] = volume;
    std::cout << j.dump(2) << "\n";
    return;
  }
  char a[64], v[64];
  std::snprintf(a, sizeof a, "%.9g", area);
  std::snprintf(v, sizeof v, "%.9g", volume);
  std::cout << file << ": triangle surface\n"
            << "  vertices               " << s.vertices.size() << "\n"
            << "  triangles              " << s.triangles.size() << "\n"
            << "  bounding box min       " << fmt3(lo) << "\n"
            << "  bounding box max       " << fmt3(hi) << "\n"
            << "  area                   " << a << "\n"
            << "  enclosed volume        " << v << " (if closed)\n";
}

}  // namespace

void add_info(CLI::App& app) {
  struct Opts {
    std::string file;
    bool json = false;
  };
  auto o = std::make_shared<Opts>();
  auto* cmd = app.add_subcommand("info", "Describe a mesh file: counts, format, bounding box, volume, labels, boundary tags");
  cmd->add_option("file", o->file,
                  "Tet mesh (.msh .mesh .vtk .vtu .node/.ele) or surface (.off .obj .stl .ply .gltf ...)")
      ->required();
  cmd->add_flag("--json", o->json, "Print JSON");
  cmd->callback([o] {
    if (is_tet_mesh_path(o->file))
      info_tet(o->file, o->json);
    else
      info_surface(o->file, o->json);
  });
}

}  // namespace incise::cli
