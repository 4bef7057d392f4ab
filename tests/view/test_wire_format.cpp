// The viewer's wire format both ways, and the boundary it streams: the tracker's slots against
// a full recount of the mesh's boundary after cuts, and the page's copy rebuilt from the
// difference messages against the snapshot they came from.
#include <catch2/catch.hpp>

#include <algorithm>
#include <cmath>
#include <map>
#include <set>

#include "cut/cutter.h"
#include "mesh/errors.h"
#include "mesh/generate.h"
#include "view/boundary_tracker.h"
#include "quality/metrics.h"
#include "scene/scene_runner.h"
#include "view/frame_diff.h"
#include "view/quality_watch.h"
#include "view/wire_format.h"

using namespace incise;
using namespace incise::view;

TEST_CASE("frame messages round-trip and refuse damaged bytes") {
  FrameMessage m;
  m.reset = true;
  m.frame = 42;
  m.vertex_slots = 5;
  m.triangle_slots = 3;
  m.positions = {{0, {1.f, 2.f, 3.f}}, {4, {-1.5f, 0.f, 1e-7f}}};
  m.removed = {1};
  m.set = {{0, {0, 1, 2}, kTriangleCut}, {2, {2, 3, 4}, kTriangleFixed}};
  m.scalars = {0.5f, 0.f, 2.f};
  m.scalar_lo = 0;
  m.scalar_hi = 2;
  m.stats_json = R"({"frame":42})";
  const std::vector<std::uint8_t> bytes = encode(m);
  CHECK(bytes.size() == 16 + 4 + 2 * 16 + 4 + 4 + 4 + 2 * 20 + 4 + 8 + 3 * 4 + 4 + m.stats_json.size());
  const FrameMessage d = decode_frame(bytes);
  CHECK(d.reset);
  CHECK(d.frame == 42);
  CHECK(d.vertex_slots == 5);
  CHECK(d.triangle_slots == 3);
  REQUIRE(d.positions.size() == 2);
  CHECK(d.positions[1].slot == 4);
  CHECK(d.positions[1].p == m.positions[1].p);
  CHECK(d.removed == m.removed);
  REQUIRE(d.set.size() == 2);
  CHECK(d.set[1].v == m.set[1].v);
  CHECK(d.set[1].flags == kTriangleFixed);
  CHECK(d.scalars == m.scalars);
  CHECK(d.scalar_hi == 2);
  CHECK(d.stats_json == m.stats_json);

  for (std::size_t cut = 0; cut < bytes.size(); cut += 7)  // every truncation is refused
    CHECK_THROWS_AS(decode_frame(std::span(bytes.data(), cut)), InvalidArgument);
  std::vector<std::uint8_t> forged = bytes;
  forged[16] = 0xff, forged[17] = 0xff, forged[18] = 0xff, forged[19] = 0x7f;  // position count
  CHECK_THROWS_AS(decode_frame(forged), InvalidArgument);
  std::vector<std::uint8_t> corner = bytes;
  corner[16 + 4 + 2 * 16 + 4 + 4 + 4 + 4] = 9;  // a triangle corner beyond the vertex slots
  CHECK_THROWS_AS(decode_frame(corner), InvalidArgument);
}

