#pragma once
// What the PETSc backend's two halves share: the process state (whether this is a distributed
// run and which rank), the commands rank 0 sends serving ranks, and error checking. Only
// sim/petsc/*.cpp include it (it pulls in petscksp.h).
#include <string>

#include <petscksp.h>

namespace incise::petsc_detail {

enum Command : int { kFinish = 0, kCreate = 1, kAssemble = 2, kSolve = 3, kDestroy = 4, kMemory = 5, kSaddle = 6 };

struct State {
  bool distributed = false;  // started by petsc_start_distributed() with more than one rank
  bool shared = false;       // started by petsc_start_shared() with more than one rank
  int rank = 0, size = 1;
  int next_id = 1;           // rank 0: the id of the next solver
};
State& state();

// PETSc (and MPI, a singleton without a launcher) started if it is not yet; PETSc's own error
// printing and signal handlers off, so failures come out as one line.
void ensure_initialized();
// A failed PETSc call: an Error with PETSc's message, or in a distributed run (where another
// rank may wait in a collective call) the message on stderr and MPI_Abort.
void check(PetscErrorCode e, const char* what);
[[noreturn]] void abort_all(const std::string& message);

// Rank 0 (distributed runs): the command every serving rank receives next.
void broadcast_command(Command c, int id);
// A serving rank: carries out one command of rank 0's.
void serve_command(Command c, int id);
// A serving rank's share of a saddle-point solve (kSaddle, sim/petsc/petsc_saddle.cpp).
void serve_saddle(MPI_Comm comm);

}  // namespace incise::petsc_detail

#define INCISE_PETSC(expr) ::incise::petsc_detail::check((expr), #expr)
