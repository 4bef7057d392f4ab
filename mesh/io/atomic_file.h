#pragma once
// Atomic file output: data goes to a temporary file in the destination's directory, which
// commit() renames over the destination. Until then the destination is untouched; if the
// object is destroyed without commit() (an exception while writing), the temporary is
// removed. Throws IoError naming the destination when the file cannot be created or written.
#include <string>
#include <string_view>

namespace incise {

class AtomicFile {
public:
  explicit AtomicFile(std::string path);
  ~AtomicFile();
  AtomicFile(const AtomicFile&) = delete;
  AtomicFile& operator=(const AtomicFile&) = delete;

  void write(std::string_view data);
  // Writes `buffer` when it has grown past `threshold` bytes and clears it: writers append
  // to a string and call this in their loops, so memory stays bounded on large meshes.
  void flush_if_large(std::string& buffer, std::size_t threshold = std::size_t(1) << 20) {
    if (buffer.size() >= threshold) {
      write(buffer);
      buffer.clear();
    }
  }
  // Flushes, closes and renames the temporary onto the destination.
  void commit();

  const std::string& path() const { return path_; }
  const std::string& temp_path() const { return temp_; }

private:
  void discard() noexcept;
  std::string path_;
  std::string temp_;
  int fd_ = -1;
  bool committed_ = false;
};

}  // namespace incise
