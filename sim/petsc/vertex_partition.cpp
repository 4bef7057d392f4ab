// partition_vertices (sim/petsc/vertex_partition.h).
#include "sim/petsc/vertex_partition.h"

#include <algorithm>
#include <utility>

#include <petscmat.h>

#include "sim/fem/fem_model.h"
#include "sim/petsc/petsc_internal.h"

namespace incise {

void partition_vertices(const FemElements& e, std::size_t slots, int parts, PetscOptions options,
                        std::vector<PetscInt>& perm, std::vector<PetscInt>& starts) {
  // The vertex graph: two slots adjacent when they share a tet.
  std::vector<std::pair<PetscInt, PetscInt>> pairs;
  pairs.reserve(12 * e.alive.size());
  for (std::size_t t = 0; t < e.alive.size(); ++t) {
    if (!e.alive[t]) continue;
    for (int i = 0; i < 4; ++i)
      for (int j = 0; j < 4; ++j)
        if (i != j) pairs.emplace_back(PetscInt(e.verts[t][std::size_t(i)]), PetscInt(e.verts[t][std::size_t(j)]));
  }
  std::sort(pairs.begin(), pairs.end());
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  const PetscInt n = PetscInt(slots);
  PetscInt *ia = nullptr, *ja = nullptr;  // MatCreateMPIAdj takes them over
  INCISE_PETSC(PetscMalloc1(std::size_t(n) + 1, &ia));
  INCISE_PETSC(PetscMalloc1(std::max<std::size_t>(pairs.size(), 1), &ja));
  std::fill(ia, ia + n + 1, PetscInt(0));
  for (const auto& [a, b] : pairs) ia[a + 1]++;
  for (PetscInt i = 0; i < n; ++i) ia[i + 1] += ia[i];
  for (std::size_t k = 0; k < pairs.size(); ++k) ja[k] = pairs[k].second;
  pairs = {};
  Mat adj = nullptr;
  INCISE_PETSC(MatCreateMPIAdj(PETSC_COMM_SELF, n, n, ia, ja, nullptr, &adj));
  MatPartitioning part = nullptr;
  IS is = nullptr;
  INCISE_PETSC(PetscOptionsPush(options));
  INCISE_PETSC(MatPartitioningCreate(PETSC_COMM_SELF, &part));
  INCISE_PETSC(MatPartitioningSetAdjacency(part, adj));
  INCISE_PETSC(MatPartitioningSetNParts(part, parts));
  INCISE_PETSC(MatPartitioningSetType(part, MATPARTITIONINGPTSCOTCH));
  INCISE_PETSC(MatPartitioningSetFromOptions(part));
  INCISE_PETSC(MatPartitioningApply(part, &is));
  PetscOptionsPop();
  const PetscInt* owner = nullptr;
  INCISE_PETSC(ISGetIndices(is, &owner));
  starts.assign(std::size_t(parts) + 1, 0);
  for (PetscInt v = 0; v < n; ++v) starts[std::size_t(owner[v]) + 1]++;
  for (int r = 0; r < parts; ++r) starts[std::size_t(r) + 1] += starts[std::size_t(r)];
  std::vector<PetscInt> next(starts.begin(), starts.end() - 1);
  perm.resize(slots);
  for (PetscInt v = 0; v < n; ++v) perm[std::size_t(v)] = next[std::size_t(owner[v])]++;
  INCISE_PETSC(ISRestoreIndices(is, &owner));
  INCISE_PETSC(ISDestroy(&is));
  INCISE_PETSC(MatPartitioningDestroy(&part));
  INCISE_PETSC(MatDestroy(&adj));
}

}  // namespace incise
