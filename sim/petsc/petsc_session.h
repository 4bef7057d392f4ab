#pragma once
// A distributed run: `mpirun -np N incise simulate SCENE -o DIR`. Rank 0 runs the scene as one
// process does (mesh, cuts, probes, output files); the other ranks serve its PetscSolvers (each
// compute() and solve() is collective, sim/petsc/petsc_solver.h) until rank 0 finishes.
//
//   const int rank = petsc_start_distributed();   // 0 without mpirun
//   if (rank != 0) return petsc_serve();          // the exit status rank 0 sent
//   ... rank 0's work ...; petsc_finish(status);   // also on failure: every rank exits with it
//
// A failure on rank 0 outside a solve reaches the others as a status (rank 0 prints its one
// line, every rank exits 1); a failure inside a collective step aborts the communicator with the
// message (MPI_Abort), so no rank hangs.
#include <string>
#include <vector>

namespace incise {

// The number of processes the launcher started, read from its environment before MPI starts
// (OMPI_COMM_WORLD_SIZE, PMI_SIZE); 1 without one.
int launched_ranks();
// Starts MPI and PETSc for a distributed run when launched_ranks() > 1 and returns this rank
// (0 otherwise, nothing started). Throws InvalidArgument when several ranks were launched and
// this build has no PETSc.
int petsc_start_distributed();
// Ranks other than 0: serve rank 0's solvers until it finishes; returns its status, after
// PetscFinalize.
int petsc_serve();
// Rank 0: tells the serving ranks to exit with `status` and finalizes. No-op when not distributed.
// Every PetscSolver of rank 0 must be gone by then (freeing PETSc objects is collective).
void petsc_finish(int status);
// Whether this process is rank 0 of a distributed run with more than one rank.
bool petsc_distributed();
// Shared work (`mpirun -np N incise trade`): every rank plays its share of independent runs and
// rank 0 gathers the results; no rank serves another, so PetscSolvers made meanwhile stay on
// their own process. petsc_start_shared() returns this rank (0 without mpirun, nothing started).
int petsc_start_shared();
int petsc_ranks();  // ranks of the distributed or shared run (1 when none)
// Rank 0 receives every rank's `mine` in rank order, the others an empty vector. Collective.
std::vector<std::string> petsc_gather(const std::string& mine);
// Whether `ok` holds on every rank (collective; `ok` itself without mpirun).
bool petsc_all_ok(bool ok);
// Ends a shared run on this rank (after its last collective call).
void petsc_end_shared();
// A failure of one rank in a shared run: its one line on stderr and every rank stops.
[[noreturn]] void petsc_abort(const std::string& message);

// Peak resident memory of every rank in MB, rank 0 first (getrusage); collective in a
// distributed run (rank 0 asks the others), this process's alone otherwise.
std::vector<double> rank_peak_memory_mb();

}  // namespace incise