TEST_CASE("inputs round-trip, and wrong sizes, kinds and numbers are refused") {
  for (std::uint8_t k = 1; k <= std::uint8_t(InputKind::Clip); ++k) {
    InputMessage in;
    in.kind = InputKind(k);
    in.v = {1, 2, 3, 4, 5, 6};
    in.value = in.kind == InputKind::Colour ? 2 : in.kind == InputKind::Record ? 1 : 77;
    const bool valued = k >= 11;  // Colour, Ack, Frame, Record, Clip carry a value
    const std::vector<std::uint8_t> b = encode(in);
    CHECK(b.size() == input_size(k));
    const InputMessage out = decode_input(b);
    CHECK(out.kind == in.kind);
    const int floats = int((b.size() - 1) / 4) - (valued ? 1 : 0);
    for (int i = 0; i < floats; ++i) CHECK(out.v[i] == in.v[i]);
    if (valued) CHECK(out.value == in.value);
    std::vector<std::uint8_t> longer = b;
    longer.push_back(0);
    CHECK_THROWS_AS(decode_input(longer), InvalidArgument);
  }
  CHECK_THROWS_AS(decode_input(std::vector<std::uint8_t>{}), InvalidArgument);
  CHECK_THROWS_AS(decode_input(std::vector<std::uint8_t>{0}), InvalidArgument);
  CHECK_THROWS_AS(decode_input(std::vector<std::uint8_t>{200}), InvalidArgument);
  InputMessage blade{InputKind::BladeMove, {0, 0, 0, 1, NAN, 0}, 0};
  CHECK_THROWS_AS(decode_input(encode(blade)), InvalidArgument);
  InputMessage colour{InputKind::Colour, {}, kColourModes};
  CHECK_THROWS_AS(decode_input(encode(colour)), InvalidArgument);
  InputMessage probe{InputKind::ProbeGrab, {0, 0, 0, 0, 0, 0}, 0};
  CHECK_THROWS_AS(decode_input(encode(probe)), InvalidArgument);
  CHECK_THROWS_AS(decode_input(encode(InputMessage{InputKind::Record, {}, 2})), InvalidArgument);
  CHECK_THROWS_AS(decode_input(encode(InputMessage{InputKind::Clip, {}, kMaxClipDeg + 1})), InvalidArgument);
}

namespace {

// The boundary as a set of (corner vertex ids rotated to start at the smallest, cut?) from a
// full pass over the mesh: the independent answer.
using Face = std::pair<std::array<std::uint32_t, 3>, bool>;
Face canonical(std::array<std::uint32_t, 3> v, bool cut) {
  std::rotate(v.begin(), std::min_element(v.begin(), v.end()), v.end());
  return {v, cut};
}
std::multiset<Face> recount(const TetMesh& m) {
  std::multiset<Face> out;
  for (const BoundaryFace& f : m.boundary_faces())
    out.insert(canonical({f.vertices[0].idx(), f.vertices[1].idx(), f.vertices[2].idx()}, f.tag == kTagCut));
  return out;
}
std::multiset<Face> tracked(const BoundaryTracker& t) {
  std::multiset<Face> out;
  for (const auto& tri : t.triangles())
    if (tri.v[0] != kNoSlot) {
      for (std::uint32_t slot : tri.v) REQUIRE(t.vertices()[slot].is_valid());  // a live triangle's corners are live slots
      out.insert(canonical({t.vertices()[tri.v[0]].idx(), t.vertices()[tri.v[1]].idx(), t.vertices()[tri.v[2]].idx()},
                           tri.flags & kTriangleCut));
    }
  return out;
}

// A page's copy: what the messages build, read back as a snapshot's arrays.
struct Page {
  std::vector<float> pos;
  std::vector<std::uint32_t> tris;
  void apply(const FrameMessage& m) {
    if (m.reset) pos.clear(), tris.clear();
    pos.resize(3 * m.vertex_slots, NAN);
    tris.resize(4 * m.triangle_slots, kNoSlot);
    for (const auto& p : m.positions)
      for (int k = 0; k < 3; ++k) pos[3 * p.slot + k] = p.p[k];
    for (std::uint32_t s : m.removed)
      for (int k = 0; k < 4; ++k) tris[4 * s + k] = kNoSlot;
    for (const auto& t : m.set) tris[4 * t.slot] = t.v[0], tris[4 * t.slot + 1] = t.v[1], tris[4 * t.slot + 2] = t.v[2], tris[4 * t.slot + 3] = t.flags;
  }
};

Snapshot snapshot_of(const TetMesh& m, const BoundaryTracker& t, std::uint32_t frame, float shift) {
  Snapshot s;
  s.frame = frame;
  s.positions.assign(3 * t.vertices().size(), NAN);
  for (std::size_t i = 0; i < t.vertices().size(); ++i)
    if (t.vertices()[i].is_valid())
      for (int k = 0; k < 3; ++k) s.positions[3 * i + k] = float(m.rest(t.vertices()[i])[k]) + (k == 2 ? shift : 0.f);
  s.tris.assign(4 * t.triangles().size(), kNoSlot);
  for (std::size_t i = 0; i < t.triangles().size(); ++i)
    if (t.triangles()[i].v[0] != kNoSlot) {
      for (int k = 0; k < 3; ++k) s.tris[4 * i + k] = t.triangles()[i].v[k];
      s.tris[4 * i + 3] = t.triangles()[i].flags;
    }
  return s;
}

}  // namespace

