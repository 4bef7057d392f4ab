#include "mesh/io/input_file.h"

#include <cerrno>
#include <cstring>
#include <sys/stat.h>

#include "mesh/errors.h"

namespace incise {

std::uintmax_t check_input_file(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0)  // one wording for a missing input everywhere
    throw IoError(path, 0, errno == ENOENT ? std::string("no such file") : std::string("cannot open: ") + std::strerror(errno));
  if (S_ISDIR(st.st_mode)) throw IoError(path, 0, "is a directory, not a file");
  if (!S_ISREG(st.st_mode))
    throw IoError(path, 0, std::string("is not a regular file (") +
                               (S_ISFIFO(st.st_mode) ? "a FIFO" : S_ISSOCK(st.st_mode) ? "a socket" : "a device") +
                               "): refused, it could block or never end");
  return std::uintmax_t(st.st_size);
}

}  // namespace incise
