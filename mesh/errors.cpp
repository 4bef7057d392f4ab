// GCC 12 reports a false -Wrestrict inside std::string concatenation here (PR105329); the
// pragma must precede the standard headers to reach the code inlined from them.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wrestrict"
#endif
#include "mesh/errors.h"

namespace incise {

namespace {

// The length of the valid UTF-8 sequence at s[i], or 0.
std::size_t utf8_sequence(const std::string& s, std::size_t i) {
  const auto b = [&](std::size_t k) { return static_cast<unsigned char>(s[k]); };
  const unsigned c = b(i);
  std::size_t n = c < 0x80 ? 1 : (c >> 5) == 0x6 ? 2 : (c >> 4) == 0xE ? 3 : (c >> 3) == 0x1E ? 4 : 0;
  if (n == 0 || i + n > s.size()) return 0;
  for (std::size_t k = 1; k < n; ++k)
    if ((b(i + k) & 0xC0) != 0x80) return 0;
  if (n == 2 && c < 0xC2) return 0;                                   // overlong
  if (n == 3 && ((c == 0xE0 && b(i + 1) < 0xA0) || (c == 0xED && b(i + 1) >= 0xA0))) return 0;  // overlong, surrogate
  if (n == 4 && ((c == 0xF0 && b(i + 1) < 0x90) || c > 0xF4 || (c == 0xF4 && b(i + 1) >= 0x90))) return 0;
  return n;
}

std::string printable(const std::string& s) {
  std::string out;
  out.reserve(s.size());
  for (std::size_t i = 0; i < s.size();) {
    const std::size_t n = utf8_sequence(s, i);
    if (n > 0 && !(n == 1 && static_cast<unsigned char>(s[i]) < 0x20 && s[i] != '\t')) {
      out.append(s, i, n);
      i += n;
    } else {
      static const char* hex = "0123456789ABCDEF";
      const unsigned char c = static_cast<unsigned char>(s[i++]);
      out += "\\x";
      out += hex[c >> 4];
      out += hex[c & 15];
    }
  }
  return out;
}

std::string io_message(const std::string& file, long line, const std::string& reason) {
  std::string msg = file;
  if (line > 0) msg += ":" + std::to_string(line);
  msg += ": ";
  msg += reason;
  return msg;
}
}  // namespace

Error::Error(const std::string& what) : std::runtime_error(printable(what)) {}

IoError::IoError(const std::string& file, long line, const std::string& reason)
    : Error(io_message(file, line, reason)), file_(file), line_(line) {}

}  // namespace incise
