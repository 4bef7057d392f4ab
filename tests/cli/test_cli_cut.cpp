// incise cut: progressive, plane and surface cuts from the command line, the JSON report, the
// tags in the written file, and one-line errors that leave nothing behind.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <map>
#include <string>

#include <nlohmann/json.hpp>

#include "cli_run.h"
#include "mesh/io/tet_io.h"
#include "quality/components.h"

namespace fs = std::filesystem;
using incise::testing::Run;
using incise::testing::run_incise;
using incise::testing::scratch_dir;
using incise::testing::slurp;

namespace {

double tagged_area(const incise::TetMesh& m, std::uint16_t tag) {
  double a = 0;
  for (const auto& f : m.boundary_faces())
    if (f.tag == tag)
      a += 0.5 * (m.rest(f.vertices[1]) - m.rest(f.vertices[0])).cross(m.rest(f.vertices[2]) - m.rest(f.vertices[0])).norm();
  return a;
}

double volume(const incise::TetMesh& m) {
  double v = 0;
  for (incise::TetId t : m.tets()) v += m.volume(t);
  return v;
}

}  // namespace

TEST_CASE("incise cut: a progressive through-cut of a box, JSON report and tagged faces", "[cli][cut]") {
  const fs::path dir = scratch_dir("cli_cut");
  const std::string box = (dir / "box.msh").string(), out = (dir / "cut.msh").string(), js = (dir / "cut.json").string();
  REQUIRE(run_incise("generate box --size 2 1 1 --cells 8 4 4 -o '" + box + "'", dir).code == 0);
  // An oblique blade (not on a vertex layer) spanning y, pushed down through z in 4 steps.
  Run r = run_incise("cut '" + box + "' -o '" + out + "' --blade 1.03 -0.5 1.3 0.97 1.5 1.3 --sweep 0.02 0 -1.6 --steps 4 --json '" +
                         js + "' --no-improve",
                     dir);
  INFO(r.err);
  REQUIRE(r.code == 0);
  std::ifstream in(js);
  const nlohmann::json j = nlohmann::json::parse(in);
  for (const char* k : {"tets_cut", "tets_added", "vertices_added", "vertices_duplicated", "min_dihedral_before",
                        "min_dihedral_after", "ms_total", "ms_max_step"})
    CHECK(j.contains(k));
  CHECK(j["steps"].size() == 4);
  CHECK(j["tets_cut"].get<int>() > 0);
  CHECK(j["vertices_duplicated"].get<int>() > 0);
  CHECK(j["min_dihedral_after"].get<double>() > 0);
  CHECK(j["ms_max_step"].get<double>() <= j["ms_total"].get<double>());

  const incise::TetMesh before = incise::read_tet_mesh(box);
  const incise::TetMesh m = incise::read_tet_mesh(out);
  REQUIRE_NOTHROW(m.validate({true, true}));
  CHECK(m.num_tets() == j["tets_after"].get<std::size_t>());
  CHECK(incise::tet_components(m).count == 2);  // a through-cut adds a component
  CHECK(volume(m) == Approx(volume(before)).epsilon(1e-12));
  // Both sides of the cut are tagged 2 in .msh: twice the section of the box (about 1 x 1).
  const double area = tagged_area(m, incise::kTagCut);
  CHECK(area == Approx(2 * j["cut_area"].get<double>()).epsilon(1e-9));
  CHECK(area == Approx(j["exposed_area"].get<double>()).epsilon(1e-9));
  CHECK(area > 2.0);
  CHECK(area < 2.1);
}

