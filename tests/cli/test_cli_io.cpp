// incise info / incise convert, run as a user would: exit codes, one-line errors naming the
// file, and no partial or clobbered output when a conversion fails.
#include <catch2/catch.hpp>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <nlohmann/json.hpp>
#include <sstream>

#include "mesh/generate.h"
#include "mesh/io/tet_io.h"

using namespace incise;
namespace fs = std::filesystem;

namespace {

struct IoRun {
  int rc = -1;
  std::string out, err;
};

std::string slurp(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::stringstream ss;
  ss << in.rdbuf();
  return ss.str();
}

struct Dir {
  fs::path path;
  Dir() {
    path = fs::path(INCISE_BINARY_DIR) / "cli_io_tmp" / std::to_string(::getpid());
    fs::remove_all(path);
    fs::create_directories(path);
  }
  ~Dir() {
    std::error_code ec;
    fs::remove_all(path, ec);
  }
  std::string operator/(const std::string& f) const { return (path / f).string(); }
  int temporaries() const {
    int n = 0;
    for (const auto& e : fs::directory_iterator(path))
      if (e.path().filename().string().find(".tmp") != std::string::npos) ++n;
    return n;
  }
};

IoRun run(const Dir& d, const std::string& args) {
  const std::string out = d / "stdout.txt", err = d / "stderr.txt";
  std::string cmd = std::string(INCISE_EXE) + " " + args + " > " + out + " 2> " + err;
  int status = std::system(cmd.c_str());
  IoRun r;
  r.rc = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
  r.out = slurp(out);
  r.err = slurp(err);
  fs::remove(out);
  fs::remove(err);
  return r;
}

// Exactly one line on stderr, "incise: error: FILE...".
void require_one_line_error(const IoRun& r, const std::string& file) {
  INFO("stderr: " << r.err);
  REQUIRE(r.rc == 1);
  REQUIRE(!r.err.empty());
  REQUIRE(r.err.back() == '\n');
  REQUIRE(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  REQUIRE(r.err.rfind("incise: error: " + file, 0) == 0);
}

}  // namespace

TEST_CASE("incise info on good files", "[cli][io]") {
  Dir d;
  TetMesh m = make_ellipsoid(Vec3(1, 2, 3), 2, 5);
  auto tets = m.tets();
  for (std::size_t i = 0; i < tets.size() / 3; ++i) m.set_label(tets[i], 8);
  const double volume = m.total_volume();
  for (std::string name : {"e.msh", "e.mesh", "e.vtk", "e.vtu", "e.node"}) {
    write_tet_mesh(m, d / name);
    INFO(name);
    IoRun text = run(d, "info " + (d / name));
    CHECK(text.rc == 0);
    CHECK(text.out.find("tets                   " + std::to_string(m.num_tets())) != std::string::npos);
    IoRun js = run(d, "info --json " + (d / name));
    REQUIRE(js.rc == 0);
    auto j = nlohmann::json::parse(js.out);
    CHECK(j["tets"] == m.num_tets());
    CHECK(j["vertices"] == m.num_vertices());
    CHECK(j["volume"].get<double>() == Approx(volume).epsilon(1e-12));
    CHECK(j["labels"]["8"] == tets.size() / 3);
    CHECK(j["labels"]["5"] == tets.size() - tets.size() / 3);
    CHECK(j["boundary_faces"] == m.boundary_faces().size());
    CHECK(j["bounding_box"]["max"][2].get<double>() == Approx(3.0));
    CHECK(j["reoriented_tets"] == 0);
  }
  // A surface.
  std::ofstream(d / "t.off") << "OFF\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n";
  IoRun s = run(d, "info --json " + (d / "t.off"));
  REQUIRE(s.rc == 0);
  auto j = nlohmann::json::parse(s.out);
  CHECK(j["triangles"] == 4);
  CHECK(j["enclosed_volume"].get<double>() == Approx(1.0 / 6));
  CHECK(run(d, "info --help").rc == 0);
  CHECK(run(d, "convert --help").rc == 0);
}

TEST_CASE("incise info and convert on bad files: one line, exit 1", "[cli][io]") {
  Dir d;
  std::ofstream(d / "bad.msh") << "$MeshFormat\n2.2 0 8\n$EndMeshFormat\n$Nodes\n2\n1 0 0 0\n2 nan 0 0\n$EndNodes\n";
  std::ofstream(d / "medit.msh") << "MeshVersionFormatted 2\n";
  std::ofstream(d / "garbage.vtu") << std::string("\x00\x01\x02<VTKFile\xff", 12);
  std::ofstream(d / "surface.off") << "OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n3 0 1 2\n";
  std::ofstream(d / "tris.mesh") << "MeshVersionFormatted 2\nDimension 3\nVertices\n3\n0 0 0 0\n1 0 0 0\n0 1 0 0\n"
                                    "Triangles\n1\n1 2 3 1\nEnd\n";
  IoRun r = run(d, "info " + (d / "bad.msh"));
  require_one_line_error(r, d / "bad.msh:7: ");
  CHECK(r.err.find("non-finite") != std::string::npos);
  require_one_line_error(run(d, "info " + (d / "medit.msh")), d / "medit.msh:1: ");
  require_one_line_error(run(d, "info " + (d / "garbage.vtu")), d / "garbage.vtu");
  require_one_line_error(run(d, "info " + (d / "missing.vtk")), d / "missing.vtk");
  require_one_line_error(run(d, "info " + (d / "tris.mesh")), d / "tris.mesh");
  require_one_line_error(run(d, "convert " + (d / "surface.off") + " " + (d / "x.msh")), d / "surface.off");
  CHECK_FALSE(fs::exists(d / "x.msh"));
}

TEST_CASE("a mesh with overlapping tets is refused by every command that reads it", "[cli][io]") {
  Dir d;
  // A generated box and a tet spanning it from a corner (it shares corners, no face).
  TetMesh m = make_box(Vec3(1, 1, 1), {2, 2, 2});
  auto corner = [&](const Vec3& p) {
    for (VertexId v : m.vertices())
      if ((m.rest(v) - p).norm() < 1e-12) return v;
    return VertexId();
  };
  m.add_tet(corner(Vec3(0, 0, 0)), corner(Vec3(1, 0, 0)), corner(Vec3(0, 1, 0)), corner(Vec3(0, 0, 1)));
  write_tet_mesh(m, d / "span.mesh");
  std::ofstream(d / "scene.json") << R"({"mesh": "span.mesh", "model": "fem-linear",
    "materials": {"*": {"young": 1e5, "poisson": 0.3}}, "fixed": [{"box": [-0.01, -0.01, -0.01, 0.01, 1.01, 1.01]}],
    "loads": [{"type": "gravity", "g": [0, 0, -9.81]}], "time": {"frames": 2}})";
  for (const std::string& cmd : {"info " + (d / "span.mesh"), "quality " + (d / "span.mesh"),
                                "convert " + (d / "span.mesh") + " " + (d / "x.vtu"),
                                "cut " + (d / "span.mesh") + " -o " + (d / "x.vtu") + " --plane 0.5 0.5 0.5 1 0 0",
                                "simulate " + (d / "scene.json") + " -o " + (d / "run")}) {
    INFO(cmd);
    const IoRun r = run(d, cmd);
    require_one_line_error(r, d / "span.mesh:");
    CHECK(r.err.find("overlaps tet #") != std::string::npos);
  }
  CHECK_FALSE(fs::exists(d / "x.vtu"));
  CHECK_FALSE(fs::exists(d / "run"));
}

