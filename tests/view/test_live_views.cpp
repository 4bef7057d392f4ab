// What live mode draws besides the boundary: the loaded regions (flagged on the wire like the
// fixed ones) and the clip view (the tets below an angle, drawn whole over the body).
#include <catch2/catch.hpp>

#include <chrono>
#include <thread>

#include <nlohmann/json.hpp>

#include "view/boundary_tracker.h"
#include "view/frame_diff.h"
#include "live_test_util.h"
#include "view/live_session.h"

using namespace incise;
using namespace incise::view;
using namespace incise::view::testing;

namespace {

// 4 x 1 x 1, 12 x 3 x 3 cubes of 6 Kuhn tets (smallest dihedral 45 deg): clamped at x = 0,
// pulled at the tip face x = 4.
const char* kViewsBeam = R"({
  "mesh": {"generate": "box", "size": [4, 1, 1], "cells": [12, 3, 3]},
  "model": "fem-linear",
  "materials": {"*": {"young": 1e4, "poisson": 0.3}},
  "fixed": [{"box": [-0.01, -1, -1, 0.01, 2, 2]}],
  "loads": [{"type": "force", "box": [3.99, -1, -1, 4.01, 2, 2], "total": [0, 0, -1]}],
  "solver": {"method": "cg", "tolerance": 1e-8, "preconditioner": "block-jacobi"},
  "time": {"frames": 100}
})";

std::size_t flagged(const Snapshot& s, std::uint32_t flag) {
  std::size_t n = 0;
  for (std::size_t i = 0; i + 3 < s.tris.size(); i += 4)
    if (s.tris[i] != kNoSlot && (s.tris[i + 3] & flag)) ++n;
  return n;
}

}  // namespace

TEST_CASE("live views: loaded regions are flagged, and the clip view draws the tets below an angle", "[view]") {
  LiveSession live(parse_scene(kViewsBeam, "beam.json"));
  // The end faces: 3 x 3 squares, 2 triangles each.
  auto snap = live.snapshot();
  CHECK(flagged(*snap, kTriangleFixed) == 18);
  CHECK(flagged(*snap, kTriangleLoaded) == 18);
  CHECK(flagged(*snap, kTriangleWorst) == 0);
  const std::size_t boundary = snap->triangles;

  REQUIRE(live.post(msg(InputKind::Pause)).empty());
  live.start();
  // Every tet is at 45 deg: below 50 all 648 are drawn, 4 faces each; below 40 none.
  REQUIRE(live.post(msg(InputKind::Clip, {}, 50)).empty());
  wait_for(live, [](const nlohmann::json& j) { return j["clip_deg"] == 50; });
  snap = live.snapshot();
  CHECK(status(live)["clip_tets"] == 12 * 3 * 3 * 6);
  CHECK(flagged(*snap, kTriangleWorst) == 4 * 12 * 3 * 3 * 6);
  CHECK(snap->triangles == boundary + 4 * 12 * 3 * 3 * 6);
  // A page's copy follows: the clip triangles arrive as set slots.
  ClientMirror page;
  const FrameMessage m = diff(*snap, page);
  CHECK(m.set.size() == snap->triangles);
  REQUIRE(live.post(msg(InputKind::Clip, {}, 40)).empty());
  wait_for(live, [](const nlohmann::json& j) { return j["clip_deg"] == 40; });
  snap = live.snapshot();
  CHECK(flagged(*snap, kTriangleWorst) == 0);
  CHECK(snap->triangles == boundary);
  // Back off: the page's arrays shrink to the boundary's slots (slots past the end vanish).
  const FrameMessage back = diff(*snap, page);
  CHECK(back.triangle_slots == m.triangle_slots - 4 * 12 * 3 * 3 * 6);

  // After a cut (a blade from the top at x = 1.3 to mid-height), the tets below 10 deg are the
  // overlay's count of them.
  REQUIRE(live.post(msg(InputKind::Clip, {}, 10)).empty());
  REQUIRE(live.post(msg(InputKind::BladeStart, {1.37f, -0.5f, 1.2f, 1.37f, 1.5f, 1.2f})).empty());
  REQUIRE(live.post(msg(InputKind::BladeMove, {1.37f, -0.5f, 0.41f, 1.37f, 1.5f, 0.41f})).empty());
  REQUIRE(live.post(msg(InputKind::BladeEnd)).empty());
  wait_for(live, [](const nlohmann::json& j) { return j["blade_steps"] == 1 && !j["blade"].get<bool>(); });
  const nlohmann::json j = status(live);
  live.stop();
  snap = live.snapshot();
  CHECK(j["clip_tets"] == j["below"]);
  CHECK(flagged(*snap, kTriangleWorst) == 4 * j["below"].get<std::size_t>());
  INFO("tets below 10 deg after the cut: " << j["below"]);
  CHECK(flagged(*snap, kTriangleLoaded) == 18);  // the cut is far from the tip
}
