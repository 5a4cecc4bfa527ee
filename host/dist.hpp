// The processes of one job: MPI's world when the tool was built with MPI (STYLERF_HAVE_MPI) and started by
// mpirun or srun, else this process alone (rank 0 of 1, every call a no-op or a copy). Nothing here knows
// what the processes compute: callers split their work by rank() and size() and meet in the calls below.
// Every rank must make the same calls in the same order (MPI's collectives).
//
// A rank that hangs (stopped, deadlocked, stuck in a driver) would leave the others waiting in a collective
// forever: every collective here first meets the others with a time limit, and its data moves by nonblocking
// calls waited for under the same limit. The ranks send each other a small
// sign of life (alive(), and every meeting); when one has not been heard from for STYLERF_RANK_TIMEOUT_S seconds (300) while
// the others wait, the job ends with an error naming it. A rank that dies is ended by the launcher itself.
#pragma once
#include <string>
#include <vector>

namespace stylerf::host {

class Dist {
 public:
  // The job's process group, MPI initialised on first use when launched under MPI.
  static Dist& world();
  // Whether this build can run as several ranks (built with MPI).
  static bool built_with_mpi();

  int rank() const { return rank_; }
  int size() const { return size_; }
  int local_rank() const { return local_rank_; }  // among the ranks on this machine
  int local_size() const { return local_size_; }
  bool root() const { return rank_ == 0; }

  // Every rank's bytes at `root`, in rank order; the other ranks get an empty list.
  std::vector<std::string> gather(const std::string& bytes, int root = 0);
  // Element-wise sums over the ranks, in place (the same length on every rank).
  void allreduce_sum(std::vector<double>& values);
  // `root`'s values on every rank, in place (the same length on every rank).
  void broadcast(std::vector<double>& values, int root = 0);
  double broadcast(double value, int root = 0);
  // A sign of life between collectives, for work that is long between them (a rank's share of frames): call it
  // after each unit of work. Cheap: at most one message a second.
  void alive();
  // Ends the whole job at once (a rank that failed must not leave the others waiting in a collective).
  [[noreturn]] void abort(int code);
  // MPI_Finalize when it was initialised; called once at exit.
  void finalize();

 private:
  Dist();
  // Every rank reaches this point before a collective starts, or the job ends naming the silent rank.
  void meet(const char* collective);
  // Polls an MPI request (an MPI_Request*) to completion under the same time limit: the collective's data
  // moves with nonblocking calls too, so a rank stopped between the meeting and the data (or during it) is
  // named as well, not waited for forever.
  void wait(void* request, const char* collective);
  void send_signs_of_life(bool now);
  void read_signs_of_life();
  int rank_ = 0, size_ = 1, local_rank_ = 0, local_size_ = 1;
  bool mpi_ = false;
  double timeout_s_ = 300;       // STYLERF_RANK_TIMEOUT_S
  long meetings_ = 0;             // collectives started by this rank
  std::vector<double> heard_at_;  // when each rank was last heard from (rank 0: all; others: rank 0)
  double sent_at_ = -1e300;
};

}  // namespace stylerf::host
