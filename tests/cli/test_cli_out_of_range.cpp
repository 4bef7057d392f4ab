// Issue 18, part 2: a value out of range is an error naming the option (one line, exit 1,
// nothing written), never a different meaning (unlimited, disabled, a clamped index).
#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include "cli_run.h"
#include "mesh/io/tet_io.h"
#include "mesh/memory_limit.h"

namespace fs = std::filesystem;
using namespace incise::testing;

namespace {


struct Case {
  std::string args, expect;
};

}  // namespace

TEST_CASE("improve and cut: time limits out of range are errors", "[cli][options]") {
  const fs::path dir = scratch_dir("cli_range_time");
  const fs::path box = dir / "box.msh", out = dir / "out.msh";
  REQUIRE(run_incise("generate box --cells 1 1 1 -o " + q(box), dir).code == 0);
  const std::string improve = "improve " + q(box) + " -o " + q(out) + " --time-limit ";
  const std::string cut = "cut " + q(box) + " -o " + q(out) + " -q --plane 0.5 0.5 0.5 1 0 0 --improve-budget-ms ";
  for (const std::string v : {"-1", "nan", "inf", "1e300"}) {
    check_failed(run_incise(improve + v, dir), "--time-limit");
    check_failed(run_incise(cut + v, dir), "--improve-budget-ms");
  }
  check_failed(run_incise(cut + "-5", dir), "--improve-budget-ms");
  CHECK(!fs::exists(out));
  // 0 is documented as "no limit".
  CHECK(run_incise(improve + "0", dir).code == 0);
  CHECK(run_incise("improve --help", dir).out.find("0: no limit") != std::string::npos);
}

TEST_CASE("cut: degenerate blades are errors, a blade that misses is a warning", "[cli][options][cut]") {
  const fs::path dir = scratch_dir("cli_range_blade");
  const fs::path box = dir / "box.msh", out = dir / "out.msh";
  REQUIRE(run_incise("generate box --cells 2 2 2 -o " + q(box), dir).code == 0);
  const std::string cut = "cut " + q(box) + " -q -o " + q(out) + " ";
  const Case cases[] = {
      {"--blade 0.5 0.5 2 0.5 0.5 2 --sweep 0 0 -3", "same point"},
      {"--blade 0.3 -1 2 0.3 2 2 --sweep 0 0 0", "does not move"},
      {"--blade 0.3 -1 2 0.3 2 2 --sweep 0 2 0", "parallel"},
      {"--blade 0.3 -1 1e200 0.3 2 2 --sweep 0 0 -3", "1e15"},
      {"--plane 0.5 0 0 1 0 0 --sweep 0 0 1", "--sweep and --steps go with --blade only"},
      {"--plane 0.5 0 0 1 0 0 --steps 3", "--sweep and --steps go with --blade only"},
      {"--plane 0.5 0 0 1 0 0 --finish-insert 10", "--finish-insert goes with --blade or --path only"},
      {"--blade 0.3 -1 2 0.3 2 2 --sweep 0 0 -3 --finish-insert 91", "--finish-insert"},
      {"--blade 0.3 -1 2 0.3 2 2 --sweep 0 0 -3 --finish-insert nan", "--finish-insert"},
      {"--plane 0.5 0 0 1 0 0 --finish-work 10", "--finish-work goes with --blade or --path only"},
      {"--blade 0.3 -1 2 0.3 2 2 --sweep 0 0 -3 --finish-work -1", "--finish-work"},
      {"--blade 0.3 -1 2 0.3 2 2 --sweep 0 0 -inf", "--sweep: '-inf': numbers must be finite"},
  };
  for (const Case& c : cases) {
    INFO(c.args);
    check_failed(run_incise(cut + c.args, dir), c.expect);
    CHECK(!fs::exists(out));
  }
  // Entirely outside the body: a warning, and the mesh written unchanged.
  Run r = run_incise(cut + "--blade 5 -1 2 5 2 2 --sweep 0 0 -3", dir);
  INFO(r.err);
  CHECK(r.code == 0);
  CHECK(r.err.find("cut: warning: the blade does not reach the mesh") != std::string::npos);
  CHECK(incise::read_tet_mesh(out.string()).num_tets() == incise::read_tet_mesh(box.string()).num_tets());
}

