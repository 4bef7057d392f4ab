// GCC 12 reports a false -Wrestrict inside std::string concatenation here (PR105329); the
// pragma must precede the standard headers to reach the code inlined from them.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wrestrict"
#endif
#include "mesh/errors.h"

namespace incise {

namespace {
std::string io_message(const std::string& file, long line, const std::string& reason) {
  std::string msg = file;
  if (line > 0) msg += ":" + std::to_string(line);
  msg += ": ";
  msg += reason;
  return msg;
}
}  // namespace

IoError::IoError(const std::string& file, long line, const std::string& reason)
    : Error(io_message(file, line, reason)), file_(file), line_(line) {}

}  // namespace incise
