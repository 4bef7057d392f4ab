// The one place mesh/io builds an IoError. GCC 12 reports a spurious -Wrestrict inside
// std::string concatenation once IoError's constructor is inlined (GCC PR105329); the
// pragma must precede the standard headers to reach the code inlined from them.
#if defined(__GNUC__) && !defined(__clang__)
#pragma GCC diagnostic ignored "-Wrestrict"
#endif
#include "mesh/errors.h"
#include "mesh/io/parse_util.h"

namespace incise::io {

void throw_io(const std::string& file, long line, const std::string& reason) { throw IoError(file, line, reason); }

}  // namespace incise::io
