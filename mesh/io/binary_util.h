#pragma once
// Internal to mesh/io: numeric types of the VTK formats and byte-order conversion.
#include <bit>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

namespace incise::io {

enum class NumType { Int8, UInt8, Int16, UInt16, Int32, UInt32, Int64, UInt64, Float32, Float64, Unknown };

inline int num_size(NumType t) {
  switch (t) {
    case NumType::Int8:
    case NumType::UInt8: return 1;
    case NumType::Int16:
    case NumType::UInt16: return 2;
    case NumType::Int32:
    case NumType::UInt32:
    case NumType::Float32: return 4;
    case NumType::Int64:
    case NumType::UInt64:
    case NumType::Float64: return 8;
    default: return 0;
  }
}
inline bool num_is_integer(NumType t) { return t != NumType::Float32 && t != NumType::Float64; }

// Reads one value of type t stored with the given byte order at p (unaligned).
inline double load_value(const char* p, NumType t, bool big_endian) {
  unsigned char b[8];
  const int n = num_size(t);
  std::memcpy(b, p, static_cast<std::size_t>(n));
  if (big_endian != (std::endian::native == std::endian::big))
    for (int i = 0; i < n / 2; ++i) std::swap(b[i], b[n - 1 - i]);
  switch (t) {
    case NumType::Int8: { std::int8_t v; std::memcpy(&v, b, 1); return v; }
    case NumType::UInt8: return b[0];
    case NumType::Int16: { std::int16_t v; std::memcpy(&v, b, 2); return v; }
    case NumType::UInt16: { std::uint16_t v; std::memcpy(&v, b, 2); return v; }
    case NumType::Int32: { std::int32_t v; std::memcpy(&v, b, 4); return v; }
    case NumType::UInt32: { std::uint32_t v; std::memcpy(&v, b, 4); return v; }
    case NumType::Int64: { std::int64_t v; std::memcpy(&v, b, 8); return static_cast<double>(v); }
    case NumType::UInt64: { std::uint64_t v; std::memcpy(&v, b, 8); return static_cast<double>(v); }
    case NumType::Float32: { float v; std::memcpy(&v, b, 4); return v; }
    case NumType::Float64: { double v; std::memcpy(&v, b, 8); return v; }
    default: return 0;
  }
}
inline std::uint64_t load_uint(const char* p, int size, bool big_endian) {
  std::uint64_t v = 0;
  for (int i = 0; i < size; ++i) {
    auto byte = static_cast<unsigned char>(p[big_endian ? i : size - 1 - i]);
    v = (v << 8) | byte;
  }
  return v;
}

// Appends a value in the given byte order.
template <class T>
void store_value(std::string& out, T v, bool big_endian) {
  char b[sizeof(T)];
  std::memcpy(b, &v, sizeof(T));
  if (big_endian != (std::endian::native == std::endian::big))
    for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
  out.append(b, sizeof(T));
}

// VTK legacy type names and VTU type names.
NumType vtk_legacy_type(std::string_view name);
NumType vtu_type(std::string_view name);

}  // namespace incise::io