TEST_CASE("incise convert: every direction, and failures leave no trace", "[cli][io]") {
  Dir d;
  TetMesh m = make_box(Vec3(2, 1, 1), {3, 2, 2}, 4);
  auto tets = m.tets();
  for (std::size_t i = 0; i < tets.size(); i += 2) m.set_label(tets[i], 11);
  write_tet_mesh(m, d / "src.msh");
  const std::vector<std::pair<std::string, std::string>> outs = {
      {"a.mesh", ""}, {"a.vtk", ""}, {"b.vtk", "--binary"}, {"a.vtu", ""}, {"b.vtu", "--binary"},
      {"c.vtu", "--big-endian"}, {"d.vtu", "--binary --header64"}, {"a.node", ""}, {"a.msh", "--no-boundary"}};
  for (const auto& [name, flags] : outs) {
    INFO(name << " " << flags);
    IoRun r = run(d, "convert " + (d / "src.msh") + " " + (d / name) + " " + flags);
    REQUIRE(r.rc == 0);
    TetMesh back = read_tet_mesh(d / name);
    REQUIRE(back.num_tets() == m.num_tets());
    auto tb = back.tets();
    for (std::size_t i = 0; i < tets.size(); ++i) REQUIRE(back.label(tb[i]) == m.label(tets[i]));
    // And from that format back to msh.
    REQUIRE(run(d, "convert " + (d / name) + " " + (d / ("back_" + name + ".msh"))).rc == 0);
    CHECK(read_tet_mesh(d / ("back_" + name + ".msh")).num_tets() == m.num_tets());
  }
  CHECK(slurp(d / "c.vtu").find("BigEndian") != std::string::npos);
  // Renumbered along the curve: the same tets (labels, volume), in another order.
  REQUIRE(run(d, "convert " + (d / "src.msh") + " " + (d / "z.vtu") + " --spatial-order").rc == 0);
  {
    TetMesh z = read_tet_mesh(d / "z.vtu");
    REQUIRE(z.num_tets() == m.num_tets());
    CHECK(z.total_volume() == Approx(m.total_volume()).epsilon(1e-12));
    std::multiset<int> la, lb;
    for (TetId t : m.tets()) la.insert(m.label(t));
    for (TetId t : z.tets()) lb.insert(z.label(t));
    CHECK(la == lb);
    z.validate({true, true});
  }
  // Boundary as a surface.
  REQUIRE(run(d, "convert " + (d / "src.msh") + " " + (d / "boundary.stl")).rc == 0);
  REQUIRE(run(d, "info --json " + (d / "boundary.stl")).rc == 0);

  // A failed conversion does not clobber an existing destination, nor leave temporaries.
  std::ofstream(d / "bad.vtk") << "# vtk DataFile Version 4.2\nx\nASCII\nDATASET UNSTRUCTURED_GRID\nPOINTS 2 double\n0 0\n";
  const std::string before = slurp(d / "a.vtu");
  IoRun r = run(d, "convert " + (d / "bad.vtk") + " " + (d / "a.vtu"));
  require_one_line_error(r, d / "bad.vtk");
  CHECK(slurp(d / "a.vtu") == before);
  IoRun r2 = run(d, "convert " + (d / "bad.vtk") + " " + (d / "fresh.vtu"));
  require_one_line_error(r2, d / "bad.vtk");
  CHECK_FALSE(fs::exists(d / "fresh.vtu"));
  IoRun r3 = run(d, "convert " + (d / "src.msh") + " " + (d / "no_dir/x.vtu"));
  require_one_line_error(r3, d / "no_dir/x.vtu");
  IoRun r4 = run(d, "convert " + (d / "src.msh") + " " + (d / "x.unknown"));
  require_one_line_error(r4, d / "x.unknown");
  CHECK(d.temporaries() == 0);
  // Usage errors exit 1 too.
  CHECK(run(d, "convert " + (d / "src.msh")).rc == 1);
}

