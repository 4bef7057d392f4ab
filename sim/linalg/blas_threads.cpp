#include "sim/linalg/blas_threads.h"

#include <mutex>

#include <dlfcn.h>

namespace incise {

// CHOLMOD runs on whatever libblas.so.3 Debian's alternatives select. The optimized one
// (OpenBLAS, libopenblas0-pthread, installed by scripts/install-deps.sh) starts a thread per
// core for every factorization and triangular solve by default; beside the frame's own
// threads (TBB) and the background factorization that made a cut organ's frame ten times
// longer (docs/solver.md, "BLAS under the Cholesky factor"). One BLAS thread, set once through
// the symbol when that library is the one loaded (the reference BLAS has none).
void single_threaded_blas() {
  static std::once_flag once;
  std::call_once(once, [] {
    using SetThreads = void (*)(int);
    if (void* f = dlsym(RTLD_DEFAULT, "openblas_set_num_threads")) reinterpret_cast<SetThreads>(f)(1);
  });
}

}  // namespace incise
