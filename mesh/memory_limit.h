#pragma once
// What this machine can hold, for refusing work whose estimated size is past it before the
// work starts (a tiny --size, a refinement level, a cell count): the user gets one line that
// names the estimate instead of a swap storm or an out-of-memory kill minutes later.
#include <cstdint>
#include <string>

namespace incise {

// Memory the kernel reports as available (MemAvailable in /proc/meminfo), else the physical
// memory; 0 when neither can be read (then nothing is refused for memory).
std::uint64_t available_memory_bytes();

// What a TetMesh holds per tet, its vertices included (docs/architecture.md#memory).
constexpr double kTetMeshBytesPerTet = 160;

// "1.3 GB", "512 MB": for messages.
std::string format_bytes(double bytes);
// "123456", or "1.5e+12" past a trillion: a count for messages, whatever its size.
std::string format_count(double n);

// Throws InvalidArgument("WHAT would need about B (ESTIMATE), more than the A this machine has
// available; HINT") when `bytes` exceeds the available memory.
void refuse_past_memory(const std::string& what, double bytes, const std::string& estimate, const std::string& hint);

}  // namespace incise
