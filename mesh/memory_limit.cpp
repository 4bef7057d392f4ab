#include "mesh/memory_limit.h"

#include <unistd.h>

#include <cstdio>
#include <fstream>
#include <sstream>

#include "mesh/errors.h"

namespace incise {

std::uint64_t available_memory_bytes() {
  std::ifstream in("/proc/meminfo");
  std::string key;
  std::uint64_t kib = 0;
  std::string unit;
  while (in >> key >> kib >> unit)
    if (key == "MemAvailable:") return kib * 1024;
  const long pages = ::sysconf(_SC_PHYS_PAGES), page = ::sysconf(_SC_PAGE_SIZE);
  return pages > 0 && page > 0 ? std::uint64_t(pages) * std::uint64_t(page) : 0;
}

std::string format_bytes(double bytes) {
  char buf[64];
  if (bytes >= 1e12) std::snprintf(buf, sizeof buf, "%.3g TB", bytes / 1e12);
  else if (bytes >= 1e9) std::snprintf(buf, sizeof buf, "%.3g GB", bytes / 1e9);
  else std::snprintf(buf, sizeof buf, "%.3g MB", bytes / 1e6);
  return buf;
}

std::string format_count(double n) {
  char buf[64];
  if (n < 1e12) std::snprintf(buf, sizeof buf, "%.0f", n);
  else std::snprintf(buf, sizeof buf, "%.3g", n);
  return buf;
}

void refuse_past_memory(const std::string& what, double bytes, const std::string& estimate, const std::string& hint) {
  const std::uint64_t have = available_memory_bytes();
  if (have == 0 || !(bytes > double(have))) return;
  throw InvalidArgument(what + " would need about " + format_bytes(bytes) + " (" + estimate + "), more than the " +
                        format_bytes(double(have)) + " this machine has available; " + hint);
}

}  // namespace incise