TEST_CASE("cut: remove mode that would carve every tet writes nothing", "[cli][options][cut]") {
  const fs::path dir = scratch_dir("cli_range_remove_all");
  const fs::path box = dir / "box.msh", out = dir / "out.msh";
  REQUIRE(run_incise("generate box --cells 1 1 1 -o " + q(box), dir).code == 0);
  std::ofstream(out) << "sentinel\n";
  check_failed(run_incise("cut " + q(box) + " -q --mode remove --plane 0.5 0.5 0.5 1 0 0 -o " + q(out), dir),
               "removes every tet");
  CHECK(slurp(out) == "sentinel\n");
}

TEST_CASE("generate box: sizes whose cells' volume double precision cannot hold are refused", "[cli][options]") {
  const fs::path dir = scratch_dir("cli_range_generate");
  const fs::path out = dir / "b.msh";
  for (const char* s : {"1e308", "1e-308"})
    check_failed(run_incise(std::string("generate box --size ") + s + " 1 1 -o " + q(out), dir), "cells' volume");
  CHECK(!fs::exists(out));
  CHECK(run_incise("generate box --size 1e-100 1e-100 1e-100 -o " + q(out), dir).code == 0);
}

TEST_CASE("tetra, prepare, improve, quality: option ranges", "[cli][options]") {
  const fs::path dir = scratch_dir("cli_range_options");
  const fs::path box = dir / "box.msh", surf = dir / "box.off", out = dir / "out.msh";
  REQUIRE(run_incise("generate box --cells 1 1 1 -o " + q(box), dir).code == 0);
  REQUIRE(run_incise("convert " + q(box) + " " + q(surf), dir).code == 0);
  const Case cases[] = {
      {"tetra " + q(surf) + " -o " + q(out) + " --sliver-bound -5", "--sliver-bound"},
      {"prepare " + q(surf) + " -o " + q(out) + " --optimize-time -1", "--optimize-time"},
      {"prepare " + q(surf) + " -o " + q(out) + " --features 500", "--features"},
      {"prepare " + q(surf) + " -o " + q(out) + " --close -1", "--close"},
      {"prepare " + q(surf) + " -o " + q(out) + " --improve-time-limit nan", "--improve-time-limit"},
      {"tetra " + q(surf) + " -o " + q(out) + " --facet-angle nan", "--facet-angle"},
      {"improve " + q(box) + " -o " + q(out) + " --feature-angle -5", "--feature-angle"},
      {"improve " + q(box) + " -o " + q(out) + " --feature-angle 400", "--feature-angle"},
      {"quality " + q(box) + " --lanczos-iterations 0", "--lanczos-iterations"},
  };
  for (const Case& c : cases) {
    INFO(c.args);
    Run r = run_incise(c.args, dir);
    if (r.err.find("without CGAL") != std::string::npos) continue;
    check_failed(r, c.expect);
    CHECK(r.err.size() < 200);  // no 300-digit bound
    CHECK(!fs::exists(out));
  }
}

TEST_CASE("usage errors are one line with the prefix", "[cli][options]") {
  const fs::path dir = scratch_dir("cli_usage_errors");
  check_failed(run_incise("info", dir), "required");
  check_failed(run_incise("info x.msh --no-such-option", dir), "no-such-option");
  check_failed(run_incise("frobnicate", dir), "subcommand");
}

