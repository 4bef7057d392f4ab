#pragma once
// Internal to mesh/io: a cursor over a file held in memory that tracks line numbers and
// turns every malformed token into IoError("FILE:LINE: reason"). Readers check declared
// counts against the bytes left (fits()) before reserving, so a header that claims 10^12
// elements fails at once instead of allocating.
#include <charconv>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <string>
#include <string_view>

#include "mesh/errors.h"

namespace incise::io {

// Throws IoError(file, line, reason). Out of line: one place for the exception's string
// building (and for GCC 12's spurious -Wrestrict on it, PR105329).
[[noreturn]] void throw_io(const std::string& file, long line, const std::string& reason);

// The whole file. Throws IoError if it cannot be opened or read.
std::string read_file_bytes(const std::string& path);

class Cursor {
public:
  Cursor(const std::string& file, std::string_view text, char comment = 0, long first_line = 1)
      : file_(file), b_(text.data()), p_(text.data()), e_(text.data() + text.size()), comment_(comment),
        line_(first_line) {}

  const std::string& file() const { return file_; }
  long line() const { return binary_seen_ ? 0 : line_; }
  [[noreturn]] void fail(const std::string& why) const { throw_io(file_, line(), why); }

  bool at_end() {
    skip_ws();
    return p_ == e_;
  }
  std::size_t remaining() const { return static_cast<std::size_t>(e_ - p_); }
  const char* pos() const { return p_; }
  const char* begin() const { return b_; }
  const char* end() const { return e_; }

  // Skips whitespace, newlines and comments.
  void skip_ws() {
    while (p_ < e_) {
      char c = *p_;
      if (c == '\n') {
        ++line_;
        ++p_;
      } else if (c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v') {
        ++p_;
      } else if (comment_ && c == comment_) {
        while (p_ < e_ && *p_ != '\n') ++p_;
      } else {
        break;
      }
    }
  }
  // Skips blanks and a comment on the current line only.
  void skip_blank() {
    while (p_ < e_ && (*p_ == ' ' || *p_ == '\t' || *p_ == '\r' || *p_ == '\f' || *p_ == '\v')) ++p_;
    if (comment_ && p_ < e_ && *p_ == comment_)
      while (p_ < e_ && *p_ != '\n') ++p_;
  }
  bool eol() {
    skip_blank();
    return p_ == e_ || *p_ == '\n';
  }
  // Moves past the next newline.
  void next_line() {
    while (p_ < e_ && *p_ != '\n') ++p_;
    if (p_ < e_) {
      ++p_;
      ++line_;
    }
  }
  // The rest of the current line (without the newline); moves past it.
  std::string_view rest_of_line() {
    const char* s = p_;
    while (p_ < e_ && *p_ != '\n') ++p_;
    std::string_view r(s, static_cast<std::size_t>(p_ - s));
    if (!r.empty() && r.back() == '\r') r.remove_suffix(1);
    if (p_ < e_) {
      ++p_;
      ++line_;
    }
    return r;
  }

  std::string_view token(const char* what) {
    skip_ws();
    if (p_ == e_) fail(std::string("unexpected end of file, expected ") + what);
    return raw_token();
  }
  // A token that must be on the current line.
  std::string_view token_on_line(const char* what) {
    if (eol()) fail(std::string("line ends early, expected ") + what);
    return raw_token();
  }
  // Peeks at the next token without consuming it (may cross lines); empty at the end.
  std::string_view peek() {
    skip_ws();
    const char* s = p_;
    const char* q = p_;
    while (q < e_ && !is_space(*q)) ++q;
    return {s, static_cast<std::size_t>(q - s)};
  }

