#pragma once
// Every file incise reads is checked here first: it must exist and be a regular file (a
// symbolic link to one is fine). A directory, a device (/dev/zero never ends), a FIFO (blocks
// until a writer comes) or a socket is refused with IoError naming the file, before any read.
#include <cstdint>
#include <string>

namespace incise {

// The file's size in bytes; IoError(path, 0, reason) when it is missing or not a regular file.
std::uintmax_t check_input_file(const std::string& path);

}  // namespace incise