TEST_CASE("the OFF reader rejects a face index out of range, naming the line", "[cli][io]") {
  const fs::path dir = scratch_dir("cli_off_index");
  std::ofstream(dir / "bad.off") << "OFF\n# a tetrahedron with one bad index\n4 4 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n"
                                    "3 0 2 1\n3 0 1 9\n3 0 3 2\n3 1 2 3\n";
  const fs::path box = dir / "box.msh";
  REQUIRE(run_incise("generate box --cells 1 1 1 -o " + q(box), dir).code == 0);
  check_failed(run_incise("convert " + q(dir / "bad.off") + " " + q(dir / "out.obj"), dir),
               "bad.off:9: face vertex index 9 out of range (4 vertices)");
  check_failed(run_incise("cut " + q(box) + " -o " + q(dir / "out.msh") + " --surface " + q(dir / "bad.off"), dir),
               "bad.off:9:");
  CHECK(!fs::exists(dir / "out.obj"));
  CHECK(!fs::exists(dir / "out.msh"));
  // Header counts the file cannot hold, or that are no counts (a 40-digit face count made the
  // surface importer reserve 2 GB): refused before the import.
  std::ofstream(dir / "huge.off") << "OFF\n8 1333333333333333333333333333333333333332 3\n0 0 0\n";
  check_failed(run_incise("convert " + q(dir / "huge.off") + " " + q(dir / "out.obj"), dir),
               "huge.off:2: face count '");
  std::ofstream(dir / "headless.off") << "3333333332 3\n3 2 6\n3 0 6 2\n";
  check_failed(run_incise("convert " + q(dir / "headless.off") + " " + q(dir / "out.obj"), dir),
               "headless.off:1: the header announces 3333333332 vertices");
  std::ofstream(dir / "many.off") << "OFF\n4 100000000 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 2\n";
  check_failed(run_incise("convert " + q(dir / "many.off") + " " + q(dir / "out.obj"), dir),
               "many.off:2: the header announces 4 vertices and 100000000 faces");
  CHECK(!fs::exists(dir / "out.obj"));
}

TEST_CASE("scene cuts: degenerate blades and frames after the run are errors naming the key", "[cli][options][scene]") {
  const fs::path dir = scratch_dir("cli_scene_cuts");
  auto scene = [](const std::string& cut, const std::string& frames = "4") {
    return R"({"mesh": {"generate": "box", "size": [4, 1, 1], "cells": [4, 1, 1]}, "model": "fem-linear",
      "materials": {"*": {"young": 1e5, "poisson": 0.3}},
      "fixed": [{"box": [-0.01, -0.01, -0.01, 0.01, 1.01, 1.01]}],
      "cuts": [)" + cut + R"(], "time": {"frames": )" + frames + "}}";
  };
  const Case cases[] = {
      {scene(R"({"blade": [[2, -1, 2], [2, 2, 2]], "sweep": [0, 0, -3], "from_frame": 4, "to_frame": 4})"),
       "cuts[0].to_frame: frame 4 is after the run's last frame (3, time.frames 4)"},
      {scene(R"({"blade": [[2, -1, 2], [2, 2, 2]], "sweep": [0, 0, -3], "from_frame": 7})"), "cuts[0].from_frame: frame 7"},
      {scene(R"({"blade": [[2, -1, 2], [2, 2, 2]], "sweep": [0, 0, -3], "from_frame": 1, "to_frame": 9})"),
       "cuts[0].to_frame: frame 9"},
      {scene(R"({"blade": [[2, 0, 2], [2, 0, 2]], "sweep": [0, 0, -3]})"), "cuts[0]: the blade's two ends are the same point"},
      {scene(R"({"blade": [[2, -1, 2], [2, 2, 2]], "sweep": [0, 0, 0]})"), "cuts[0]: the sweep is zero"},
      {scene(R"({"blade": [[2, -1, 2], [2, 2, 2]], "sweep": [0, 1e999, 0]})"), "scene.json: invalid JSON"},
      // The same snap rule as `incise cut --snap` and Python's Cutter.
      {scene(R"({"blade": [[2, -1, 2], [2, 2, 2]], "sweep": [0, 0, -3], "snap": 0.5})"),
       "cuts[0].snap: 0.5 is not in [0, 0.5)"},
  };
  for (const Case& c : cases) {
    INFO(c.args);
    std::ofstream(dir / "scene.json") << c.args;
    check_failed(run_incise("simulate -q " + q(dir / "scene.json") + " -o " + q(dir / "out"), dir), c.expect);
    CHECK(!fs::exists(dir / "out"));
  }
}

TEST_CASE("view: options of a live scene are refused in look mode", "[cli][options]") {
  const fs::path dir = scratch_dir("cli_view_look_options");
  // A build without the viewer has no `view` subcommand (`view --help` then prints the top
  // help and exits 0): its list of subcommands says.
  if (run_incise("--help", dir).out.find("\n  view ") == std::string::npos) {
    WARN("incise built without the viewer (INCISE_WITH_VIEW=OFF): nothing to check");
    return;
  }
  const fs::path box = dir / "box.msh";
  REQUIRE(run_incise("generate box --cells 1 1 1 -o " + q(box), dir).code == 0);
  for (const char* opt : {"--paused", "--budget-ms 10", "--record " })
    check_failed(run_incise("view " + q(box) + " " + opt + (std::string(opt) == "--record " ? q(dir / "takes") : ""), dir),
                 "is for a scene (live mode)");
  CHECK(!fs::exists(dir / "takes"));
  // A budget that is not a number is refused, not replaced by the default.
  check_failed(run_incise("view " + q(box) + " --budget-ms nan", dir), "--budget-ms: 'nan': expected a finite number");
}