TEST_CASE("the tracked boundary follows progressive cuts, and the page's copy follows the messages") {
  TetMesh m = make_box(Vec3(1, 1, 1), {5, 5, 5});
  BoundaryTracker tracker(m, {});
  QualityWatch quality(m, 10.0);
  CHECK(tracked(tracker) == recount(m));
  CHECK(tracker.cut_triangle_count() == 0);

  ClientMirror mirror;
  Page page;
  page.apply(diff(snapshot_of(m, tracker, 0, 0), mirror));

  Cutter cutter(m);
  cutter.start({Vec3(0.43, -0.2, 1.2), Vec3(0.43, 1.2, 1.2)});
  std::size_t sent_positions = 0;
  for (int step = 1; step <= 8; ++step) {
    const double z = 1.2 - 0.15 * step;
    CutStepReport r = cutter.advance({Vec3(0.43, -0.2, z), Vec3(0.43, 1.2, z)});
    tracker.apply(r.change);
    quality.apply(r.change);
    if (step == 8) {
      const TopologyChange fin = cutter.finish().change;
      tracker.apply(fin);
      quality.apply(fin);
    }
    REQUIRE(tracked(tracker) == recount(m));
    // The incremental quality figures against a pass over every tet.
    const QualityRange all = quality_range(m, 10.0);
    CHECK(quality.min_dihedral() == all.min_dihedral);
    CHECK(quality.below() == all.below);
    // Every other frame the body "moves" (all positions change); in between only topology does.
    const Snapshot s = snapshot_of(m, tracker, std::uint32_t(step), step % 2 ? 0.f : 0.01f * float(step));
    const FrameMessage msg = decode_frame(encode(diff(s, mirror)));
    sent_positions += msg.positions.size();
    page.apply(msg);
    CHECK(page.tris == s.tris);
    for (std::size_t i = 0; i < s.tris.size() / 4; ++i)
      if (s.tris[4 * i] != kNoSlot)
        for (int k = 0; k < 3; ++k)
          for (int c = 0; c < 3; ++c) CHECK(page.pos[3 * s.tris[4 * i + k] + c] == s.positions[3 * s.tris[4 * i + k] + c]);
  }
  CHECK(tracker.cut_triangle_count() > 0);
  const std::multiset<Face> now = recount(m);
  CHECK(tracker.cut_triangle_count() == std::size_t(std::count_if(now.begin(), now.end(), [](const Face& f) { return f.second; })));
  // A frame where nothing changed sends nothing but its figures.
  const Snapshot same = snapshot_of(m, tracker, 9, 0.01f * 8);
  const FrameMessage quiet = diff(same, mirror);
  CHECK(quiet.positions.empty());
  CHECK(quiet.set.empty());
  CHECK(quiet.removed.empty());
  CHECK(sent_positions > 0);
}

TEST_CASE("through the runner's change observer the boundary follows outside blades and removed fragments") {
  // The sample liver scene (static FEM: a detached part is removed). A blade through the whole
  // depth swept across the body at x = 150 cuts off the part away from the fixed side.
  SceneRunner run(load_scene(std::string(INCISE_SOURCE_DIR) + "/samples/scenes/liver_cut.json"));
  const TetMesh& m = run.mesh();
  BoundaryTracker tracker(m, {});
  QualityWatch quality(m, 10.0);
  run.set_change_observer([&](const TopologyChange& c) {
    tracker.apply(c);
    quality.apply(c);
  });
  const std::size_t tets_before = m.num_tets();
  run.advance_blade({Vec3(150, 0, 0), Vec3(150, 0, 220)});
  for (int k = 1; k <= 11; ++k) {
    run.advance_blade({Vec3(150, 20.0 * k, 0), Vec3(150, 20.0 * k, 220)});
    REQUIRE(tracked(tracker) == recount(m));
  }
  run.finish_blade();
  CHECK(tracked(tracker) == recount(m));
  CHECK(run.fragments_handled() == 1);
  CHECK(m.num_tets() < tets_before);  // the far part went
  const QualityRange all = quality_range(m, 10.0);
  CHECK(quality.min_dihedral() == all.min_dihedral);
  CHECK(quality.below() == all.below);
  CHECK(tracker.cut_triangle_count() > 0);
}
