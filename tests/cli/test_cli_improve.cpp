// incise improve: a jittered two-label mesh comes out better, with labels, volumes and the
// JSON report; bad input fails with one line naming the file.
#include <catch2/catch.hpp>

#include <map>

#include <nlohmann/json.hpp>

#include "mesh/generate.h"
#include "mesh/io/tet_io.h"
#include "quality/metrics.h"
#include "tests/cli/cli_run.h"
#include "testing/mesh_edits.h"

using namespace incise;
using incise::testing::Run;
using incise::testing::run_incise;
using incise::testing::scratch_dir;
using incise::testing::slurp;

namespace {

std::map<int, double> label_volumes(const TetMesh& m) {
  std::map<int, double> v;
  for (TetId t : m.tets()) v[m.label(t)] += m.volume(t);
  return v;
}

double min_dihedral(const TetMesh& m) {
  double d = 180;
  for (TetId t : m.tets()) d = std::min(d, tet_quality(m, t).min_dihedral);
  return d;
}

}  // namespace

TEST_CASE("incise improve on a jittered two-label box", "[cli][improve]") {
  const auto dir = scratch_dir("cli_improve");
  TetMesh m = make_box(Vec3(1, 1, 1), {4, 4, 4});
  for (TetId t : m.tets())
    if (m.rest(m.tet_vertices(t)[0]).z() > 0.6) m.set_label(t, 3);
  testing::jitter(m, 0.35, 17);
  const std::string in = (dir / "in.vtu").string(), out = (dir / "out.msh").string(),
                    json = (dir / "report.json").string();
  write_tet_mesh(m, in);
  Run r = run_incise("improve '" + in + "' -o '" + out + "' --json '" + json + "' --time-limit 30 --keep-surface", dir);
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("min dihedral") != std::string::npos);
  const TetMesh back = read_tet_mesh(out);
  REQUIRE_NOTHROW(back.validate());
  const auto before = label_volumes(m), after = label_volumes(back);
  REQUIRE(after.size() == 2);
  for (const auto& [l, v] : before) CHECK(after.at(l) == Approx(v).epsilon(1e-9));
  CHECK(min_dihedral(back) > min_dihedral(m));
  const nlohmann::json j = nlohmann::json::parse(slurp(json));
  CHECK(j["schema"] == "incise.improve/1");
  CHECK(j["before"]["min_dihedral"].get<double>() == Approx(min_dihedral(m)));
  CHECK(j["after"]["min_dihedral"].get<double>() == Approx(min_dihedral(back)).margin(1e-6));
  CHECK(j["after"]["tets"].get<std::size_t>() == back.num_tets());

  // By default interface vertices also slide on the (jittered, curved) interface: the box's
  // flat boundary keeps the total volume, the labels' volumes move a little.
  const std::string out2 = (dir / "out2.vtu").string();
  Run r2 = run_incise("improve '" + in + "' -o '" + out2 + "'", dir);
  REQUIRE(r2.code == 0);
  const TetMesh back2 = read_tet_mesh(out2);
  const auto after2 = label_volumes(back2);
  CHECK(after2.at(1) + after2.at(3) == Approx(before.at(1) + before.at(3)).epsilon(1e-9));
  for (const auto& [l, v] : before) CHECK(after2.at(l) == Approx(v).epsilon(1e-2));
  CHECK(min_dihedral(back2) > min_dihedral(m));
}

TEST_CASE("incise improve: bad input and bad options", "[cli][improve]") {
  const auto dir = scratch_dir("cli_improve_bad");
  const std::string missing = (dir / "missing.vtu").string();
  Run r = run_incise("improve '" + missing + "' -o '" + (dir / "o.vtu").string() + "'", dir);
  CHECK(r.code == 1);
  CHECK(r.err.find("missing.vtu") != std::string::npos);
  CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
  CHECK_FALSE(std::filesystem::exists(dir / "o.vtu"));
  const std::string in = (dir / "box.vtu").string();
  write_tet_mesh(make_box(Vec3(1, 1, 1), {1, 1, 1}), in);
  Run t = run_incise("improve '" + in + "' -o '" + (dir / "o.vtu").string() + "' --target-dihedral 80", dir);
  CHECK(t.code == 1);
  CHECK(t.err.find("target") != std::string::npos);
}