TEST_CASE("incise cut: partial, plane and removal cuts", "[cli][cut]") {
  const fs::path dir = scratch_dir("cli_cut_modes");
  const std::string box = (dir / "box.vtu").string();
  REQUIRE(run_incise("generate box --size 1 1 1 --cells 5 5 5 -o '" + box + "'", dir).code == 0);
  const std::string part = (dir / "partial.mesh").string();
  Run r = run_incise("cut '" + box + "' -o '" + part + "' --blade 0.52 -0.2 1.2 0.52 1.2 1.2 --sweep 0 0 -0.6 --steps 3 -q", dir);
  INFO(r.err);
  REQUIRE(r.code == 0);
  const incise::TetMesh pm = incise::read_tet_mesh(part);
  REQUIRE_NOTHROW(pm.validate({true, true}));
  CHECK(incise::tet_components(pm).count == 1);  // the front stays attached
  CHECK(tagged_area(pm, incise::kTagCut) > 0.5);

  const std::string plane = (dir / "plane.vtu").string();
  r = run_incise("cut '" + box + "' -o '" + plane + "' --plane 0.5 0.5 0.5 1 1 1", dir);
  REQUIRE(r.code == 0);
  const incise::TetMesh plm = incise::read_tet_mesh(plane);
  REQUIRE_NOTHROW(plm.validate({true, true}));
  CHECK(incise::tet_components(plm).count == 2);

  const std::string carved = (dir / "carved.msh").string();
  const std::string carved_json = (dir / "carved.json").string();
  r = run_incise("cut '" + box + "' -o '" + carved + "' --mode remove --plane 0.5 0.5 0.5 0 0 1 --json '" +
                     carved_json + "'",
                 dir);
  REQUIRE(r.code == 0);
  const incise::TetMesh cm = incise::read_tet_mesh(carved);
  REQUIRE_NOTHROW(cm.validate({true, true}));
  CHECK(cm.num_tets() < incise::read_tet_mesh(box).num_tets());
  CHECK(tagged_area(cm, incise::kTagCut) > 1.9);
  // Removal reports one side like subdivision (it once gave both walls of the channel).
  const nlohmann::json cj = nlohmann::json::parse(slurp(carved_json));
  CHECK(cj["exposed_area"].get<double>() == Approx(tagged_area(cm, incise::kTagCut)).epsilon(1e-9));
  CHECK(cj["cut_area"].get<double>() == Approx(tagged_area(cm, incise::kTagCut) / 2).epsilon(1e-9));
}

TEST_CASE("incise cut fails with one line naming the problem, and writes nothing", "[cli][cut]") {
  const fs::path dir = scratch_dir("cli_cut_bad");
  const std::string box = (dir / "box.vtu").string(), out = (dir / "out.vtu").string();
  REQUIRE(run_incise("generate box --cells 2 2 2 -o '" + box + "'", dir).code == 0);
  {
    std::ofstream bad(dir / "bad.msh");
    bad << "$MeshFormat\n4.1 0 8\n$EndMeshFormat\n$Nodes\nnonsense\n";
  }
  struct Case {
    std::string args, expect;
  };
  const Case cases[] = {
      {"'" + (dir / "missing.vtu").string() + "' -o '" + out + "' --plane 0 0 0 1 0 0", "missing.vtu"},
      {"'" + (dir / "bad.msh").string() + "' -o '" + out + "' --plane 0 0 0 1 0 0", "bad.msh:"},
      {"'" + box + "' -o '" + out + "' --plane 0 0 0 0 0 0", "normal must be a nonzero"},
      {"'" + box + "' -o '" + out + "' --blade 0 0 0 1 nan 0 --sweep 0 0 1", "finite"},
      {"'" + box + "' -o '" + out + "' --blade 0 0 0 1 1 0", "--sweep"},
      {"'" + box + "' -o '" + out + "' --plane 0 0 0 1 0 0 --blade 0 0 0 1 1 0 --sweep 0 0 1", "exactly one"},
  };
  for (const Case& c : cases) {
    Run r = run_incise("cut " + c.args, dir);
    INFO(c.args << "\n" << r.err);
    CHECK(r.code == 1);
    CHECK(r.err.find(c.expect) != std::string::npos);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    CHECK(!fs::exists(out));
  }
  // Option values out of range are caught by the option parser: one line like every error.
  for (const char* snap : {"0.7", "0.5", "-0.1", "nan"}) {
    Run r = run_incise("cut '" + box + "' -o '" + out + "' --plane 0 0 0 1 0 0 --snap " + snap, dir);
    INFO(snap << ": " << r.err);
    CHECK(r.code == 1);
    CHECK(r.err.find("incise: error: --snap") == 0);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    CHECK(!fs::exists(out));
  }
  // The rule is the library's (scenes and Python share it): [0, 0.5), so 0.49 is a snap.
  Run ok = run_incise("cut '" + box + "' -o '" + out + "' --plane 0.5 0.5 0.5 1 0 0 --snap 0.49", dir);
  CHECK(ok.code == 0);
  // --help shows the defaults.
  Run help = run_incise("cut --help", dir);
  for (const char* d : {"--snap FLOAT:in [0, 0.5)=0.05", "=subdivide", "--improve-work INT:INT in [0 - 100000000]=8"})
    CHECK(help.out.find(d) != std::string::npos);
}

