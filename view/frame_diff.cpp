#include "view/frame_diff.h"

#include <cmath>

#include "view/boundary_tracker.h"

namespace incise::view {

FrameMessage diff(const Snapshot& now, ClientMirror& mirror) {
  FrameMessage m;
  m.frame = now.frame;
  m.stats_json = now.stats_json;
  if (mirror.generation != now.generation) {
    m.reset = true;
    mirror = ClientMirror{};
    mirror.generation = now.generation;
  }
  const std::size_t nv = now.positions.size() / 3, nt = now.tris.size() / 4;
  m.vertex_slots = std::uint32_t(nv);
  m.triangle_slots = std::uint32_t(nt);
  mirror.positions.resize(3 * nv, NAN);
  for (std::size_t s = 0; s < nv; ++s) {
    const float* p = &now.positions[3 * s];
    float* q = &mirror.positions[3 * s];
    if (std::isnan(p[0])) continue;  // a free slot: the page ignores it
    bool moved = std::isnan(q[0]);
    for (int k = 0; k < 3 && !moved; ++k) moved = std::fabs(p[k] - q[k]) > now.position_epsilon;
    if (!moved) continue;
    m.positions.push_back({std::uint32_t(s), {p[0], p[1], p[2]}});
    q[0] = p[0], q[1] = p[1], q[2] = p[2];
  }
  // Slots past the page's end vanish with the smaller size; the mirror forgets them too.
  mirror.tris.resize(4 * nt, kNoSlot);
  for (std::size_t s = 0; s < nt; ++s) {
    const std::uint32_t* t = &now.tris[4 * s];
    std::uint32_t* u = &mirror.tris[4 * s];
    if (t[0] == u[0] && t[1] == u[1] && t[2] == u[2] && t[3] == u[3]) continue;
    if (t[0] == kNoSlot) m.removed.push_back(std::uint32_t(s));
    else m.set.push_back({std::uint32_t(s), {t[0], t[1], t[2]}, t[3]});
    for (int k = 0; k < 4; ++k) u[k] = t[k];
  }
  // Colours go whole when recomputed (every so often, not every frame), or when slots changed.
  const bool want = !now.scalars.empty();
  if (want && (!mirror.had_scalars || mirror.scalar_version != now.scalar_version || !m.set.empty() || m.reset)) {
    m.scalars = now.scalars;
    m.scalar_lo = now.scalar_lo;
    m.scalar_hi = now.scalar_hi;
  }
  mirror.had_scalars = want;
  mirror.scalar_version = now.scalar_version;
  return m;
}

}  // namespace incise::view
