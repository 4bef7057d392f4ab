#pragma once
// A blade path file: the blade's ends at each step, one position per line,
// "AX AY AZ BX BY BZ" (whitespace-separated numbers; blank lines and '#' comments skipped).
// The first position places the blade; each later one is one cut step (Cutter::advance).
// `incise cut --path FILE` and Python's read_blade_path() read it.
#include <string>
#include <vector>

#include "cut/blade.h"

namespace incise {

// At least two positions, every coordinate finite and of magnitude at most 1e15, each blade's
// ends distinct, and the blade moving at least once; else IoError naming the file and line.
std::vector<BladeSegment> read_blade_path(const std::string& path);

}  // namespace incise