TEST_CASE("incise cut --path: a blade along a curved path detaches what the path closes off", "[cli][cut]") {
  const fs::path dir = scratch_dir("cli_cut_path");
  const std::string box = (dir / "box.msh").string(), out = (dir / "cut.msh").string(), js = (dir / "cut.json").string();
  REQUIRE(run_incise("generate box --size 4 2 1 --cells 16 8 4 -o '" + box + "'", dir).code == 0);
  // A vertical blade along a half circle of radius 1 about (2.03, 0), in and out through y = 0.
  const double pi = std::acos(-1.0);
  {
    std::ofstream p(dir / "arc.path");
    p << "# blade ends per step: AX AY AZ BX BY BZ\n1.03 -0.2 -0.5 1.03 -0.2 1.5\n";
    for (int k = 0; k <= 60; ++k) {
      const double a = pi * (1 - k / 60.0), x = 2.03 + std::cos(a), y = std::sin(a);
      p << x << " " << y << " -0.5  " << x << " " << y << " 1.5\n";
    }
    p << "\n3.03 -0.2 -0.5 3.03 -0.2 1.5\n";
  }
  Run r = run_incise("cut '" + box + "' -o '" + out + "' --path '" + (dir / "arc.path").string() + "' --json '" + js + "' -q",
                     dir);
  INFO(r.err);
  REQUIRE(r.code == 0);
  std::ifstream in(js);
  const nlohmann::json j = nlohmann::json::parse(in);
  CHECK(j["fragments"].get<int>() == 1);
  CHECK(j["steps"].size() >= 62);
  const incise::TetMesh m = incise::read_tet_mesh(out);
  REQUIRE_NOTHROW(m.validate({true, true}));
  CHECK(incise::tet_components(m).count == 2);
  // The cut faces: both sides of a half-cylinder wall, about pi x 1 each.
  CHECK(tagged_area(m, incise::kTagCut) == Approx(2 * pi).epsilon(0.04));

  // Bad path files: one line naming the file and line, nothing written.
  struct Case {
    std::string text, expect;
  };
  const Case cases[] = {
      {"0 0 0 1 1 1\n", "bad.path:1: a path needs at least two"},
      {"0 0 0 1 1 1\n0 0 0 1 1\n", "bad.path:2: expected 6 numbers"},
      {"0 0 0 1 1 1\n0 0 zero 1 1 1\n", "bad.path:2: 'zero' is not a number"},
      {"0 0 0 1 1 1\n# c\n0 0 nan 1 1 1\n", "bad.path:3: coordinates must be finite"},
      {"1 1 1 1 1 1\n0 0 0 1 1 1\n", "bad.path:1: the blade's two ends are the same point"},
      {"0 0 0 1 1 1\n0 0 0 1 1 1\n", "the blade never moves"},
  };
  const std::string out2 = (dir / "out2.msh").string();
  for (const Case& c : cases) {
    {
      std::ofstream p(dir / "bad.path");
      p << c.text;
    }
    Run b = run_incise("cut '" + box + "' -o '" + out2 + "' --path '" + (dir / "bad.path").string() + "'", dir);
    INFO(c.text << "\n" << b.err);
    CHECK(b.code == 1);
    CHECK(b.err.find(c.expect) != std::string::npos);
    CHECK(std::count(b.err.begin(), b.err.end(), '\n') == 1);
    CHECK(!fs::exists(out2));
  }
  Run both = run_incise("cut '" + box + "' -o '" + out2 + "' --path '" + (dir / "arc.path").string() + "' --steps 4", dir);
  CHECK(both.code == 1);
  CHECK(both.err.find("--steps go with --blade, not --path") != std::string::npos);
}

