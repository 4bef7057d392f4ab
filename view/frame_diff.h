#pragma once
// What one page is sent: the difference between the newest published frame and the copy of
// what that page already has (its mirror). A page that acknowledges slowly simply gets the
// newest frame's difference when it is ready: frames in between are dropped, never queued,
// and nothing is lost (the difference is against what the page holds, not against the
// previous frame). O(boundary) per message.
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "view/wire_format.h"

namespace incise::view {

// One frame as the simulation thread publishes it (immutable once published).
struct Snapshot {
  std::uint32_t generation = 0;  // bumped by a reset: slots start over
  std::uint32_t frame = 0;
  std::vector<float> positions;      // 3 per vertex slot; NaN for a free slot
  std::vector<std::uint32_t> tris;   // 4 per triangle slot: corners' vertex slots, flags; kNoSlot: free
  std::vector<float> scalars;        // empty or one per triangle slot
  std::uint32_t scalar_version = 0;  // bumped when scalars are recomputed
  float scalar_lo = 0, scalar_hi = 0;
  float position_epsilon = 0;        // moves below this are not sent
  std::string stats_json;
  std::size_t triangles = 0, cut_triangles = 0, tets = 0, vertices = 0;
};

struct ClientMirror {
  std::uint32_t generation = 0xffffffffu;  // none yet: the first message resets the page
  std::vector<float> positions;
  std::vector<std::uint32_t> tris;
  std::uint32_t scalar_version = 0;
  bool had_scalars = false;
};

// The message bringing `mirror` to `now`; `mirror` then equals `now`.
FrameMessage diff(const Snapshot& now, ClientMirror& mirror);

}  // namespace incise::view
