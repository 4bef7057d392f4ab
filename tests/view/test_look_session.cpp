// Look mode (view/look_session.h): what it draws is checked against independent counts on the
// mesh (boundary faces, the worst elements' faces), a run directory's frames against the
// positions they were written with, and bad arguments against their errors.
#include <catch2/catch.hpp>

#include <filesystem>
#include <fstream>
#include <set>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include "mesh/errors.h"
#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "quality/report.h"
#include "scene/run_scene.h"
#include "view/boundary_tracker.h"
#include "view/look_session.h"

using namespace incise;
using namespace incise::view;
namespace fs = std::filesystem;

namespace {

struct TempDir {
  fs::path path;
  TempDir() {
    path = fs::path(INCISE_BINARY_DIR) / "look_session_tmp" / std::to_string(::getpid());
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~TempDir() { fs::remove_all(path); }
};

void write(const fs::path& p, const std::string& text) { std::ofstream(p) << text; }

std::size_t boundary_faces(const TetMesh& m) {
  std::size_t n = 0;
  for (TetId t : m.tets())
    for (int f = 0; f < 4; ++f) n += !m.neighbor(t, f).is_valid();
  return n;
}

std::size_t interior_faces(const TetMesh& m, const std::vector<int>& tets) {
  std::size_t n = 0;
  for (int t : tets)
    for (int f = 0; f < 4; ++f) n += m.neighbor(TetId(std::uint32_t(t)), f).is_valid();
  return n;
}

std::size_t drawn(const Snapshot& s, std::uint32_t flag = 0) {
  std::size_t n = 0;
  for (std::size_t i = 0; i + 3 < s.tris.size(); i += 4)
    if (s.tris[i] != kNoSlot && (flag == 0 || (s.tris[i + 3] & flag))) ++n;
  return n;
}

}  // namespace

TEST_CASE("look mode draws a mesh's boundary and its worst elements, computed or from a report") {
  const std::string liver = std::string(INCISE_SOURCE_DIR) + "/samples/liver.msh";
  const TetMesh mesh = read_tet_mesh(liver);
  QualityOptions qo;
  qo.worst_count = LookSession::kWorstCount;
  std::vector<int> worst;
  for (const WorstElement& w : compute_quality_report(mesh, qo).worst) worst.push_back(int(w.tet.idx()));

  auto look = LookSession::open_mesh(liver);
  auto snap = look->snapshot();
  const std::size_t expected = boundary_faces(mesh) + interior_faces(mesh, worst);
  CHECK(snap->triangles == expected);
  CHECK(drawn(*snap) == expected);
  CHECK(drawn(*snap, kTriangleWorst) == 4 * worst.size());  // every face of every worst tet
  const auto status = nlohmann::json::parse(look->status_json());
  CHECK(status["mode"] == "look");
  CHECK(status["worst"].get<std::vector<int>>() == worst);

  // Labels as colours: one value per triangle, the labels the mesh has.
  REQUIRE(look->post({InputKind::Colour, {}, 3}).empty());
  snap = look->snapshot();
  std::set<int> labels_drawn, labels;
  for (std::size_t i = 0; i < snap->scalars.size(); ++i)
    if (snap->tris[4 * i] != kNoSlot) labels_drawn.insert(int(snap->scalars[i]));
  for (TetId t : mesh.tets()) labels.insert(mesh.label(t));
  CHECK(labels_drawn == labels);
  CHECK_FALSE(look->post({InputKind::Colour, {}, 1}).empty());      // no stresses here
  CHECK_FALSE(look->post({InputKind::BladeStart, {0, 0, 0, 1, 1, 1}}).empty());
  CHECK_FALSE(look->post({InputKind::Frame, {}, 1}).empty());        // one frame only

  // A report's worst list is what gets highlighted (found beside the report).
  TempDir dir;
  fs::copy_file(liver, dir.path / "liver.msh");
  const std::vector<int> picked = {5, 17, 300};
  write(dir.path / "report.json",
        nlohmann::json{{"schema", "incise.quality/1"}, {"file", "liver.msh"},
                       {"worst", {{"elements", {{{"tet", 5}}, {{"tet", 17}}, {{"tet", 300}}}}}}}
            .dump());
  CHECK(classify_view_argument((dir.path / "report.json").string()) == ViewArgument::Report);
  auto from_report = LookSession::open_report((dir.path / "report.json").string());
  CHECK(nlohmann::json::parse(from_report->status_json())["worst"].get<std::vector<int>>() == picked);
  CHECK(from_report->snapshot()->triangles == boundary_faces(mesh) + interior_faces(mesh, picked));
  // A report without "file" named NAME.quality.json (an older `incise prepare`'s) is NAME's.
  write(dir.path / "liver.quality.json", nlohmann::json{{"schema", "incise.quality/1"}}.dump());
  auto beside = LookSession::open_report((dir.path / "liver.quality.json").string());
  CHECK(beside->snapshot()->tets == mesh.num_tets());
  write(dir.path / "other.json", nlohmann::json{{"schema", "incise.quality/1"}, {"file", "nowhere.msh"}}.dump());
  CHECK_THROWS_AS(LookSession::open_report((dir.path / "other.json").string()), IoError);
}

TEST_CASE("a run directory's frames are shown one at a time, at the positions they were written with") {
  TempDir dir;
  TetMesh a = make_box(Vec3(1, 1, 1), {2, 2, 2});
  TetMesh b = a;
  const Vec3 shift(0.25, 0, -0.5);
  for (VertexId v : b.vertices()) b.set_rest(v, b.rest(v) + shift);
  write_tet_mesh(a, (dir.path / "frame_0000.vtu").string());
  write_tet_mesh(b, (dir.path / "frame_0001.vtu").string());
  write(dir.path / "frames.pvd",
        "<VTKFile type=\"Collection\">\n<Collection>\n"
        "    <DataSet timestep=\"0\" group=\"\" part=\"0\" file=\"frame_0000.vtu\"/>\n"
        "    <DataSet timestep=\"0.5\" group=\"\" part=\"0\" file=\"frame_0001.vtu\"/>\n</Collection>\n</VTKFile>\n");
  write(dir.path / "stats.csv", "frame,time,max_displacement\n0,0,0\n1,0.5,0.56\n");
  CHECK(classify_view_argument(dir.path.string()) == ViewArgument::Run);

  auto run = LookSession::open_run(dir.path.string());
  REQUIRE(run->frame_count() == 2);
  const auto s0 = run->snapshot();
  const auto status = nlohmann::json::parse(run->status_json());
  CHECK(status["mode"] == "run");
  CHECK(status["stats"]["columns"].size() == 3);
  CHECK(status["stats"]["rows"][1][2].get<double>() == Approx(0.56));
  REQUIRE(run->post({InputKind::Frame, {}, 1}).empty());
  const auto s1 = run->snapshot();
  CHECK(s1->frame == 1);
  CHECK(nlohmann::json::parse(run->status_json())["time"].get<double>() == Approx(0.5));
  // Same triangles: the page keeps its slots, and every drawn vertex moved by exactly the shift.
  CHECK(s1->generation == s0->generation);
  CHECK(s1->tris == s0->tris);
  for (std::size_t i = 0; i < s0->positions.size(); i += 3) {
    if (std::isnan(s0->positions[i])) continue;
    for (int k = 0; k < 3; ++k) CHECK(s1->positions[i + k] - s0->positions[i + k] == Approx(shift[k]).margin(1e-6));
  }
  CHECK_FALSE(run->post({InputKind::Frame, {}, 2}).empty());

  // A frame outside the directory, a directory without a series, a missing path.
  write(dir.path / "frames.pvd", "<DataSet timestep=\"0\" file=\"../frame_0000.vtu\"/>\n");
  CHECK_THROWS_AS(LookSession::open_run(dir.path.string()), IoError);
  fs::remove(dir.path / "frames.pvd");
  CHECK_THROWS_AS(classify_view_argument(dir.path.string()), IoError);
  CHECK_THROWS_AS(classify_view_argument((dir.path / "nothing.msh").string()), IoError);
  write(dir.path / "broken.json", "{ not json");
  CHECK_THROWS_AS(classify_view_argument((dir.path / "broken.json").string()), IoError);
}

TEST_CASE("a damaged frame of a run is an error for the page, and links out of the run are refused") {
  TempDir dir;
  const TetMesh a = make_box(Vec3(1, 1, 1), {2, 2, 2});
  write_tet_mesh(a, (dir.path / "frame_0000.vtu").string());
  {  // Random bytes, invalid UTF-8 among them, where frame 1 should be.
    std::ofstream f(dir.path / "frame_0001.vtu", std::ios::binary);
    for (int i = 0; i < 4096; ++i) f.put(char((i * 7919 + 13) % 256));
  }
  const std::string pvd = "<VTKFile type=\"Collection\">\n<Collection>\n"
                          "    <DataSet timestep=\"0\" file=\"frame_0000.vtu\"/>\n"
                          "    <DataSet timestep=\"1\" file=\"frame_0001.vtu\"/>\n</Collection>\n</VTKFile>\n";
  write(dir.path / "frames.pvd", pvd);
  auto run = LookSession::open_run(dir.path.string());
  const std::string err = run->post({InputKind::Frame, {}, 1});
  CHECK_FALSE(err.empty());  // the page gets an error frame; the view stays on frame 0
  CHECK(run->snapshot()->frame == 0);
  CHECK_NOTHROW(nlohmann::json::parse(run->status_json()));
  // A frame or stats.csv linked to a file outside the run directory.
  struct Other {
    fs::path path;
    ~Other() { fs::remove_all(path); }
  } other{dir.path.parent_path() / (dir.path.filename().string() + "_elsewhere")};
  fs::create_directories(other.path);
  write_tet_mesh(a, (other.path / "elsewhere.vtu").string());
  fs::remove(dir.path / "frame_0001.vtu");
  fs::create_symlink(other.path / "elsewhere.vtu", dir.path / "frame_0001.vtu");
  CHECK_THROWS_WITH(LookSession::open_run(dir.path.string()), Catch::Contains("links out of the run directory"));
  fs::remove(dir.path / "frame_0001.vtu");
  write_tet_mesh(a, (dir.path / "frame_0001.vtu").string());
  write(other.path / "shells", "/bin/sh\n");
  fs::create_symlink(other.path / "shells", dir.path / "stats.csv");
  auto linked = LookSession::open_run(dir.path.string());
  CHECK(nlohmann::json::parse(linked->status_json())["stats"].dump().find("/bin/sh") == std::string::npos);
}

TEST_CASE("a run with cuts shows its cut faces and its von Mises stress in look mode") {
  TempDir dir;
  const Scene scene = parse_scene(R"({
    "mesh": {"generate": "box", "size": [4, 1, 1], "cells": [8, 2, 2]},
    "model": "fem-linear",
    "materials": {"*": {"young": 1e4, "poisson": 0.3}},
    "fixed": [{"box": [-0.01, -1, -1, 0.01, 2, 2]}],
    "loads": [{"type": "gravity", "g": [0, 0, -0.001]}],
    "cuts": [{"blade": [[2.1, -0.5, 1.2], [2.1, 1.5, 1.2]], "sweep": [0, 0, -0.7], "from_frame": 1, "to_frame": 2}],
    "solver": {"method": "direct"},
    "time": {"frames": 3}})", "beam.json");
  SceneRunOptions ro;
  ro.out_dir = (dir.path / "run").string();
  std::size_t cut_faces = 0;
  run_scene(scene, ro);
  const TetMesh last = read_tet_mesh((dir.path / "run" / "frame_0002.vtu").string());
  for (TetId t : last.tets())
    for (int f = 0; f < 4; ++f) cut_faces += !last.neighbor(t, f).is_valid() && last.face_tag(t, f) == kTagCut;
  REQUIRE(cut_faces > 0);
  auto run = LookSession::open_run((dir.path / "run").string());
  CHECK(run->snapshot()->cut_triangles == 0);  // frame 0: before the blade
  // Von Mises colours from the frame's field (the run is FEM).
  CHECK(nlohmann::json::parse(run->status_json())["von_mises"] == true);
  REQUIRE(run->post({InputKind::Frame, {}, 2}).empty());
  CHECK(run->snapshot()->cut_triangles == cut_faces);
  REQUIRE(run->post({InputKind::Colour, {}, 1}).empty());
  const auto s = run->snapshot();
  REQUIRE(!s->scalars.empty());
  CHECK(s->scalar_hi > s->scalar_lo);
  CHECK(s->scalar_lo >= 0);
}