TEST_CASE("incise improve keeps each label's volume within --volume-tolerance on the sample liver",
          "[cli][improve]") {
  // The liver is curved everywhere: unlimited curved sliding moved a label by 1.5%, while
  // --help promised the surface kept. Volumes are measured here from the files.
  const auto dir = scratch_dir("cli_improve_volume");
  const std::string in = std::string(INCISE_SOURCE_DIR) + "/samples/liver.msh";
  const TetMesh m = read_tet_mesh(in);
  const auto before = label_volumes(m);
  auto largest_change = [&](const TetMesh& out) {
    const auto after = label_volumes(out);
    double worst = 0;
    for (const auto& [l, v] : before) worst = std::max(worst, std::abs(after.at(l) - v) / v);
    return worst;
  };
  const std::string out = (dir / "default.msh").string(), json = (dir / "default.json").string();
  Run r = run_incise("improve '" + in + "' -o '" + out + "' --json '" + json + "'", dir);
  INFO(r.err);
  REQUIRE(r.code == 0);
  const double moved = largest_change(read_tet_mesh(out));
  CHECK(moved <= 1e-4 * (1 + 1e-9));
  CHECK(nlohmann::json::parse(slurp(json))["label_volume_change"].get<double>() == Approx(moved).margin(1e-12));
  CHECK(r.out.find("label volumes moved by at most") != std::string::npos);

  const std::string loose = (dir / "loose.msh").string();
  Run u = run_incise("improve '" + in + "' -o '" + loose + "' --volume-tolerance 1", dir);
  REQUIRE(u.code == 0);
  CHECK(largest_change(read_tet_mesh(loose)) > 1e-3);  // what the limit prevents

  for (const char* bad : {"-1", "2", "nan"}) {
    Run b = run_incise("improve '" + in + "' -o '" + (dir / "bad.msh").string() + "' --volume-tolerance " + bad, dir);
    CHECK(b.code == 1);
    CHECK(b.err.find("--volume-tolerance") != std::string::npos);
    CHECK_FALSE(std::filesystem::exists(dir / "bad.msh"));
  }
}

TEST_CASE("incise improve --insert says when --max-growth stopped it, the reshaping options refuse bad values",
          "[cli][improve]") {
  const auto dir = scratch_dir("cli_improve_growth");
  const std::string in = std::string(INCISE_SOURCE_DIR) + "/samples/elephant.msh";
  const std::string json = (dir / "capped.json").string();
  Run c = run_incise("improve '" + in + "' -o '" + (dir / "capped.msh").string() + "' --insert --max-growth 1 --json '" +
                         json + "'",
                     dir);
  INFO(c.err);
  REQUIRE(c.code == 0);
  CHECK(c.out.find("stopped by the growth cap (--max-growth)") != std::string::npos);
  const auto j = nlohmann::json::parse(slurp(json));
  CHECK(j["growth_capped"].get<bool>());
  CHECK(j["operations"].contains("surface_flips"));
  CHECK(j["operations"].contains("feature_slides"));
  Run f = run_incise("improve '" + in + "' -o '" + (dir / "free.msh").string() + "' --insert --max-growth 3", dir);
  REQUIRE(f.code == 0);
  CHECK(f.out.find("stopped by the growth cap") == std::string::npos);
  for (const char* bad : {"--feature-line-angle -1", "--surface-flip-deviation 2", "--max-slides -1"}) {
    Run b = run_incise("improve '" + in + "' -o '" + (dir / "bad.msh").string() + "' " + bad, dir);
    CHECK(b.code == 1);
    CHECK(b.err.find(std::string(bad).substr(0, std::string(bad).find(' '))) != std::string::npos);
    CHECK(std::count(b.err.begin(), b.err.end(), '\n') == 1);
    CHECK_FALSE(std::filesystem::exists(dir / "bad.msh"));
  }
}

TEST_CASE("incise improve --max-work stops after that many operations, the same mesh every run", "[cli][improve]") {
  const auto dir = scratch_dir("cli_improve_work");
  TetMesh m = make_box(Vec3(1, 1, 1), {5, 5, 5});
  testing::jitter(m, 0.4, 5);
  const std::string in = (dir / "in.msh").string();
  write_tet_mesh(m, in);
  auto run = [&](const std::string& out, const std::string& args) {
    const std::string json = (dir / (out + ".json")).string();
    Run r = run_incise("improve '" + in + "' -o '" + (dir / out).string() + "' --json '" + json + "' --insert " + args, dir);
    INFO(r.err);
    REQUIRE(r.code == 0);
    return nlohmann::json::parse(slurp(json));
  };
  const auto a = run("a.msh", "--max-work 40 --time-limit 0");
  const auto b = run("b.msh", "--max-work 40 --time-limit 0");
  const auto all = run("all.msh", "--time-limit 0");
  CHECK(a["budget_exhausted"] == true);
  CHECK(a["work"].get<int>() >= 40);
  CHECK(all["work"].get<int>() > a["work"].get<int>());
  CHECK(slurp((dir / "a.msh").string()) == slurp((dir / "b.msh").string()));
  CHECK(slurp((dir / "a.msh").string()) != slurp((dir / "all.msh").string()));
  // A bad count is refused with one line, nothing written.
  Run bad = run_incise("improve '" + in + "' -o '" + (dir / "c.msh").string() + "' --max-work -3", dir);
  CHECK(bad.code != 0);
  CHECK_FALSE(std::filesystem::exists(dir / "c.msh"));
}
