#pragma once
// Wall-clock milliseconds for frame budgets and timing reports, from the steady clock (it never
// jumps, so differences are elapsed time even when the system clock is set). One place for the
// solver, the cutter, scenes and the viewer.
#include <chrono>

namespace incise {

// Milliseconds since the clock's fixed origin: only differences of two calls mean anything.
inline double now_ms() {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// Milliseconds elapsed since t0.
inline double ms_since(std::chrono::steady_clock::time_point t0) {
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0).count();
}

// Seconds elapsed since t0 (long runs: trade's reference and grid).
inline double seconds_since(std::chrono::steady_clock::time_point t0) { return ms_since(t0) / 1000; }

}  // namespace incise
