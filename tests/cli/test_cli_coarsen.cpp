// incise coarsen: a coarser copy written with its summary; bad input is one line, nothing written.
#include <catch2/catch.hpp>

#include "cli_run.h"
#include "mesh/io/tet_io.h"

namespace fs = std::filesystem;
using namespace incise::testing;

TEST_CASE("incise coarsen writes a coarser copy of the body and says what it did", "[cli][coarsen]") {
  const fs::path dir = scratch_dir("cli_coarsen");
  std::string gen = "generate box --size 2 1 1 --cells 8 4 4 -o ";
  gen += q(dir / "box.msh");
  REQUIRE(run_incise(gen, dir).code == 0);
  std::string args = "coarsen ";
  args += q(dir / "box.msh");
  args += " -o ";
  args += q(dir / "coarse.vtu");
  const Run r = run_incise(args, dir);
  INFO(r.err);
  REQUIRE(r.code == 0);
  CHECK(r.out.find("tets      768 -> ") != std::string::npos);
  CHECK(r.out.find("surface within") != std::string::npos);
  const incise::TetMesh in = incise::read_tet_mesh((dir / "box.msh").string());
  const incise::TetMesh out = incise::read_tet_mesh((dir / "coarse.vtu").string());
  CHECK(out.num_tets() * 4 <= in.num_tets());
  CHECK(std::abs(out.total_volume() - 2) < 1e-9);  // flat faces: the box exactly
}

TEST_CASE("incise coarsen: bad input is one line, nothing written", "[cli][coarsen][errors]") {
  const fs::path dir = scratch_dir("cli_coarsen_errors");
  std::string args = "coarsen ";
  args += q(dir / "missing.msh");
  args += " -o ";
  args += q(dir / "out.msh");
  const Run r = run_incise(args, dir);
  check_failed(r, (dir / "missing.msh").string());
  CHECK(!fs::exists(dir / "out.msh"));
}
