#pragma once
// Atomic file output: data goes to a temporary file in the destination's directory, which
// commit() renames over the destination. Until then the destination is untouched; if the
// object is destroyed without commit() (an exception while writing), the temporary is
// removed. Throws IoError naming the destination when the file cannot be created or written.
//
// OutputTransaction groups every file one command writes: the command reserves its output
// paths before any work (check_output_path: a typo costs nothing), stages each file as an
// AtomicFile, and commit() closes every temporary first and renames only when all of them were
// written. A failure before commit() -- in the work, in any writer, a full disk -- leaves every
// existing file as it was and no temporary behind.
#include <memory>
#include <string>
#include <string_view>
#include <vector>

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
  // Flushes and closes the temporary without renaming it (OutputTransaction: every file is
  // complete before the first rename). commit() afterwards only renames.
  void close();

  const std::string& path() const { return path_; }
  const std::string& temp_path() const { return temp_; }

private:
  void discard() noexcept;
  std::string path_;
  std::string temp_;
  int fd_ = -1;
  bool committed_ = false;
  bool closed_ = false;
};

// Throws IoError naming `path` when a file cannot be written there: empty, an existing
// directory, a name ending in '/', or a parent that is missing or not a directory. Run on
// every output path before the work, so a long run never ends in "cannot create".
void check_output_path(const std::string& path);

// The same for an output directory (created at the end if missing, parents too): throws
// IoError when `path` is empty, an existing non-directory, or under a file.
void check_output_dir(const std::string& path);

class OutputTransaction {
public:
  // Checks `path` (check_output_path) and that no other reserved output of this transaction is
  // the same file (`role` names the option in that message, e.g. "--json").
  void reserve(const std::string& path, const std::string& role);
  // An input of the command: no output may be the same file (by device and inode, so a link
  // or another spelling of the path counts), checked now against the outputs reserved so far
  // and later against each new one. A missing input is left to its reader.
  void forbid_input(const std::string& path);
  // A staged file for `path` (reserved here if it was not); written by the caller.
  AtomicFile& open(const std::string& path);
  // Stages a whole text file.
  void write_text(const std::string& path, std::string_view text);
  // Closes every staged temporary, then renames them in the order they were opened.
  void commit();

private:
  struct Reserved {
    std::string path, key, role;
  };
  std::vector<Reserved> reserved_;
  struct Input {
    std::string path;
    unsigned long long dev = 0, ino = 0;
  };
  std::vector<Input> inputs_;
  void check_not_input(const Reserved& out) const;
  std::vector<std::unique_ptr<AtomicFile>> files_;
};

}  // namespace incise