TEST_CASE("incise cut along a plane of mesh faces opens them and does not claim it missed", "[cli][cut]") {
  const fs::path dir = scratch_dir("cli_cut_grid_plane");
  const std::string box = (dir / "b.msh").string(), out = (dir / "c.msh").string(), js = (dir / "r.json").string();
  REQUIRE(run_incise("generate box -o '" + box + "'", dir).code == 0);
  Run r = run_incise("cut '" + box + "' -o '" + out + "' --plane 0.5 0.5 0.5 1 0 0 --json '" + js + "'", dir);
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK(r.err.find("does not reach") == std::string::npos);
  std::ifstream in(js);
  const nlohmann::json j = nlohmann::json::parse(in);
  CHECK(j["cut_faces"].get<int>() > 0);
  CHECK(incise::tet_components(incise::read_tet_mesh(out)).count == 2);
  // A plane that misses says so.
  Run miss = run_incise("cut '" + box + "' -o '" + out + "' --plane 5 0.5 0.5 1 0 0", dir);
  CHECK(miss.code == 0);
  CHECK(miss.err.find("does not reach the mesh") != std::string::npos);
}

TEST_CASE("incise cut --steps N prints N steps and labels the blade's withdrawal", "[cli][cut]") {
  const fs::path dir = scratch_dir("cli_cut_finish");
  const std::string box = (dir / "box.msh").string(), out = (dir / "cut.msh").string(), js = (dir / "cut.json").string();
  REQUIRE(run_incise("generate box --size 2 1 1 --cells 8 4 4 -o '" + box + "'", dir).code == 0);
  Run r = run_incise("cut '" + box + "' -o '" + out + "' --blade 1.03 -0.5 1.3 0.97 1.5 1.3 --sweep 0.02 0 -1.6 --steps 3 --json '" + js + "'",
                     dir);
  INFO(r.err);
  REQUIRE(r.code == 0);
  for (const char* line : {"cut: step 1:", "cut: step 2:", "cut: step 3:", "cut: finish (blade withdrawn):"})
    CHECK(r.err.find(line) != std::string::npos);
  CHECK(r.err.find("cut: step 4:") == std::string::npos);
  std::ifstream in(js);
  const nlohmann::json j = nlohmann::json::parse(in);
  REQUIRE(j["steps"].size() == 4);
  CHECK(j["steps"][2]["finish"] == false);
  CHECK(j["steps"][3]["finish"] == true);
}

TEST_CASE("incise cut keeps every label's volume to rounding unless --no-exact-volumes", "[cli][cut]") {
  // The sample liver (3 labels) cut from above its middle 70% down in 10 steps: by default (and
  // with --exact-volumes) every label keeps its volume; with --no-exact-volumes the
  // improvement's tolerance contractions move the surface and the interfaces a hair.
  const fs::path dir = scratch_dir("cli_cut_exact_volumes");
  const std::string liver = std::string(INCISE_SOURCE_DIR) + "/samples/liver.msh";
  auto labels = [](const incise::TetMesh& m) {
    std::map<int, double> v;
    for (incise::TetId t : m.tets()) v[m.label(t)] += m.volume(t);
    return v;
  };
  const auto before = labels(incise::read_tet_mesh(liver));
  auto worst = [&](const std::string& flag) {
    // Appended, not operator+ chains: GCC 12 warns falsely on those (PR105329, cli_run.h).
    std::string out = (dir / "cut").string();
    if (flag.empty())
      out += "-default";
    else
      out += flag;
    out += ".vtu";
    std::string args = "cut '";
    args += liver;
    args += "' -o '";
    args += out;
    args += "' --blade 140 20 205 140 180 205 --sweep 0 0 -125 --steps 10 -q ";
    args += flag;
    const Run r = run_incise(args, dir);
    INFO(r.err);
    REQUIRE(r.code == 0);
    const auto after = labels(incise::read_tet_mesh(out));
    double w = 0, body = 0;
    for (const auto& [l, v] : before) {
      w = std::max(w, std::abs(after.at(l) - v));
      body += v;
    }
    return w / body;
  };
  const double exact = worst("--exact-volumes"), plain = worst(""), loose = worst("--no-exact-volumes");
  INFO("largest label volume change / body: " << exact << " with --exact-volumes, " << plain << " by default, "
                                              << loose << " with --no-exact-volumes");
  CHECK(exact < 1e-12);
  CHECK(plain < 1e-12);
  CHECK(loose > 1e-9);
}

