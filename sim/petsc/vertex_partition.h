#pragma once
// Which rank owns which vertex in a distributed PETSc solve (sim/petsc/petsc_solver.h): the
// vertex graph of the model's tets cut into one part per rank by PETSc's MatPartitioning, on
// rank 0. PT-Scotch by default (Debian's PETSc is built with PT-Scotch, not ParMETIS);
// `-mat_partitioning_type current` in the solver's options keeps the slots' own order.
#include <cstddef>
#include <vector>

#include <petscsys.h>

namespace incise {

struct FemElements;

// perm[v]: the new index of vertex slot v; each part's slots are contiguous in the new order
// (in slot order inside a part), part r holding [starts[r], starts[r + 1]). `options`: the
// database MatPartitioningSetFromOptions reads. O(mesh) plus the partitioner's time.
void partition_vertices(const FemElements& e, std::size_t slots, int parts, PetscOptions options,
                        std::vector<PetscInt>& perm, std::vector<PetscInt>& starts);

}  // namespace incise
