#pragma once
// One BLAS thread for CHOLMOD's factorizations and solves (the asynchronous Cholesky factor,
// the multigrid's coarse level): see the .cpp for why. Idempotent, thread-safe.
namespace incise {

void single_threaded_blas();

}  // namespace incise
