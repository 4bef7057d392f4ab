// Issue 18, part 1: a failed command leaves every existing file as it was. Each case puts a
// sentinel where the command would write, makes the command fail (a bad second output, two
// outputs naming one file, a run that breaks), and checks the sentinel survives byte for byte
// with one line on stderr and exit code 1.
#include <catch2/catch.hpp>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>

#include "cli_run.h"

namespace fs = std::filesystem;
using namespace incise::testing;

namespace {

const std::string kSentinel = "sentinel: must survive a failed command\n";

void put_sentinel(const fs::path& p) { std::ofstream(p) << kSentinel; }


// Files in `d` without the capture files run_incise writes.
std::vector<std::string> listing(const fs::path& d) {
  std::vector<std::string> names;
  for (const auto& e : fs::directory_iterator(d)) names.push_back(e.path().filename().string());
  std::sort(names.begin(), names.end());
  return names;
}

// A static FEM scene whose blade frees the right half at frame 2 with "fragments": "error":
// frames 0 and 1 are written, then the run stops. Stiff, so the blade still meets the body.
const char* kBreakingScene = R"({
  "mesh": {"generate": "box", "size": [4, 1, 1], "cells": [8, 2, 2]},
  "model": "fem-linear",
  "materials": {"*": {"young": 1e9, "poisson": 0.3}},
  "fixed": [{"box": [-0.01, -0.01, -0.01, 0.01, 1.01, 1.01]}],
  "loads": [{"type": "gravity", "g": [0, 0, -9.81]}],
  "cuts": [{"blade": [[2.03, -0.5, 1.5], [2.03, 1.5, 1.5]], "sweep": [0, 0, -2], "from_frame": 2, "to_frame": 2}],
  "fragments": "error",
  "time": {"frames": 4}
})";

const char* kScene = R"({
  "mesh": {"generate": "box", "size": [4, 1, 1], "cells": [4, 1, 1]},
  "model": "fem-linear",
  "materials": {"*": {"young": 1e5, "poisson": 0.3}},
  "fixed": [{"box": [-0.01, -0.01, -0.01, 0.01, 1.01, 1.01]}],
  "loads": [{"type": "gravity", "g": [0, 0, -9.81]}],
  "time": {"frames": 4}
})";

}  // namespace

TEST_CASE("cut and improve: a bad report path or one equal to -o keeps the existing mesh", "[cli][nothing-lost]") {
  const fs::path dir = scratch_dir("cli_lost_cut_improve");
  const fs::path box = dir / "box.msh", out = dir / "s.msh";
  REQUIRE(run_incise("generate box --cells 2 2 2 -o " + q(box), dir).code == 0);
  const std::string cut = "cut " + q(box) + " -q --plane 0.5 0.5 0.5 1 0 0 -o ";
  const std::string improve = "improve " + q(box) + " --time-limit 1 -o ";
  for (const std::string& cmd : {cut, improve}) {
    INFO(cmd);
    put_sentinel(out);
    check_failed(run_incise(cmd + q(out) + " --json " + q(dir / "nodir" / "r.json"), dir), "nodir");
    CHECK(slurp(out) == kSentinel);
    // The report path names the mesh (also spelled differently): refused, not overwritten.
    check_failed(run_incise(cmd + q(out) + " --json " + q(out), dir), "--json names the same file as the output mesh");
    check_failed(run_incise(cmd + q(out) + " --json " + q(dir / "." / "s.msh"), dir), "same file");
    CHECK(slurp(out) == kSentinel);
    // A directory as the report: refused before any work.
    check_failed(run_incise(cmd + q(out) + " --json " + q(dir), dir), "is a directory");
    CHECK(slurp(out) == kSentinel);
    // .node/.ele output: both names reserved, the pair checked.
    check_failed(run_incise(cmd + q(dir / "p.node") + " --json " + q(dir / "p.ele"), dir), "same file");
  }
  CHECK(listing(dir) == std::vector<std::string>{"box.msh", "s.msh", "stderr.txt", "stdout.txt"});
}

