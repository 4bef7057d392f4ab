#include "mesh/io/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>

#include "mesh/errors.h"
#include "mesh/io/parse_util.h"

namespace incise {

namespace {
std::atomic<unsigned> g_counter{0};
}

AtomicFile::AtomicFile(std::string path) : path_(std::move(path)) {
  if (path_.empty()) io::throw_io("<empty path>", 0, "no output file name");
  // Same directory as the destination, so the rename stays on one file system.
  auto slash = path_.find_last_of('/');
  std::string dir = slash == std::string::npos ? std::string() : path_.substr(0, slash + 1);
  std::string base = slash == std::string::npos ? path_ : path_.substr(slash + 1);
  if (base.empty()) io::throw_io(path_, 0, "output path names a directory");
  for (int attempt = 0; attempt < 100; ++attempt) {
    temp_ = dir + "." + base + ".tmp" + std::to_string(::getpid()) + "_" + std::to_string(g_counter++);
    fd_ = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
    if (fd_ >= 0) return;
    if (errno != EEXIST) break;
  }
  int err = errno;
  temp_.clear();
  io::throw_io(path_, 0, std::string("cannot create output file: ") + std::strerror(err));
}

AtomicFile::~AtomicFile() {
  if (!committed_) discard();
}

void AtomicFile::discard() noexcept {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
  if (!temp_.empty()) ::unlink(temp_.c_str());
  temp_.clear();
}

void AtomicFile::write(std::string_view data) {
  if (fd_ < 0) io::throw_io(path_, 0, "write after commit");
  const char* p = data.data();
  std::size_t left = data.size();
  while (left > 0) {
    ssize_t n = ::write(fd_, p, left);
    if (n < 0) {
      if (errno == EINTR) continue;
      int err = errno;
      discard();
      io::throw_io(path_, 0, std::string("write failed: ") + std::strerror(err));
    }
    p += n;
    left -= static_cast<std::size_t>(n);
  }
}

void AtomicFile::commit() {
  if (fd_ < 0) io::throw_io(path_, 0, "commit without an open file");
  if (::close(fd_) != 0) {
    int err = errno;
    fd_ = -1;
    discard();
    io::throw_io(path_, 0, std::string("close failed: ") + std::strerror(err));
  }
  fd_ = -1;
  if (std::rename(temp_.c_str(), path_.c_str()) != 0) {
    int err = errno;
    discard();
    io::throw_io(path_, 0, std::string("cannot rename temporary into place: ") + std::strerror(err));
  }
  committed_ = true;
}

}  // namespace incise