namespace {
// The organ meshed from the sample image, cut from the command line along bench_cut --only
// curved-organ's half circle (radius 0.6 of its depth, entering and leaving through its low-y
// side) moved by (dx, dy) of its extent, in `steps` steps (0: a tenth of an edge each), with
// `flags`; returns the parts (sharing no vertex) holding a tet more than an edge inside and
// outside the circle (joined) and the parts on one side only (apart).
struct OrganArc {
  int joined = 0, apart = 0;
};
// The bench's half circle (shape "arc") or S (shape "S") across the organ, centre moved by dx
// and dy of its extent (bench_cut --only curved-organ, paths_at).
OrganArc cut_organ_arc(const std::string& name, double dx, double dy, int steps, const std::string& flags,
                       const std::string& shape = "arc") {
  const fs::path dir = scratch_dir(name);
  const std::string organ = (dir / "organ.vtu").string(), out = (dir / "cut.vtu").string();
  const fs::path image = fs::path(INCISE_SOURCE_DIR) / "samples" / "liver.inr.gz";
  REQUIRE(run_incise("tetra " + incise::testing::q(image) + " -o '" + organ + "' --size 1.7% -q", dir).code == 0);
  const incise::TetMesh body = incise::read_tet_mesh(organ);
  incise::Vec3 lo = incise::Vec3::Constant(1e300), hi = -lo;
  for (incise::VertexId v : body.vertices()) {
    lo = lo.cwiseMin(body.rest(v));
    hi = hi.cwiseMax(body.rest(v));
  }
  double edge = 0;
  std::size_t edges = 0;
  for (incise::TetId t : body.tets())
    for (int i = 0; i < 4; ++i)
      for (int k = i + 1; k < 4; ++k, ++edges)
        edge += (body.rest(body.tet_vertices(t)[std::size_t(i)]) - body.rest(body.tet_vertices(t)[std::size_t(k)])).norm();
  edge /= double(edges);
  const incise::Vec3 ext = hi - lo, c = 0.5 * (lo + hi);
  const double pi = std::acos(-1.0), r = 0.6 * ext.y(), y0 = lo.y() - 0.1 * ext.y() + dy * ext.y(), cx = c.x() + dx * ext.x();
  const bool s_curve = shape == "S";
  auto s_x = [&](double y) { return cx + 0.15 * ext.x() * std::sin(2 * pi * (y - y0) / (1.2 * ext.y())); };
  if (steps == 0) steps = int(std::ceil((s_curve ? 1.3 * ext.y() : pi * r) / (0.1 * edge)));
  {
    std::ofstream p(dir / "arc.path");
    p.precision(17);
    for (int k = 0; k <= steps; ++k) {
      const double t = double(k) / steps, a = pi * (1 - t);
      const double y = s_curve ? y0 + t * 1.2 * ext.y() : y0 + r * std::sin(a), x = s_curve ? s_x(y) : cx + r * std::cos(a);
      p << x << " " << y << " " << lo.z() - 0.1 * ext.z() << " " << x << " " << y << " " << hi.z() + 0.1 * ext.z() << "\n";
    }
  }
  Run run = run_incise("cut '" + organ + "' -o '" + out + "' --path '" + (dir / "arc.path").string() + "' -q " + flags, dir);
  INFO(run.err);
  REQUIRE(run.code == 0);
  const incise::TetMesh m = incise::read_tet_mesh(out);
  REQUIRE_NOTHROW(m.validate({true, true}));
  std::vector<std::uint32_t> parent(m.vertex_capacity());
  for (std::uint32_t i = 0; i < parent.size(); ++i) parent[i] = i;
  auto find = [&](std::uint32_t x) {
    while (parent[x] != x) x = parent[x] = parent[parent[x]];
    return x;
  };
  for (incise::TetId t : m.tets())
    for (int k = 1; k < 4; ++k) parent[find(m.tet_vertices(t)[std::size_t(k)].idx())] = find(m.tet_vertices(t)[0].idx());
  std::map<std::uint32_t, int> sides;  // bit 0: a tet inside by more than an edge, bit 1: outside
  for (incise::TetId t : m.tets()) {
    incise::Vec3 x = incise::Vec3::Zero();
    for (incise::VertexId v : m.tet_vertices(t)) x += m.rest(v) / 4;
    const double side = s_curve ? x.x() - s_x(x.y()) : std::hypot(x.x() - cx, x.y() - y0) - r;
    int& b = sides[find(m.tet_vertices(t)[0].idx())];
    if (side < -edge) b |= 1;
    if (side > edge) b |= 2;
  }
  OrganArc out_parts;
  for (const auto& [root, b] : sides) {
    out_parts.joined += b == 3;
    out_parts.apart += b == 1 || b == 2;
  }
  return out_parts;
}
}  // namespace