TEST_CASE("prepare: a bad --report keeps the existing mesh and leaves no temporary", "[cli][nothing-lost]") {
  const fs::path dir = scratch_dir("cli_lost_prepare");
  const fs::path box = dir / "box.msh", surf = dir / "box.off", out = dir / "s.vtu";
  REQUIRE(run_incise("generate box --cells 2 2 2 -o " + q(box), dir).code == 0);
  REQUIRE(run_incise("convert " + q(box) + " " + q(surf), dir).code == 0);
  const std::string prepare = "prepare " + q(surf) + " -q --engine stuffing -o " + q(out);
  Run probe = run_incise(prepare + " --report " + q(dir / "nodir" / "q.json"), dir);
  if (probe.err.find("without CGAL") != std::string::npos) return;  // no meshing in this build
  put_sentinel(out);
  check_failed(run_incise(prepare + " --report " + q(dir / "nodir" / "q.json"), dir), "nodir");
  CHECK(slurp(out) == kSentinel);
  check_failed(run_incise(prepare + " --report " + q(dir), dir), "is a directory");
  CHECK(slurp(out) == kSentinel);
  check_failed(run_incise(prepare + " --report " + q(out), dir), "--report names the same file as the output mesh");
  CHECK(slurp(out) == kSentinel);
  CHECK(listing(dir) == std::vector<std::string>{"box.msh", "box.off", "s.vtu", "stderr.txt", "stdout.txt"});
}

TEST_CASE("convert to .node/.ele: an unwritable .ele keeps the existing .node", "[cli][nothing-lost]") {
  const fs::path dir = scratch_dir("cli_lost_convert");
  const fs::path box = dir / "box.msh";
  REQUIRE(run_incise("generate box --cells 1 1 1 -o " + q(box), dir).code == 0);
  put_sentinel(dir / "p.node");
  fs::create_directory(dir / "p.ele");
  check_failed(run_incise("convert " + q(box) + " " + q(dir / "p.node"), dir), "p.ele");
  CHECK(slurp(dir / "p.node") == kSentinel);
  // A missing directory is found before reading.
  check_failed(run_incise("convert " + q(box) + " " + q(dir / "nodir" / "p.vtu"), dir), "nodir");
  CHECK(listing(dir) == std::vector<std::string>{"box.msh", "p.ele", "p.node", "stderr.txt", "stdout.txt"});
}

TEST_CASE("convert: options the output format has no use for are refused", "[cli][nothing-lost]") {
  const fs::path dir = scratch_dir("cli_convert_options");
  const fs::path box = dir / "box.msh";
  REQUIRE(run_incise("generate box --cells 1 1 1 -o " + q(box), dir).code == 0);
  struct Case {
    std::string out, opt, expect;
  };
  const Case cases[] = {
      {"a.msh", "--binary", "--binary applies to .vtk and .vtu output only"},
      {"a.vtk", "--big-endian", "--big-endian applies to .vtu output only"},
      {"a.vtu", "--header64", "--header64 applies to binary .vtu"},
      {"a.vtu", "--no-boundary", "--no-boundary applies to .msh and .mesh output only"},
      {"a.off", "--binary", "--binary applies"},
      {"a.stl", "--spatial-order", "--spatial-order applies to tet mesh output only"},
  };
  for (const Case& c : cases) {
    check_failed(run_incise("convert " + q(box) + " " + q(dir / c.out) + " " + c.opt, dir), c.expect);
    CHECK(!fs::exists(dir / c.out));
  }
  CHECK(run_incise("convert " + q(box) + " " + q(dir / "b.vtu") + " --binary --header64", dir).code == 0);
  CHECK(run_incise("convert " + q(box) + " " + q(dir / "b.vtu") + " --big-endian --header64", dir).code == 0);
  CHECK(run_incise("convert " + q(box) + " " + q(dir / "b.mesh") + " --no-boundary", dir).code == 0);
}