TEST_CASE("sizes are estimated before the work: past the ids or the memory is refused, naming the estimate",
          "[cli][options][size]") {
  const fs::path dir = scratch_dir("cli_range_size");
  const fs::path out = dir / "g.msh";
  check_failed(run_incise("generate box --cells 2147483647 1 1 -o " + q(out), dir),
               "2147483647x1x1 cells make 12884901882 tets and 8589934592 vertices, more than a mesh's 32-bit ids");
  const double have = double(incise::available_memory_bytes());
  if (have > 0 && have < 200e9)  // 1.3e9 tets at 160 bytes
    check_failed(run_incise("generate box --cells 600 600 600 -o " + q(out), dir),
                 "600x600x600 cells would need about 207 GB (1296000000 tets), more than the");
  CHECK(!fs::exists(out));
  // trade: the reference four levels up from the beam's 5184 tets is 21M tets.
  const std::string beam = q(fs::path(INCISE_SOURCE_DIR) / "samples" / "scenes" / "beam.json");
  if (have > 0 && have < 120e9)
    check_failed(run_incise("trade " + beam + " --resolutions 0 --reference-level 4 --output " + q(dir / "t.md"), dir),
                 "trade: the reference at level 4 would need about");
  CHECK(!fs::exists(dir / "t.md"));
  // simulate: integration steps a frame and a run.
  std::ofstream(dir / "s.json") << R"({"mesh": {"generate": "box", "cells": [2, 1, 1]}, "model": "springs",
    "materials": {"*": {"young": 1e5, "poisson": 0.3}}, "time": {"frames": 4, "substeps": 1000000000}})";
  check_failed(run_incise("simulate " + q(dir / "s.json") + " -o " + q(dir / "run"), dir),
               "time.substeps: 1000000000 integration steps a frame is more than the 1000000 allowed");
  std::ofstream(dir / "s2.json") << R"({"mesh": {"generate": "box", "cells": [2, 1, 1]}, "model": "springs",
    "materials": {"*": {"young": 1e5, "poisson": 0.3}}, "time": {"frames": 100000, "substeps": 100000}})";
  check_failed(run_incise("simulate " + q(dir / "s2.json") + " -o " + q(dir / "run"), dir),
               "100000 frames of 100000 steps are 10000000000 steps, more than the 1000000000 a run may take");
  CHECK(!fs::exists(dir / "run"));
}

TEST_CASE("an empty value is an error naming its option, not the default", "[cli][options]") {
  const fs::path dir = scratch_dir("cli_range_empty");
  const fs::path box = dir / "box.msh";
  REQUIRE(run_incise("generate box --cells 1 1 1 -o " + q(box), dir).code == 0);
  check_failed(run_incise("quality " + q(box) + " --worst ''", dir), "--worst: an empty value");
  check_failed(run_incise("quality " + q(box) + " --sliver-angle=", dir), "--sliver-angle: an empty value");
  check_failed(run_incise("info ''", dir), "an empty value");
}

TEST_CASE("a blade whose sweep is lost to rounding says so", "[cli][options][cut]") {
  const fs::path dir = scratch_dir("cli_range_rounding");
  const fs::path box = dir / "box.msh";
  REQUIRE(run_incise("generate box --cells 1 1 1 -o " + q(box), dir).code == 0);
  check_failed(run_incise("cut " + q(box) + " -o " + q(dir / "x.msh") + " --blade 0.5 -1e15 2 0.5 1e15 2 --sweep 0 0 -3", dir),
               "the sweep's length (3) is lost to rounding at the blade's coordinates (up to 1e+15)");
  // A tet output named as a surface: the message names the command line's way, not Python's.
  check_failed(run_incise("cut " + q(box) + " -o " + q(dir / "x.off") + " --plane 0.5 0.5 0.5 1 0 0", dir),
               "incise convert MESH OUT.off");
}
