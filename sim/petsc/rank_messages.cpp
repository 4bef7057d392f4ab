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

// Each vector in turn (fold expressions over a message's fields).
template <class... V>
void send_vectors(int dest, MPI_Comm comm, const V&... v) {
  (send_vector(v, dest, comm), ...);
}
template <class... V>
void receive_vectors(MPI_Comm comm, V&... v) {
  (receive_vector(v, comm), ...);
}

}  // namespace

// Contiguous ranges: rank r owns [n r / size, n (r + 1) / size).
std::vector<PetscInt> split(long long n, int size) {
  std::vector<PetscInt> s(static_cast<std::size_t>(size) + 1);
  for (int r = 0; r <= size; ++r) s[std::size_t(r)] = PetscInt(n * r / size);
  return s;
}

void send_part(const Part& p, int dest, MPI_Comm comm) {
  send_vectors(dest, comm, p.tet_verts, p.tet_data, p.free, p.mass, p.coords, p.b_ptr, p.b_col, p.b_val);
}

void receive_part(Part& p, MPI_Comm comm) {
  receive_vectors(comm, p.tet_verts, p.tet_data, p.free, p.mass, p.coords, p.b_ptr, p.b_col, p.b_val);
}

void send_saddle_rows(const SaddleRows& r, int dest, MPI_Comm comm) {
  send_vectors(dest, comm, r.ptr, r.col, r.val, r.p_diagonal);
}

void receive_saddle_rows(SaddleRows& r, MPI_Comm comm) {
  receive_vectors(comm, r.ptr, r.col, r.val, r.p_diagonal);
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
