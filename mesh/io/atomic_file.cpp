#include "mesh/io/atomic_file.h"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstdio>
#include <cstring>

#include <filesystem>

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

void AtomicFile::close() {
  if (closed_) return;
  if (fd_ < 0) io::throw_io(path_, 0, "close without an open file");
  if (::close(fd_) != 0) {
    int err = errno;
    fd_ = -1;
    discard();
    io::throw_io(path_, 0, std::string("close failed: ") + std::strerror(err));
  }
  fd_ = -1;
  closed_ = true;
}

void AtomicFile::commit() {
  if (committed_) io::throw_io(path_, 0, "committed twice");
  close();
  if (std::rename(temp_.c_str(), path_.c_str()) != 0) {
    int err = errno;
    discard();
    io::throw_io(path_, 0, std::string("cannot rename temporary into place: ") + std::strerror(err));
  }
  committed_ = true;
}

void check_output_path(const std::string& path) {
  namespace fs = std::filesystem;
  if (path.empty()) io::throw_io("<empty path>", 0, "no output file name");
  if (path.back() == '/') io::throw_io(path, 0, "output path names a directory");
  std::error_code ec;
  const fs::path p(path);
  if (fs::is_directory(p, ec)) io::throw_io(path, 0, "output path is a directory");
  fs::path parent = p.parent_path();
  if (parent.empty()) parent = ".";
  if (!fs::exists(parent, ec)) io::throw_io(path, 0, "cannot write here: directory " + parent.string() + " does not exist");
  if (!fs::is_directory(parent, ec)) io::throw_io(path, 0, "cannot write here: " + parent.string() + " is not a directory");
  if (::access(parent.c_str(), W_OK) != 0)
    io::throw_io(path, 0, "cannot write here: directory " + parent.string() + ": " + std::strerror(errno));
}

void check_output_dir(const std::string& path) {
  namespace fs = std::filesystem;
  if (path.empty()) io::throw_io("<empty path>", 0, "no output directory name");
  std::error_code ec;
  fs::path p = fs::absolute(path).lexically_normal();
  if (fs::exists(p, ec) && !fs::is_directory(p, ec)) io::throw_io(path, 0, "output path exists and is not a directory");
  while (!fs::exists(p, ec) && p.has_parent_path() && p.parent_path() != p) p = p.parent_path();
  if (!fs::is_directory(p, ec)) io::throw_io(path, 0, "cannot create the output directory: " + p.string() + " is not a directory");
  if (::access(p.c_str(), W_OK) != 0)
    io::throw_io(path, 0, "cannot create the output directory under " + p.string() + ": " + std::strerror(errno));
}

void OutputTransaction::reserve(const std::string& path, const std::string& role) {
  check_output_path(path);
  // Two roles naming one file (a report path equal to the mesh, "./a" and "a") would leave only
  // the last one written: compare the resolved paths.
  std::error_code ec;
  std::filesystem::path key = std::filesystem::weakly_canonical(std::filesystem::absolute(path), ec);
  if (ec) key = std::filesystem::absolute(path).lexically_normal();
  for (const Reserved& r : reserved_) {
    if (r.key != key.string()) continue;
    if (r.path == path && r.role == role) return;
    io::throw_io(path, 0, role + " names the same file as " + r.role);
  }
  reserved_.push_back({path, key.string(), role});
  check_not_input(reserved_.back());
}

void OutputTransaction::forbid_input(const std::string& path) {
  struct stat st {};
  if (::stat(path.c_str(), &st) != 0) return;
  inputs_.push_back({path, static_cast<unsigned long long>(st.st_dev), static_cast<unsigned long long>(st.st_ino)});
  for (const Reserved& r : reserved_) check_not_input(r);
}

void OutputTransaction::check_not_input(const Reserved& out) const {
  struct stat st {};
  if (inputs_.empty() || ::stat(out.path.c_str(), &st) != 0) return;
  for (const Input& in : inputs_)
    if (static_cast<unsigned long long>(st.st_dev) == in.dev && static_cast<unsigned long long>(st.st_ino) == in.ino)
      io::throw_io(out.path, 0, out.role + " names the input " + in.path + ": refused, it would be overwritten");
}

AtomicFile& OutputTransaction::open(const std::string& path) {
  bool known = false;
  for (const Reserved& r : reserved_) known = known || r.path == path;
  if (!known) reserve(path, path);
  for (const auto& f : files_)
    if (f->path() == path) io::throw_io(path, 0, "staged twice");
  files_.push_back(std::make_unique<AtomicFile>(path));
  return *files_.back();
}

void OutputTransaction::write_text(const std::string& path, std::string_view text) { open(path).write(text); }

void OutputTransaction::commit() {
  for (auto& f : files_) f->close();
  for (auto& f : files_) f->commit();
  files_.clear();
}

}  // namespace incise
