#pragma once
// The viewer's binary messages (docs/view.md, "Wire format"). Little-endian, 4-byte fields,
// so the page reads them with one DataView. No Boost here: the page's encoder (viewer.js) and
// this file are the two ends; tests/view round-trips both directions.
//
// Server -> page, one message per delivered frame: what changed since the frame that page
// last acknowledged (boundary vertex positions, boundary triangles set or removed, optional
// per-triangle colours), plus the overlay's figures as a JSON text.
// Page -> server: one input each (blade, probe, pause/step/reset, colour mode, frame ack).
#include <array>
#include <cstdint>
#include <span>
#include <string>
#include <vector>

namespace incise::view {

inline constexpr std::uint8_t kFrameMessage = 1;
inline constexpr std::uint16_t kWireVersion = 1;

// Triangle flags (FrameMessage::Triangle::flags).
inline constexpr std::uint32_t kTriangleCut = 1;    // a face a cut opened (kTagCut)
inline constexpr std::uint32_t kTriangleFixed = 2;  // its three corners are held by the scene
inline constexpr std::uint32_t kTriangleWorst = 4;  // a face of one of the worst elements (look mode; live: the clip view)
inline constexpr std::uint32_t kTriangleLoaded = 8; // its three corners carry a scene load (force, probe, pressure, traction)
inline constexpr std::uint32_t kTriangleInterface = 16;  // between two labels (look mode, colouring by label)

struct FrameMessage {
  bool reset = false;                // the page drops every slot first (a new run or a reset)
  std::uint32_t frame = 0;
  std::uint32_t vertex_slots = 0;    // sizes of the page's arrays (slots below these)
  std::uint32_t triangle_slots = 0;
  struct Position {
    std::uint32_t slot = 0;
    std::array<float, 3> p{};
  };
  struct Triangle {
    std::uint32_t slot = 0;
    std::array<std::uint32_t, 3> v{};  // vertex slots, outward orientation
    std::uint32_t flags = 0;
  };
  std::vector<Position> positions;       // boundary vertices that moved (or are new)
  std::vector<std::uint32_t> removed;    // triangle slots gone
  std::vector<Triangle> set;             // triangle slots new or changed
  std::vector<float> scalars;            // empty, or one colour value per triangle slot
  float scalar_lo = 0, scalar_hi = 0;    // the colour scale
  std::string stats_json;                // the overlay's figures
};

std::vector<std::uint8_t> encode(const FrameMessage& m);
// Throws InvalidArgument naming what is wrong (truncated, counts beyond the slots, ...).
FrameMessage decode_frame(std::span<const std::uint8_t> bytes);

enum class InputKind : std::uint8_t {
  BladeStart = 1,  // a b: the blade's edge, body coordinates (places a new cut)
  BladeMove,       // a b: the blade's next position (cuts what it sweeps)
  BladeEnd,        // withdraw the blade
  ProbeGrab,       // point, radius: grab the boundary near point
  ProbeMove,       // displacement from where it was grabbed
  ProbeRelease,
  Pause,
  Resume,
  Step,            // one frame while paused
  Reset,           // the scene from its start
  Colour,          // value: 0 none, 1 von Mises stress, 2 element quality (min dihedral)
  Ack,             // value: the frame the page has drawn (the next one may be sent)
  Frame,           // value: which frame of a run directory to show (look mode)
  Record,          // value: 1 starts a take (frames and the inputs that replay them), 0 ends it
  Clip,            // value: show the tets whose smallest dihedral is below this many degrees (0: none)
};
// 0 plain, 1 von Mises, 2 element quality; look mode adds 3 label, 4 boundary tag.
inline constexpr std::uint32_t kColourModes = 5;

struct InputMessage {
  InputKind kind = InputKind::Pause;
  std::array<float, 6> v{};  // BladeStart/Move: a, b; ProbeGrab: point, radius; ProbeMove: d
  std::uint32_t value = 0;   // Colour: mode; Ack, Frame: frame; Record: 1 start, 0 stop
};

inline constexpr std::uint32_t kMaxClipDeg = 90;

// Exact size of an input's encoding (each kind has one), 0 for an unknown kind byte.
std::size_t input_size(std::uint8_t kind);
std::vector<std::uint8_t> encode(const InputMessage& m);
// Throws InvalidArgument: unknown kind, wrong length, a number that is not finite, a colour
// mode out of range. A message that throws changes nothing.
InputMessage decode_input(std::span<const std::uint8_t> bytes);

}  // namespace incise::view
