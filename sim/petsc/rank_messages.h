#pragma once
// What rank 0 sends the ranks that serve its PETSc solves (sim/petsc/petsc_solver.h): per
// assembly a header and each rank's part (the tets touching its vertices, its rows' data, its
// share of B), per solve the rows of the right-hand side and the guess, and back the solution.
#include <cstdint>
#include <string>
#include <vector>

#include <petscsys.h>

namespace incise::petsc_detail {

constexpr int kTetData = 21;  // per tet: shape matrix (9), rotation (9), volume, mu, lambda

// What one rank receives to assemble its rows (row blocks in the solve's numbering).
struct Part {
  std::vector<std::uint32_t> tet_verts;  // #T by 4: the tets touching the rank's vertices
  std::vector<double> tet_data;          // #T by kTetData
  std::vector<std::uint8_t> free;        // per owned unknown
  std::vector<double> mass, coords;      // per owned unknown: lumped mass, rest position
  std::vector<PetscInt> b_ptr, b_col;    // B's rows of this rank's share (CSR, global columns)
  std::vector<double> b_val;
};

// One rank's rows of a mixed formulation's saddle-point system (sim/petsc/petsc_saddle.h), in
// the system's own numbering (displacements first): CSR with global columns, and the pressure
// diagonal of its pressure rows.
struct SaddleRows {
  std::vector<PetscInt> ptr, col;
  std::vector<double> val;
  std::vector<double> p_diagonal;
};

struct Header {
  long long vertices = 0, b_rows = 0;
  double a = 0, c = 1;
};

// Contiguous ranges: rank r owns [n r / size, n (r + 1) / size).
std::vector<PetscInt> split(long long n, int size);

void send_part(const Part& p, int dest, MPI_Comm comm);
void receive_part(Part& p, MPI_Comm comm);  // from rank 0
void send_saddle_rows(const SaddleRows& r, int dest, MPI_Comm comm);
void receive_saddle_rows(SaddleRows& r, MPI_Comm comm);  // from rank 0
void broadcast_string(std::string& s, MPI_Comm comm);  // from rank 0

// Rank 0's vector of `block` values per row block to the ranks (each gets the rows of its
// blocks [starts[r], starts[r + 1])), and back. `all` is read or written on rank 0 only.
void scatter_rows(const std::vector<PetscInt>& starts, const double* all, std::vector<double>& mine, MPI_Comm comm,
                  int block = 3);
void gather_rows(const std::vector<PetscInt>& starts, const std::vector<double>& mine, double* all, MPI_Comm comm,
                 int block = 3);

}  // namespace incise::petsc_detail