TEST_CASE("incise cut --path: a half circle through the imaged organ in 732 steps cuts it through", "[cli][cut][scale]") {
  // bench_cut --only curved-organ's half circle at a twentieth of an edge per step, on the
  // organ meshed from the sample image. At one of its creases a vertex one sheet made lay
  // within the other sheet's snap distance of it, on the far side of the crease; judged a hair
  // off the union, it left a flat tet between the two sheets joined to both sides, and the
  // organ in one piece (CutStep::crease_faces; docs/cut.md#curved-paths).
  const OrganArc a = cut_organ_arc("cli_cut_organ_arc", 0, 0, 732, "");
  CHECK(a.joined == 0);
  CHECK(a.apart >= 2);
}

TEST_CASE("incise cut --path: a face lying along a crease opens (the organ's offset half circle, no improvement)",
          "[cli][cut][scale]") {
  // The bench's sixth offset drag of the half circle (a tenth of an edge per step), without
  // the steps' improvement: at a crease a face of two crease vertices and one a hundredth of an
  // edge beside them, between tets on the two sides, lay on both sheets' union, but its
  // centroid was a hair outside both polygons (in the wedge between their planes), so neither
  // opened it and the organ stayed in one piece (CutStep::crease_faces; docs/cut.md#curved-paths).
  const OrganArc a = cut_organ_arc("cli_cut_organ_arc_offset", 3 * 0.037, 0.021, 0, "--no-improve");
  CHECK(a.joined == 0);
  CHECK(a.apart >= 2);
}

TEST_CASE("incise cut --path: a vertex a hair from a crease goes on the sheet that ends there (the organ's offset S)",
          "[cli][cut][scale]") {
  // The bench's second offset S (a tenth of an edge per step, 253 steps). At one crease an
  // original vertex lay a hair from the ending sheet's plane and from its front (the crease);
  // its star reached past the front, so the sheet kept it on its side and split its edges a
  // hair from it, and the tets between it, those splits and the crease stayed shut across both
  // sheets: the organ in one piece (CutStep::side, kCreaseFrontShare; docs/cut.md#curved-paths).
  const OrganArc a = cut_organ_arc("cli_cut_organ_s_offset", -0.037, 0, 253, "", "S");
  CHECK(a.joined == 0);
  CHECK(a.apart >= 2);
}