  long long integer(const char* what, bool same_line = false) {
    std::string_view t = same_line ? token_on_line(what) : token(what);
    return to_integer(t, what);
  }
  double real(const char* what, bool same_line = false) {
    std::string_view t = same_line ? token_on_line(what) : token(what);
    return to_real(t, what);
  }
  // A count that must be >= 0 and leave at least `min_bytes_each` bytes per entry.
  std::size_t count(const char* what, std::size_t min_bytes_each, bool same_line = false) {
    long long n = integer(what, same_line);
    if (n < 0) fail(std::string("negative ") + what + " " + std::to_string(n));
    check_fits(static_cast<unsigned long long>(n), min_bytes_each, what);
    return static_cast<std::size_t>(n);
  }
  void check_fits(unsigned long long n, std::size_t min_bytes_each, const char* what) const {
    if (n >= 0xffffffffull) fail(std::string(what) + " " + std::to_string(n) + " exceeds 32-bit ids");
    if (min_bytes_each && n > remaining() / min_bytes_each)
      fail(std::string("declared ") + what + " " + std::to_string(n) + " cannot fit in the " +
           std::to_string(remaining()) + " bytes left (truncated file?)");
  }

  long long to_integer(std::string_view t, const char* what) const {
    long long v = 0;
    const char* s = t.data();
    const char* e = t.data() + t.size();
    if (s < e && *s == '+') ++s;
    auto r = std::from_chars(s, e, v);
    if (r.ec != std::errc() || r.ptr != e || s == e)
      fail(std::string("expected ") + what + ", got '" + shorten(t) + "'");
    return v;
  }
  double to_real(std::string_view t, const char* what) const {
    double v = 0;
    const char* s = t.data();
    const char* e = t.data() + t.size();
    if (s < e && *s == '+') ++s;
    auto r = std::from_chars(s, e, v);
    if (r.ec != std::errc() || r.ptr != e || s == e)
      fail(std::string("expected ") + what + ", got '" + shorten(t) + "'");
    if (!std::isfinite(v)) fail(std::string("non-finite ") + what + " '" + shorten(t) + "'");
    return v;
  }

  // Binary payloads (VTK legacy): after the first one, line numbers are no longer meaningful.
  const char* take_bytes(std::size_t n, const char* what) {
    if (n > remaining()) fail(std::string("truncated binary ") + what);
    const char* s = p_;
    p_ += n;
    binary_seen_ = true;
    return s;
  }
  // Skips exactly one newline (and a CR before it) if present: the separator before binary data.
  void skip_one_newline() {
    while (p_ < e_ && (*p_ == ' ' || *p_ == '\t' || *p_ == '\r')) ++p_;
    if (p_ < e_ && *p_ == '\n') {
      ++p_;
      ++line_;
    }
  }

  static std::string shorten(std::string_view t) {
    std::string s(t.substr(0, 40));
    for (char& c : s)
      if (static_cast<unsigned char>(c) < 32 || static_cast<unsigned char>(c) > 126) c = '?';
    if (t.size() > 40) s += "...";
    return s;
  }

private:
  static bool is_space(char c) { return c == ' ' || c == '\t' || c == '\n' || c == '\r' || c == '\f' || c == '\v'; }
  std::string_view raw_token() {
    const char* s = p_;
    while (p_ < e_ && !is_space(*p_) && !(comment_ && *p_ == comment_)) ++p_;
    return {s, static_cast<std::size_t>(p_ - s)};
  }

  std::string file_;
  const char* b_;
  const char* p_;
  const char* e_;
  char comment_;
  long line_;
  bool binary_seen_ = false;
};

inline bool starts_with_nocase(std::string_view s, std::string_view prefix) {
  if (s.size() < prefix.size()) return false;
  for (std::size_t i = 0; i < prefix.size(); ++i) {
    char a = s[i], b = prefix[i];
    if (a >= 'A' && a <= 'Z') a = static_cast<char>(a - 'A' + 'a');
    if (b >= 'A' && b <= 'Z') b = static_cast<char>(b - 'A' + 'a');
    if (a != b) return false;
  }
  return true;
}
inline bool equals_nocase(std::string_view a, std::string_view b) {
  return a.size() == b.size() && starts_with_nocase(a, b);
}

// Appends numbers to a text buffer: doubles in shortest round-trip form (exact on read).
inline void append_real(std::string& out, double v) {
  char buf[32];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}
inline std::string real_text(double v) {
  std::string s;
  append_real(s, v);
  return s;
}
inline void append_int(std::string& out, long long v) {
  char buf[24];
  auto r = std::to_chars(buf, buf + sizeof buf, v);
  out.append(buf, r.ptr);
}

}  // namespace incise::io