TEST_CASE("simulate: DIR is always one run's output", "[cli][nothing-lost][simulate]") {
  const fs::path dir = scratch_dir("cli_lost_simulate");
  std::ofstream(dir / "scene.json") << kScene;
  std::ofstream(dir / "breaks.json") << kBreakingScene;
  const fs::path out = dir / "out";
  const std::string sim = "simulate -q " + q(dir / "scene.json") + " -o " + q(out);
  REQUIRE(run_incise(sim, dir).code == 0);
  // A run directory carries its marker (.incise-run) besides the run's files.
  const std::vector<std::string> four{".incise-run",    "frame_0000.vtu", "frame_0001.vtu", "frame_0002.vtu",
                                      "frame_0003.vtu", "frames.pvd",     "stats.csv"};
  CHECK(listing(out) == four);
  {  // Progress numbers frames as the files do (it once said frame 1/4 for frame_0000).
    const Run loud = run_incise("simulate " + q(dir / "scene.json") + " -o " + q(dir / "loud"), dir);
    REQUIRE(loud.code == 0);
    const std::string all = loud.out + loud.err;
    CHECK(all.find("simulate: frame 0 (0..3)") != std::string::npos);
    CHECK(all.find("simulate: frame 3 (0..3)") != std::string::npos);
    CHECK(all.find("frame 4") == std::string::npos);
    fs::remove_all(dir / "loud");
  }
  const std::string stats = slurp(out / "stats.csv"), frame0 = slurp(out / "frame_0000.vtu");

  // A run that fails mid-way leaves the earlier run as it was, and says so.
  Run r = run_incise("simulate -q " + q(dir / "breaks.json") + " -o " + q(out), dir);
  check_failed(r, "keeps the earlier run");
  CHECK(listing(out) == four);
  CHECK(slurp(out / "stats.csv") == stats);
  CHECK(slurp(out / "frame_0000.vtu") == frame0);

  // A shorter successful re-run leaves no stale frames.
  // A hidden run directory a killed run left beside DIR (its process is gone) is removed.
  fs::create_directory(dir / ".out.run999999999_0");
  REQUIRE(run_incise(sim + " --frames 2", dir).code == 0);
  CHECK(listing(out) ==
        std::vector<std::string>{".incise-run", "frame_0000.vtu", "frame_0001.vtu", "frames.pvd", "stats.csv"});

  // Into a new directory a failed run keeps the frames it computed (docs/scene.md).
  r = run_incise("simulate -q " + q(dir / "breaks.json") + " -o " + q(dir / "fresh"), dir);
  check_failed(r, "frame 2");
  CHECK(listing(dir / "fresh") ==
        std::vector<std::string>{".incise-run", "frame_0000.vtu", "frame_0001.vtu", "frames.pvd", "stats.csv"});

  // A directory holding other files is refused before the run; the files stay.
  fs::create_directory(dir / "mine");
  put_sentinel(dir / "mine" / "notes.txt");
  check_failed(run_incise("simulate -q " + q(dir / "scene.json") + " -o " + q(dir / "mine"), dir), "notes.txt");
  CHECK(slurp(dir / "mine" / "notes.txt") == kSentinel);
  CHECK(listing(dir / "mine") == std::vector<std::string>{"notes.txt"});
  // ... also when they are named like a run's: a user's stats.csv and frames.pvd, no marker.
  fs::create_directory(dir / "theirs");
  put_sentinel(dir / "theirs" / "stats.csv");
  put_sentinel(dir / "theirs" / "frames.pvd");
  check_failed(run_incise("simulate -q " + q(dir / "scene.json") + " -o " + q(dir / "theirs"), dir),
               "holds files incise simulate did not write (no .incise-run)");
  CHECK(slurp(dir / "theirs" / "stats.csv") == kSentinel);
  CHECK(slurp(dir / "theirs" / "frames.pvd") == kSentinel);
  // A file as DIR.
  check_failed(run_incise("simulate -q " + q(dir / "scene.json") + " -o " + q(dir / "scene.json"), dir),
               "not a directory");
  // No run directory is left beside DIR.
  CHECK(listing(dir) ==
        std::vector<std::string>{"breaks.json", "fresh", "mine", "out", "scene.json", "stderr.txt", "stdout.txt", "theirs"});
}

TEST_CASE("trade: a scene error leaves no output directory", "[cli][nothing-lost][trade]") {
  const fs::path dir = scratch_dir("cli_lost_trade");
  std::ofstream(dir / "bad.json") << R"({"mesh": {"generate": "box"}, "model": "fem-linear", "time": {"frames": 0}})";
  check_failed(run_incise("trade -q " + q(dir / "bad.json") + " -o " + q(dir / "out"), dir), "bad.json");
  CHECK(!fs::exists(dir / "out"));
}

