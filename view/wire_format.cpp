#include "view/wire_format.h"

#include <bit>
#include <cmath>
#include <cstring>

#include "mesh/errors.h"

namespace incise::view {

namespace {

static_assert(std::endian::native == std::endian::little, "the wire format is little-endian");

class Writer {
public:
  void u8(std::uint8_t x) { out.push_back(x); }
  void u16(std::uint16_t x) { raw(&x, 2); }
  void u32(std::uint32_t x) { raw(&x, 4); }
  void f32(float x) { raw(&x, 4); }
  void raw(const void* p, std::size_t n) {
    const auto* b = static_cast<const std::uint8_t*>(p);
    out.insert(out.end(), b, b + n);
  }
  std::vector<std::uint8_t> out;
};

class Reader {
public:
  explicit Reader(std::span<const std::uint8_t> b) : b_(b) {}
  std::uint8_t u8() { return take<std::uint8_t>(); }
  std::uint16_t u16() { return take<std::uint16_t>(); }
  std::uint32_t u32() { return take<std::uint32_t>(); }
  float f32() { return take<float>(); }
  // A count of items of `size` bytes each that must fit in what is left (no huge allocation
  // from a forged count).
  std::uint32_t count(std::size_t size, const char* what) {
    const std::uint32_t n = u32();
    if (std::size_t(n) * size > left()) throw InvalidArgument(std::string("frame message: ") + what + " count beyond the message");
    return n;
  }
  std::size_t left() const { return b_.size() - at_; }
  std::string text(std::size_t n) {
    need(n);
    std::string s(reinterpret_cast<const char*>(b_.data() + at_), n);
    at_ += n;
    return s;
  }

private:
  void need(std::size_t n) const {
    if (left() < n) throw InvalidArgument("message truncated");
  }
  template <class T> T take() {
    need(sizeof(T));
    T x;
    std::memcpy(&x, b_.data() + at_, sizeof(T));
    at_ += sizeof(T);
    return x;
  }
  std::span<const std::uint8_t> b_;
  std::size_t at_ = 0;
};

}  // namespace

std::vector<std::uint8_t> encode(const FrameMessage& m) {
  Writer w;
  w.out.reserve(24 + 16 * m.positions.size() + 4 * m.removed.size() + 20 * m.set.size() + 4 * m.scalars.size() +
                m.stats_json.size());
  w.u8(kFrameMessage);
  w.u8(m.reset ? 1 : 0);
  w.u16(kWireVersion);
  w.u32(m.frame);
  w.u32(m.vertex_slots);
  w.u32(m.triangle_slots);
  w.u32(std::uint32_t(m.positions.size()));
  for (const auto& p : m.positions) {
    w.u32(p.slot);
    for (float x : p.p) w.f32(x);
  }
  w.u32(std::uint32_t(m.removed.size()));
  for (std::uint32_t s : m.removed) w.u32(s);
  w.u32(std::uint32_t(m.set.size()));
  for (const auto& t : m.set) {
    w.u32(t.slot);
    for (std::uint32_t v : t.v) w.u32(v);
    w.u32(t.flags);
  }
  w.u32(std::uint32_t(m.scalars.size()));
  w.f32(m.scalar_lo);
  w.f32(m.scalar_hi);
  for (float x : m.scalars) w.f32(x);
  w.u32(std::uint32_t(m.stats_json.size()));
  w.raw(m.stats_json.data(), m.stats_json.size());
  return std::move(w.out);
}

FrameMessage decode_frame(std::span<const std::uint8_t> bytes) {
  Reader r(bytes);
  FrameMessage m;
  if (r.u8() != kFrameMessage) throw InvalidArgument("not a frame message");
  const std::uint8_t flags = r.u8();
  if (flags > 1) throw InvalidArgument("frame message: unknown flags");
  m.reset = flags & 1;
  if (r.u16() != kWireVersion) throw InvalidArgument("frame message: unknown version");
  m.frame = r.u32();
  m.vertex_slots = r.u32();
  m.triangle_slots = r.u32();
  m.positions.resize(r.count(16, "position"));
  for (auto& p : m.positions) {
    p.slot = r.u32();
    for (float& x : p.p) x = r.f32();
    if (p.slot >= m.vertex_slots) throw InvalidArgument("frame message: vertex slot out of range");
  }
  m.removed.resize(r.count(4, "removed triangle"));
  for (auto& s : m.removed) {
    s = r.u32();
    if (s >= m.triangle_slots) throw InvalidArgument("frame message: triangle slot out of range");
  }
  m.set.resize(r.count(20, "triangle"));
  for (auto& t : m.set) {
    t.slot = r.u32();
    for (auto& v : t.v) {
      v = r.u32();
      if (v >= m.vertex_slots) throw InvalidArgument("frame message: triangle corner out of range");
    }
    t.flags = r.u32();
    if (t.slot >= m.triangle_slots) throw InvalidArgument("frame message: triangle slot out of range");
  }
  const std::uint32_t ns = r.count(4, "scalar");
  m.scalar_lo = r.f32();
  m.scalar_hi = r.f32();
  if (ns != 0 && ns != m.triangle_slots) throw InvalidArgument("frame message: scalars are one per triangle slot");
  m.scalars.resize(ns);
  for (float& x : m.scalars) x = r.f32();
  m.stats_json = r.text(r.count(1, "stats"));
  if (r.left() != 0) throw InvalidArgument("frame message: bytes after the end");
  return m;
}

std::size_t input_size(std::uint8_t kind) {
  switch (InputKind(kind)) {
    case InputKind::BladeStart:
    case InputKind::BladeMove: return 1 + 6 * 4;
    case InputKind::ProbeGrab: return 1 + 4 * 4;
    case InputKind::ProbeMove: return 1 + 3 * 4;
    case InputKind::Colour:
    case InputKind::Ack:
    case InputKind::Frame:
    case InputKind::Record:
    case InputKind::Clip: return 1 + 4;
    case InputKind::BladeEnd:
    case InputKind::ProbeRelease:
    case InputKind::Pause:
    case InputKind::Resume:
    case InputKind::Step:
    case InputKind::Reset: return 1;
  }
  return 0;
}

namespace {
int floats_of(InputKind k) {
  switch (k) {
    case InputKind::BladeStart:
    case InputKind::BladeMove: return 6;
    case InputKind::ProbeGrab: return 4;
    case InputKind::ProbeMove: return 3;
    default: return 0;
  }
}
bool has_value(InputKind k) {
  return k == InputKind::Colour || k == InputKind::Ack || k == InputKind::Frame || k == InputKind::Record ||
         k == InputKind::Clip;
}
}  // namespace

std::vector<std::uint8_t> encode(const InputMessage& m) {
  Writer w;
  w.u8(std::uint8_t(m.kind));
  for (int i = 0; i < floats_of(m.kind); ++i) w.f32(m.v[i]);
  if (has_value(m.kind)) w.u32(m.value);
  return std::move(w.out);
}

InputMessage decode_input(std::span<const std::uint8_t> bytes) {
  if (bytes.empty()) throw InvalidArgument("empty message");
  const std::size_t size = input_size(bytes[0]);
  if (size == 0) throw InvalidArgument("unknown input kind " + std::to_string(bytes[0]));
  if (bytes.size() != size)
    throw InvalidArgument("input kind " + std::to_string(bytes[0]) + ": " + std::to_string(bytes.size()) +
                          " bytes, expected " + std::to_string(size));
  Reader r(bytes);
  InputMessage m;
  m.kind = InputKind(r.u8());
  for (int i = 0; i < floats_of(m.kind); ++i) {
    m.v[i] = r.f32();
    if (!std::isfinite(m.v[i])) throw InvalidArgument("input: numbers must be finite");
  }
  if (has_value(m.kind)) m.value = r.u32();
  if (m.kind == InputKind::Colour && m.value >= kColourModes) throw InvalidArgument("input: unknown colour mode");
  if (m.kind == InputKind::Clip && m.value > kMaxClipDeg) throw InvalidArgument("input: clip angle above 90 degrees");
  if (m.kind == InputKind::Record && m.value > 1) throw InvalidArgument("input: record takes 1 (start) or 0 (stop)");
  if (m.kind == InputKind::ProbeGrab && !(m.v[3] > 0)) throw InvalidArgument("input: probe radius must be positive");
  return m;
}

}  // namespace incise::view
