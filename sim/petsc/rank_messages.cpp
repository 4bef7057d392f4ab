// The messages between rank 0 and the serving ranks (sim/petsc/rank_messages.h).
#include "sim/petsc/rank_messages.h"

#include <algorithm>
#include <climits>

namespace incise::petsc_detail {

namespace {

constexpr int kTag = 4711;

template <class T>
void send_vector(const std::vector<T>& v, int dest, MPI_Comm comm) {
  long long n = (long long)v.size();
  MPI_Send(&n, 1, MPI_LONG_LONG, dest, kTag, comm);
  const char* p = reinterpret_cast<const char*>(v.data());
  for (long long left = n * (long long)sizeof(T); left > 0;) {
    const int chunk = int(std::min<long long>(left, INT_MAX / 2));
    MPI_Send(p, chunk, MPI_BYTE, dest, kTag, comm);
    p += chunk;
    left -= chunk;
  }
}

template <class T>
void receive_vector(std::vector<T>& v, MPI_Comm comm) {
  long long n = 0;
  MPI_Recv(&n, 1, MPI_LONG_LONG, 0, kTag, comm, MPI_STATUS_IGNORE);
  v.resize(std::size_t(n));
  char* p = reinterpret_cast<char*>(v.data());
  for (long long left = n * (long long)sizeof(T); left > 0;) {
    const int chunk = int(std::min<long long>(left, INT_MAX / 2));
    MPI_Recv(p, chunk, MPI_BYTE, 0, kTag, comm, MPI_STATUS_IGNORE);
    p += chunk;
    left -= chunk;
  }
}

}  // namespace

// Contiguous ranges: rank r owns [n r / size, n (r + 1) / size).
std::vector<PetscInt> split(long long n, int size) {
  std::vector<PetscInt> s(static_cast<std::size_t>(size) + 1);
  for (int r = 0; r <= size; ++r) s[std::size_t(r)] = PetscInt(n * r / size);
  return s;
}

void send_part(const Part& p, int dest, MPI_Comm comm) {
  send_vector(p.tet_verts, dest, comm);
  send_vector(p.tet_data, dest, comm);
  send_vector(p.free, dest, comm);
  send_vector(p.mass, dest, comm);
  send_vector(p.coords, dest, comm);
  send_vector(p.b_ptr, dest, comm);
  send_vector(p.b_col, dest, comm);
  send_vector(p.b_val, dest, comm);
}

void receive_part(Part& p, MPI_Comm comm) {
  receive_vector(p.tet_verts, comm);
  receive_vector(p.tet_data, comm);
  receive_vector(p.free, comm);
  receive_vector(p.mass, comm);
  receive_vector(p.coords, comm);
  receive_vector(p.b_ptr, comm);
  receive_vector(p.b_col, comm);
  receive_vector(p.b_val, comm);
}

void send_saddle_rows(const SaddleRows& r, int dest, MPI_Comm comm) {
  send_vector(r.ptr, dest, comm);
  send_vector(r.col, dest, comm);
  send_vector(r.val, dest, comm);
  send_vector(r.p_diagonal, dest, comm);
}

void receive_saddle_rows(SaddleRows& r, MPI_Comm comm) {
  receive_vector(r.ptr, comm);
  receive_vector(r.col, comm);
  receive_vector(r.val, comm);
  receive_vector(r.p_diagonal, comm);
}

namespace {

// Counts and offsets (in doubles) of each rank's rows.
void layout(const std::vector<PetscInt>& vs, int block, std::vector<int>& counts, std::vector<int>& displs) {
  const std::size_t size = vs.size() - 1;
  counts.resize(size);
  displs.resize(size);
  for (std::size_t r = 0; r < size; ++r) {
    counts[r] = int(block * (vs[r + 1] - vs[r]));
    displs[r] = int(block * vs[r]);
  }
}

}  // namespace

void scatter_rows(const std::vector<PetscInt>& vs, const double* all, std::vector<double>& mine, MPI_Comm comm,
                  int block) {
  std::vector<int> counts, displs;
  layout(vs, block, counts, displs);
  int rank = 0;
  MPI_Comm_rank(comm, &rank);
  mine.resize(std::size_t(counts[std::size_t(rank)]));
  MPI_Scatterv(all, counts.data(), displs.data(), MPI_DOUBLE, mine.data(), counts[std::size_t(rank)], MPI_DOUBLE, 0, comm);
}
void gather_rows(const std::vector<PetscInt>& vs, const std::vector<double>& mine, double* all, MPI_Comm comm,
                 int block) {
  std::vector<int> counts, displs;
  layout(vs, block, counts, displs);
  MPI_Gatherv(mine.data(), int(mine.size()), MPI_DOUBLE, all, counts.data(), displs.data(), MPI_DOUBLE, 0, comm);
}

void broadcast_string(std::string& s, MPI_Comm comm) {
  long long n = (long long)s.size();
  MPI_Bcast(&n, 1, MPI_LONG_LONG, 0, comm);
  s.resize(std::size_t(n));
  if (n) MPI_Bcast(s.data(), int(n), MPI_CHAR, 0, comm);
}

}  // namespace incise::petsc_detail
