// launched_ranks(): built with or without PETSc (the CLI asks before anything starts).
#include <cstdlib>
#include <string>

#include "sim/petsc/petsc_session.h"

namespace incise {

int launched_ranks() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_SIZE"})
    if (const char* s = std::getenv(name)) {
      const int n = std::atoi(s);
      if (n > 0) return n;
    }
  return 1;
}

}  // namespace incise