TEST_CASE("first hour: one wording for a missing file, info says which tags came from the file", "[cli][io]") {
  Dir d;
  for (const std::string& cmd : {"info " + (d / "missing.vtk"), "quality " + (d / "missing.msh"),
                                "simulate " + (d / "missing.json") + " -o " + (d / "run"),
                                "prepare " + (d / "missing.off") + " -o " + (d / "x.vtu")}) {
    INFO(cmd);
    const IoRun r = run(d, cmd);
    CHECK(r.rc == 1);
    CHECK(r.err.find("missing.") != std::string::npos);
    CHECK(r.err.find(": no such file\n") != std::string::npos);
  }
  write_tet_mesh(make_box(Vec3(1, 1, 1), {1, 1, 1}), d / "b.vtu");
  const IoRun j = run(d, "info --json " + (d / "b.vtu"));
  REQUIRE(j.rc == 0);
  const auto info = nlohmann::json::parse(j.out);
  CHECK(info["boundary_tags"]["1"] == 12);
  CHECK(info["boundary_faces_tagged_by_file"] == 0);  // a VTU carries no boundary triangles
  CHECK(run(d, "info " + (d / "b.vtu")).out.find("tags from the file     0 faces") != std::string::npos);
}

TEST_CASE("what prepare writes reads back: the improvement's sub-percent tangles are below the overlap tolerance",
          "[cli][io]") {
  // The liver at 1.7%: the improvement left two tets, sharing no vertex, pressed 0.65% of an edge
  // into each other near the boundary; the readers' overlap check tolerates 2% (mesh/overlap.h),
  // so incise reads its own output (it refused it at a tolerance of 1e-7).
  Dir d;
  const std::string out = d / "liver.vtu";
  const IoRun p = run(d, "prepare " + std::string(INCISE_SOURCE_DIR) + "/samples/liver.inr.gz -o " + out + " --size 1.7% -q");
  REQUIRE(p.rc == 0);
  const IoRun i = run(d, "info " + out);
  INFO(i.err);
  CHECK(i.rc == 0);
}

