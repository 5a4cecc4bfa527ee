#include "host/dist.hpp"

#include <algorithm>
#include <cstdlib>
#include <iostream>

#include "host/error.hpp"

#ifdef STYLERF_HAVE_MPI
#include <mpi.h>
#endif

namespace stylerf::host {

namespace {

// Launched by a process manager that set up a job of several ranks (Open MPI's mpirun, PMIx, Slurm's srun).
bool launched_under_mpi() {
  for (const char* v : {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_SIZE", "SLURM_STEP_NUM_TASKS"})
    if (const char* s = std::getenv(v)) return *s != '\0';
  return false;
}

}  // namespace

bool Dist::built_with_mpi() {
#ifdef STYLERF_HAVE_MPI
  return true;
#else
  return false;
#endif
}

Dist& Dist::world() {
  static Dist d;
  return d;
}

Dist::Dist() {
#ifdef STYLERF_HAVE_MPI
  if (!launched_under_mpi()) return;
  int provided = 0;
  // Only the thread that calls these functions talks to MPI (the viewer and PoCL have threads of their own).
  MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
  mpi_ = true;
  MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
  MPI_Comm_size(MPI_COMM_WORLD, &size_);
  MPI_Comm local;
  MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, rank_, MPI_INFO_NULL, &local);
  MPI_Comm_rank(local, &local_rank_);
  MPI_Comm_size(local, &local_size_);
  MPI_Comm_free(&local);
#endif
}

std::vector<std::string> Dist::gather(const std::string& bytes, int root) {
  if (!mpi_) return {bytes};
#ifdef STYLERF_HAVE_MPI
  // Sizes first (64-bit: a rank's frames may pass 2 GB), then the bytes in pieces MPI's int counts can hold.
  long long mine = static_cast<long long>(bytes.size());
  std::vector<long long> sizes(size_t(size_), 0);
  MPI_Gather(&mine, 1, MPI_LONG_LONG, sizes.data(), 1, MPI_LONG_LONG, root, MPI_COMM_WORLD);
  std::vector<std::string> out;
  constexpr long long kPiece = 1 << 30;
  if (rank_ == root) {
    out.resize(size_t(size_));
    for (int r = 0; r < size_; ++r) {
      if (r == root) {
        out[size_t(r)] = bytes;
        continue;
      }
      out[size_t(r)].resize(size_t(sizes[size_t(r)]));
      for (long long at = 0; at < sizes[size_t(r)]; at += kPiece)
        MPI_Recv(&out[size_t(r)][size_t(at)], int(std::min(kPiece, sizes[size_t(r)] - at)), MPI_BYTE, r, 7,
                 MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    }
  } else {
    for (long long at = 0; at < mine; at += kPiece)
      MPI_Send(bytes.data() + at, int(std::min(kPiece, mine - at)), MPI_BYTE, root, 7, MPI_COMM_WORLD);
  }
  return out;
#else
  return {bytes};
#endif
}

void Dist::allreduce_sum(std::vector<double>& values) {
#ifdef STYLERF_HAVE_MPI
  if (mpi_ && !values.empty())
    MPI_Allreduce(MPI_IN_PLACE, values.data(), int(values.size()), MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
#endif
}

void Dist::broadcast(std::vector<double>& values, int root) {
#ifdef STYLERF_HAVE_MPI
  if (mpi_ && !values.empty()) MPI_Bcast(values.data(), int(values.size()), MPI_DOUBLE, root, MPI_COMM_WORLD);
#else
  (void)values;
  (void)root;
#endif
}

double Dist::broadcast(double value, int root) {
  std::vector<double> v{value};
  broadcast(v, root);
  return v[0];
}

void Dist::abort(int code) {
#ifdef STYLERF_HAVE_MPI
  if (mpi_) MPI_Abort(MPI_COMM_WORLD, code);
#endif
  std::exit(code);
}

void Dist::finalize() {
#ifdef STYLERF_HAVE_MPI
  if (mpi_) {
    int done = 0;
    MPI_Finalized(&done);
    if (!done) MPI_Finalize();
  }
#endif
}

}  // namespace stylerf::host