TEST_CASE("simulate and trade: --frames must be at least 1", "[cli][nothing-lost][options]") {
  const fs::path dir = scratch_dir("cli_frames_option");
  std::ofstream(dir / "scene.json") << kScene;
  for (const std::string cmd : {"simulate", "trade"})
    for (const std::string n : {"0", "-3"}) {
      check_failed(run_incise(cmd + " -q " + q(dir / "scene.json") + " -o " + q(dir / "out") + " --frames " + n, dir),
                   "--frames");
      CHECK(!fs::exists(dir / "out"));
    }
}

TEST_CASE("every command that writes a mesh keeps an existing output when it fails", "[cli][nothing-lost]") {
  // One case per writing command: the output exists, the command fails after naming it (bad
  // input or a value its checks refuse), the old output is still there byte for byte.
  const fs::path dir = scratch_dir("cli_lost_every");
  const fs::path out = dir / "out.msh", box = dir / "box.msh", bad = dir / "bad.off";
  REQUIRE(run_incise("generate box --cells 2 2 2 -o " + q(box), dir).code == 0);
  std::ofstream(bad) << "OFF\n4 1 0\n0 0 0\n1 0 0\n0 1 0\n0 0 1\n3 0 1 9\n";  // index 9 of 4
  const std::string o = " -o " + q(out);
  const std::string cases[] = {
      "generate box --cells 0 2 2" + o,
      "generate ellipsoid --resolution 0" + o,
      "tetra " + q(bad) + o,
      "prepare " + q(bad) + o,
      "convert " + q(bad) + " " + q(out),
      "cut " + q(dir / "missing.msh") + o + " --plane 0 0 0 0 0 1",
      "cut " + q(box) + o + " --blade 0.5 -1 2 0.5 2 2 --sweep 0 0 0",
      "improve " + q(dir / "missing.msh") + o,
      "improve " + q(box) + o + " --volume-tolerance 2",
  };
  for (const std::string& args : cases) {
    INFO(args);
    put_sentinel(out);
    const Run r = run_incise(args, dir);
    INFO(r.err);
    CHECK(r.code == 1);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    CHECK(slurp(out) == kSentinel);
  }
}

TEST_CASE("no output may be an input: a report or mesh path naming an input is refused, the input kept",
          "[cli][nothing-lost]") {
  const fs::path dir = scratch_dir("cli_no_output_is_input");
  const fs::path box = dir / "b.msh";
  REQUIRE(run_incise("generate box --cells 2 2 2 -o '" + box.string() + "'", dir).code == 0);
  std::string original;
  {
    std::ifstream in(box, std::ios::binary);
    original.assign(std::istreambuf_iterator<char>(in), {});
  }
  fs::create_symlink(box, dir / "link.msh");  // another name for the input: same inode
  const std::string b = "'" + box.string() + "'", link = "'" + (dir / "link.msh").string() + "'";
  const std::string out = "'" + (dir / "c.msh").string() + "'";
  struct Case {
    std::string args, expect;
  };
  const Case cases[] = {
      {"cut " + b + " -o " + out + " --plane 0.4 0.5 0.5 1 0 0 --json " + b, "--json names the input"},
      {"cut " + b + " -o " + out + " --plane 0.4 0.5 0.5 1 0 0 --json " + link, "--json names the input"},
      {"cut " + b + " -o " + link + " --plane 0.4 0.5 0.5 1 0 0", "the output mesh names the input"},
      {"improve " + b + " -o " + out + " --json " + b, "--json names the input"},
      {"improve " + b + " -o " + b, "the output mesh names the input"},
      {"coarsen " + b + " -o " + link, "the output mesh names the input"},
      {"convert " + b + " " + link, "names the input"},
  };
  for (const Case& c : cases) {
    Run r = run_incise(c.args, dir);
    INFO(c.args << "\n" << r.err);
    CHECK(r.code == 1);
    CHECK(r.err.find(c.expect) != std::string::npos);
    CHECK(std::count(r.err.begin(), r.err.end(), '\n') == 1);
    std::ifstream in(box, std::ios::binary);
    CHECK(std::string(std::istreambuf_iterator<char>(in), {}) == original);
  }
}
