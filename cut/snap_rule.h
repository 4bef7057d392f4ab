#pragma once
// The snap threshold's rule, for every front end (CLI, Python, scenes) and the Cutter itself.
// Header-only: scenes are parsed in sim/, which cut/ links, not the other way round.
#include <string>

#include "mesh/io/input_checks.h"

namespace incise {

// Empty when `snap` is valid, else why not. At 0.5 both ends of an edge could snap onto the
// blade from opposite sides.
inline std::string snap_error(double snap) {
  return snap >= 0 && snap < 0.5 ? "" : number_text(snap) + " is not in [0, 0.5)";
}

}  // namespace incise
