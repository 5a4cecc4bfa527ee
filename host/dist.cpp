#include "host/dist.hpp"

#include <algorithm>
#include <chrono>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <thread>

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

// Message tags: a gather's bytes, "I am still working".
constexpr int kGatherTag = 7, kAliveTag = 12;

[[maybe_unused]] double now_s() {
  return std::chrono::duration<double>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

// STYLERF_RANK_TIMEOUT_S, checked before MPI starts: a bad value ends the job with its reason on every rank.
[[maybe_unused]] double rank_timeout_from_environment() {
  const char* s = std::getenv("STYLERF_RANK_TIMEOUT_S");
  if (!s || !*s) return 300;
  char* end = nullptr;
  const double v = std::strtod(s, &end);
  if (*end != '\0' || !(v > 0) || v > 1e9) {
    std::cerr << "stylerf: STYLERF_RANK_TIMEOUT_S='" << s << "' is not a positive number of seconds\n";
    std::exit(2);
  }
  return v;
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
  timeout_s_ = rank_timeout_from_environment();
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
  heard_at_.assign(size_t(size_), now_s());
#endif
}

void Dist::send_signs_of_life(bool now) {
#ifdef STYLERF_HAVE_MPI
  const double t = now_s();
  if (!now && t - sent_at_ < 1.0) return;
  sent_at_ = t;
  // Empty messages: no buffer must outlive the send, so the requests are released at once.
  auto send = [](int to) {
    MPI_Request q;
    MPI_Isend(nullptr, 0, MPI_BYTE, to, kAliveTag, MPI_COMM_WORLD, &q);
    MPI_Request_free(&q);
  };
  if (root())
    for (int r = 1; r < size_; ++r) send(r);
  else
    send(0);
#else
  (void)now;
#endif
}

void Dist::read_signs_of_life() {
#ifdef STYLERF_HAVE_MPI
  for (;;) {
    int waiting = 0;
    MPI_Status st;
    MPI_Iprobe(MPI_ANY_SOURCE, kAliveTag, MPI_COMM_WORLD, &waiting, &st);
    if (!waiting) break;
    MPI_Recv(nullptr, 0, MPI_BYTE, st.MPI_SOURCE, kAliveTag, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    heard_at_[size_t(st.MPI_SOURCE)] = now_s();
  }
#endif
}

void Dist::alive() {
  if (!mpi_ || size_ == 1) return;
  send_signs_of_life(false);
  read_signs_of_life();
}

void Dist::meet(const char* collective) {
#ifdef STYLERF_HAVE_MPI
  if (!mpi_ || size_ == 1) return;
  ++meetings_;
  send_signs_of_life(true);  // this rank has reached the collective
  MPI_Request all_here;
  MPI_Ibarrier(MPI_COMM_WORLD, &all_here);
  wait(&all_here, collective);
#else
  (void)collective;
#endif
}

void Dist::wait(void* request, const char* collective) {
#ifdef STYLERF_HAVE_MPI
  MPI_Request* q = static_cast<MPI_Request*>(request);
  const double start = now_s();
  for (long polls = 0;; ++polls) {
    int done = 0;
    MPI_Test(q, &done, MPI_STATUS_IGNORE);
    if (done) return;
    read_signs_of_life();
    send_signs_of_life(false);  // the waiting ranks hear from each other, so only the silent one is named
    // Rank 0 watches every rank (one that has arrived still answers while it waits: its part of the meeting
    // needs it to run); the others watch rank 0, which watches the rest.
    const double t = now_s();
    for (int r = root() ? 1 : 0; r < (root() ? size_ : 1); ++r) {
      const double silent = t - std::max(heard_at_[size_t(r)], start);
      if (silent < timeout_s_) continue;
      std::ostringstream m;
      m << "rank " << r << " of " << size_ << " has not been heard from for " << int(silent)
        << " s while rank " << rank_ << " waits for it (" << collective << ", collective " << meetings_
        << "): it hung or was stopped, so the job ends (STYLERF_RANK_TIMEOUT_S sets the limit, now "
        << timeout_s_ << " s; checkpoints written so far are kept)";
      throw Error(m.str());
    }
    // Waiting may last as long as another rank's step: spin briefly, then leave the core to the others.
    if (polls > 2000) std::this_thread::sleep_for(std::chrono::microseconds(200));
  }
#else
  (void)request;
  (void)collective;
#endif
}

std::vector<std::string> Dist::gather(const std::string& bytes, int root) {
  if (!mpi_) return {bytes};
#ifdef STYLERF_HAVE_MPI
  // Sizes first (64-bit: a rank's frames may pass 2 GB), then the bytes in pieces MPI's int counts can hold.
  meet("gather");
  long long mine = static_cast<long long>(bytes.size());
  std::vector<long long> sizes(size_t(size_), 0);
  MPI_Request q;
  MPI_Igather(&mine, 1, MPI_LONG_LONG, sizes.data(), 1, MPI_LONG_LONG, root, MPI_COMM_WORLD, &q);
  wait(&q, "gather");
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
      for (long long at = 0; at < sizes[size_t(r)]; at += kPiece) {
        MPI_Irecv(&out[size_t(r)][size_t(at)], int(std::min(kPiece, sizes[size_t(r)] - at)), MPI_BYTE, r,
                  kGatherTag, MPI_COMM_WORLD, &q);
        wait(&q, "gather");
      }
    }
  } else {
    for (long long at = 0; at < mine; at += kPiece) {
      MPI_Isend(bytes.data() + at, int(std::min(kPiece, mine - at)), MPI_BYTE, root, kGatherTag, MPI_COMM_WORLD, &q);
      wait(&q, "gather");
    }
  }
  return out;
#else
  return {bytes};
#endif
}

void Dist::allreduce_sum(std::vector<double>& values) {
#ifdef STYLERF_HAVE_MPI
  if (mpi_ && !values.empty()) {
    meet("allreduce");
    MPI_Request q;
    MPI_Iallreduce(MPI_IN_PLACE, values.data(), int(values.size()), MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD, &q);
    wait(&q, "allreduce");
  }
#endif
}

void Dist::broadcast(std::vector<double>& values, int root) {
#ifdef STYLERF_HAVE_MPI
  if (mpi_ && !values.empty()) {
    meet("broadcast");
    MPI_Request q;
    MPI_Ibcast(values.data(), int(values.size()), MPI_DOUBLE, root, MPI_COMM_WORLD, &q);
    wait(&q, "broadcast");
  }
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
