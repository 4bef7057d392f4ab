// libFuzzer harness for the cutter: the input bytes are a script of blade moves on a small
// mesh (a box of Kuhn tets, whose vertex layers, edges and faces blades hit exactly, or an
// ellipsoid). After every step the mesh must validate (orientation, closed manifold
// boundary) and, in subdivision mode, every label keep its volume up to what the improvement's
// tolerance-mode contractions report moving. A refused blade (incise::Error) is fine; anything
// else aborts. The script ends with finish(), checked the same way.
//
// Byte 0: options (snap, mode, mesh, improvement). Then 7 bytes per move (24 at most): the action (start a
// new cut, one-shot plane, finish, advance) and six coordinates. A coordinate byte below 128 is on a
// lattice of 1/8 of the box (hits vertices, edges, faces); above it is continuous.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <map>

#include "cut/cutter.h"
#include "mesh/errors.h"
#include "mesh/generate.h"

namespace {

using incise::Vec3;

double coordinate(std::uint8_t b) {
  if (b < 128) return -0.25 + 0.125 * (b % 13);  // -0.25 .. 1.25 in steps of 1/8
  return -0.3 + 1.6 * (b - 128) / 127.0;
}

std::map<int, double> label_volumes(const incise::TetMesh& m) {
  std::map<int, double> v;
  for (incise::TetId t : m.tets()) v[m.label(t)] += m.volume(t);
  return v;
}

const incise::TetMesh& base_mesh(int which) {
  static const incise::TetMesh box = [] {
    incise::TetMesh m = incise::make_box(Vec3(1, 1, 1), {4, 4, 4});
    m.discard_change();
    return m;
  }();
  static const incise::TetMesh ball = [] {
    incise::TetMesh m = incise::make_ellipsoid(Vec3(0.5, 0.4, 0.3), 2);
    incise::tag_boundary(m);
    m.discard_change();
    return m;
  }();
  return which ? ball : box;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::uint8_t o = data[0];
  incise::TetMesh mesh = base_mesh(o & 1);
  incise::CutOptions opt;
  const double snaps[] = {0.0, 0.02, 0.1, 0.3};
  opt.snap = snaps[(o >> 1) & 3];
  opt.mode = ((o >> 3) & 7) == 7 ? incise::CutMode::Remove : incise::CutMode::Subdivide;
  opt.improve = (o >> 6) & 1;
  opt.fragment_search_limit = 500;
  opt.finish_improve_work = 50;  // finish()'s full improvement takes seconds instrumented (tested elsewhere)
  const auto vol0 = label_volumes(mesh);
  double total = 0;
  for (const auto& [l, v] : vol0) total += v;
  incise::Cutter cutter(mesh, opt);
  // The box spans [0,1]^3, the ellipsoid is centred at the origin.
  const Vec3 shift = (o & 1) ? Vec3(-0.5, -0.5, -0.5) : Vec3::Zero();
  double moved = 0;  // label volume the improvement's contractions report moving
  auto check = [&] {
    mesh.validate(incise::TetMesh::ValidateOptions{true, true});  // throws (and aborts) on a bug
    if (opt.mode == incise::CutMode::Subdivide) {
      const auto vol = label_volumes(mesh);
      if (vol.size() != vol0.size()) std::abort();
      for (const auto& [l, v] : vol0)
        if (std::abs(vol.at(l) - v) > 1e-9 * total + moved) std::abort();
    }
  };
  std::size_t steps = 0;
  for (std::size_t i = 1; i + 7 <= size && steps < 24; i += 7, ++steps) {
    const std::uint8_t* b = data + i;
    const Vec3 p = Vec3(coordinate(b[1]), coordinate(b[2]), coordinate(b[3])) + shift;
    const Vec3 q = Vec3(coordinate(b[4]), coordinate(b[5]), coordinate(b[6])) + shift;
    try {
      switch (b[0] % 8) {
        case 0: cutter.start({p, q}); break;
        case 1: moved += cutter.cut_plane(p, q - shift - Vec3(0.5, 0.5, 0.5)).improve.volume_change; break;
        case 2: moved += cutter.finish().improve.volume_change; break;
        default:  // a move with no blade placed places it (advance() would refuse)
          if (!cutter.in_cut())
            cutter.start({p, q});
          else
            moved += cutter.advance({p, q}).improve.volume_change;
          break;
      }
    } catch (const incise::InvalidMesh&) {
      std::abort();  // the cutter broke the mesh and noticed late
    } catch (const incise::Error&) {
      continue;  // a refused blade
    }
    check();
  }
  try {
    moved += cutter.finish().improve.volume_change;
  } catch (const incise::InvalidMesh&) {
    std::abort();
  } catch (const incise::Error&) {
    return 0;
  }
  check();
  return 0;
}
