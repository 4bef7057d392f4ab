// The process side of the PETSc backend: starting PETSc (one process or a distributed run),
// the serving ranks' loop, errors that must not leave a rank waiting.
#include "sim/petsc/petsc_session.h"

#include <sys/resource.h>

#include <cstdlib>
#include <iostream>
#include <new>

#include "mesh/errors.h"
#include "sim/petsc/petsc_internal.h"
#include "sim/petsc/petsc_solver.h"

namespace incise {

namespace petsc_detail {

State& state() {
  static State s;
  return s;
}

namespace {
void finalize_at_exit() {
  PetscBool fin = PETSC_FALSE;
  PetscFinalized(&fin);
  if (!fin) PetscFinalize();
}
}  // namespace

void ensure_initialized() {
  PetscBool up = PETSC_FALSE;
  PetscInitialized(&up);
  if (up) return;
  // Before PetscInitialize: the caller's SIGINT handling stays (the CLI stops between frames),
  // and a crash is not turned into PETSc's multi-line report.
  PetscOptionsSetValue(nullptr, "-no_signal_handler", nullptr);
  if (PetscInitializeNoArguments() != 0) throw Error("petsc: PetscInitialize failed (is MPI usable here?)");
  PetscPushErrorHandler(PetscReturnErrorHandler, nullptr);
  MPI_Comm_rank(PETSC_COMM_WORLD, &state().rank);
  MPI_Comm_size(PETSC_COMM_WORLD, &state().size);
  std::atexit(finalize_at_exit);
}

[[noreturn]] void abort_all(const std::string& message) {
  std::cerr << "incise: error: " << message << "\n" << std::flush;
  MPI_Abort(PETSC_COMM_WORLD, 1);
  std::_Exit(1);
}

void check(PetscErrorCode e, const char* what) {
  if (e == 0) return;
  const char* text = nullptr;
  char* specific = nullptr;
  PetscErrorMessage(e, &text, &specific);
  std::string msg = "petsc: ";
  msg += specific && *specific ? specific : (text ? text : "error");
  msg += std::string(" (") + what + ")";
  for (char& ch : msg)
    if (ch == '\n') ch = ' ';
  if (state().distributed && state().size > 1) abort_all(msg);
  throw Error(msg);
}

double peak_memory_mb() {
  rusage ru{};
  getrusage(RUSAGE_SELF, &ru);
  return double(ru.ru_maxrss) / 1024.0;  // KB on Linux
}

void gather_peak_memory(double* all) {
  double mine = peak_memory_mb();
  MPI_Gather(&mine, 1, MPI_DOUBLE, all, 1, MPI_DOUBLE, 0, PETSC_COMM_WORLD);
}

void broadcast_command(Command c, int id) {
  int msg[2] = {int(c), id};
  MPI_Bcast(msg, 2, MPI_INT, 0, PETSC_COMM_WORLD);
}

}  // namespace petsc_detail

using namespace petsc_detail;

int petsc_start_distributed() {
  if (launched_ranks() <= 1) return 0;
  ensure_initialized();
  state().distributed = state().size > 1;
  return state().rank;
}

bool petsc_distributed() { return state().distributed && state().rank == 0; }

int petsc_serve() {
  int status = 1;
  try {
    for (;;) {
      int msg[2] = {0, 0};
      MPI_Bcast(msg, 2, MPI_INT, 0, PETSC_COMM_WORLD);
      if (msg[0] == kFinish) {
        status = msg[1];
        break;
      }
      if (msg[0] == kMemory) gather_peak_memory(nullptr);
      else serve_command(Command(msg[0]), msg[1]);
    }
  } catch (const std::bad_alloc&) {
    abort_all("petsc: rank " + std::to_string(state().rank) + ": out of memory");
  } catch (const std::exception& e) {
    abort_all("petsc: rank " + std::to_string(state().rank) + ": " + e.what());
  }
  serve_command(kFinish, 0);  // drops this rank's solvers before PETSc goes
  PetscFinalize();
  return status;
}

std::vector<double> rank_peak_memory_mb() {
  if (!petsc_distributed()) return {peak_memory_mb()};
  std::vector<double> all(static_cast<std::size_t>(state().size));
  broadcast_command(kMemory, 0);
  gather_peak_memory(all.data());
  return all;
}

int petsc_start_shared() {
  if (launched_ranks() <= 1) return 0;
  ensure_initialized();
  state().shared = state().size > 1;
  return state().rank;
}

int petsc_ranks() { return state().distributed || state().shared ? state().size : 1; }

std::vector<std::string> petsc_gather(const std::string& mine) {
  if (!state().shared) return {mine};
  const int size = state().size, rank = state().rank;
  long long n = (long long)mine.size();
  std::vector<long long> sizes(static_cast<std::size_t>(size));
  MPI_Gather(&n, 1, MPI_LONG_LONG, sizes.data(), 1, MPI_LONG_LONG, 0, PETSC_COMM_WORLD);
  std::vector<int> counts(static_cast<std::size_t>(size)), displs(static_cast<std::size_t>(size));
  long long total = 0;
  for (int r = 0; r < size; ++r) {
    counts[std::size_t(r)] = int(sizes[std::size_t(r)]);
    displs[std::size_t(r)] = int(total);
    total += sizes[std::size_t(r)];
  }
  std::string all(rank == 0 ? std::size_t(total) : 0, '\0');
  MPI_Gatherv(mine.data(), int(n), MPI_CHAR, all.data(), counts.data(), displs.data(), MPI_CHAR, 0, PETSC_COMM_WORLD);
  std::vector<std::string> out;
  if (rank == 0)
    for (int r = 0; r < size; ++r) out.push_back(all.substr(std::size_t(displs[std::size_t(r)]), std::size_t(counts[std::size_t(r)])));
  return out;
}

bool petsc_all_ok(bool ok) {
  if (!state().shared) return ok;
  int v = ok ? 1 : 0;
  MPI_Allreduce(MPI_IN_PLACE, &v, 1, MPI_INT, MPI_MIN, PETSC_COMM_WORLD);
  return v == 1;
}

void petsc_end_shared() {
  if (!state().shared) return;
  state().shared = false;
  PetscFinalize();
}

[[noreturn]] void petsc_abort(const std::string& message) { abort_all(message); }

void petsc_finish(int status) {
  if (!state().distributed || state().rank != 0) return;
  broadcast_command(kFinish, status);
  state().distributed = false;
  PetscFinalize();
}

}  // namespace incise