TEST_CASE("first hour: a user's cut scene runs to the end, every frame reads back, inverted tets are counted",
          "[cli][io]") {
  // Issue 39's recipe, the README's first scene: the liver prepared at 2%, held on the left, a probe pushing the right end
  // down 20 mm, a blade cutting down through the middle over frames 10-30. Frames after the cut
  // hold a tet inverted in the deformed shape (at the cut's faces); incise reads every frame all
  // the same, and stats.csv and the summary say how many tets were inverted.
  Dir d;
  const std::string mesh = d / "liver.vtu";
  REQUIRE(run(d, "prepare " + std::string(INCISE_SOURCE_DIR) + "/samples/liver.inr.gz -o " + mesh + " --size 2% -q").rc == 0);
  {
    std::ofstream s(d / "scene.json");
    s << R"({"units": "mm", "mesh": "liver.vtu", "model": "fem-corotational", "formulation": "nodal-averaged",
  "materials": {"*": {"young": 0.003, "poisson": 0.45, "density": 1e-9}},
  "fixed": [{"box": [0, 0, 0, 70, 250, 250]}],
  "loads": [{"type": "gravity", "g": [0, 0, -9810]},
            {"type": "probe", "box": [215, 0, 0, 260, 250, 250], "displacement": [0, 0, -20], "from_frame": 0, "to_frame": 10}],
  "cuts": [{"blade": [[140, 40, 210], [140, 180, 210]], "sweep": [0, 0, -120], "from_frame": 10, "to_frame": 30}],
  "time": {"frames": 40}})";
  }
  const IoRun r = run(d, "simulate " + (d / "scene.json") + " -o " + (d / "run") + " -q");
  INFO(r.err);
  REQUIRE(r.rc == 0);
  // In one unit system, as it states: no warning but the one about a slow frame, which depends
  // on the machine's load (a timing, not what this test asks).
  {
    std::stringstream lines(r.err);
    for (std::string l; std::getline(lines, l);)
      if (l.find("warning") != std::string::npos) CHECK(l.find("not interactive") != std::string::npos);
  }
  std::ifstream csv(d / "run/stats.csv");
  std::string line;
  std::getline(csv, line);
  std::vector<std::string> cols;
  for (std::stringstream ss(line); std::getline(ss, line, ',');) cols.push_back(line);
  const auto col = std::find(cols.begin(), cols.end(), "inverted") - cols.begin();
  REQUIRE(col < long(cols.size()));
  int frames = 0, with = 0, most = 0;
  while (std::getline(csv, line)) {
    std::vector<std::string> f;
    for (std::stringstream ss(line); std::getline(ss, line, ',');) f.push_back(line);
    const int inverted = std::stoi(f[col]);
    with += inverted > 0;
    most = std::max(most, inverted);
    char name[32];
    std::snprintf(name, sizeof name, "run/frame_%04d.vtu", frames++);
    INFO(name);
    CHECK_NOTHROW(read_tet_mesh(d / name));
  }
  CHECK(frames == 40);
  CHECK(with > 0);  // what the count is for: this scene has some
  const std::string expect = std::to_string(with) + " frames with inverted tets (at most " + std::to_string(most) + ")";
  CHECK(r.out.find(expect) != std::string::npos);

  // The inversion barrier with two relinearizations a frame (docs/solver.md#inversion-barrier-inversion_barrier-in-scenes):
  // at most the frame a cut step inverts a tet first, and the next. With the multigrid, not the
  // background Cholesky factor (which lands when it is ready), so that the run is the same on
  // every machine however busy (docs/scene.md#recorded-input): the cut is made on the deformed
  // shape, and one tet more or less at the blade's last step had changed the count.
  {
    std::string text = slurp(d / "scene.json");
    text.insert(text.rfind('}'),
                R"(, "inversion_barrier": true, "solver": {"nonlinear_iterations": 2, "preconditioner": "amg"})");
    std::ofstream(d / "held.json") << text;
  }
  const IoRun h = run(d, "simulate " + (d / "held.json") + " -o " + (d / "held") + " -q --json");
  INFO(h.err);
  REQUIRE(h.rc == 0);
  const auto summary = nlohmann::json::parse(h.out);
  CHECK(summary["frames_with_inverted"].get<int>() <= 2);
  CHECK(summary["frames_with_inverted"].get<int>() < with);
  // Each scene cut says what it did, in the summary and its JSON.
  REQUIRE(summary["cuts"].size() == 1);
  CHECK(summary["cuts"][0]["tets_cut"].get<int>() > 100);
  CHECK(summary["cuts"][0]["faces_opened"].get<int>() > 100);
  CHECK(summary["cuts"][0]["parts"] == 0);  // the blade stops 120 mm down: nothing detached
  CHECK(r.out.find("simulate: cuts[0]: ") != std::string::npos);
  CHECK(r.out.find(" faces opened, 0 parts detached\n") != std::string::npos);
}
