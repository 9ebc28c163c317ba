// Sweeps across machines with MPI (issue 5): `mpirun -np N millkit sweep …` splits the cases over
// the ranks and gathers the results on rank 0, which alone writes the outputs. Case i runs on
// rank i mod N (cyclic: neighbouring cases, often alike in cost, spread over the ranks), each
// rank on its own thread pool; the results travel as raw bytes, so the rows are bitwise those of
// a serial run.
//
// MPI is built in when CMake finds it (option MILLKIT_WITH_MPI: AUTO by default, ON, OFF; OpenMPI
// from Debian). Campaigns (`identify --campaign`) share their fits out the same way through
// GatherBytes. MPI is initialised only when the program was started by mpirun (OMPI_COMM_WORLD_SIZE
// or PMI_SIZE in the environment); otherwise everything runs in this process. A program built
// without MPI but started by mpirun with more than one rank refuses to run (InputError), rather
// than have every rank run every case.
//
// No hang on failure: after the local run every rank reports success or failure in a collective
// before any data moves; if any rank failed, every rank throws.
#pragma once

#include <exception>
#include <string>
#include <vector>

#include "millkit/sweep/sweep_runner.h"

namespace millkit::sweep {

class MpiSession {
 public:
  // Initialises MPI when built with it and started by mpirun; else a single-process session.
  MpiSession();
  // MPI_Finalize when this session initialised MPI; when left by an exception, at exit instead
  // (after the program has printed the error: every rank says why it stops).
  ~MpiSession();
  MpiSession(const MpiSession&) = delete;
  MpiSession& operator=(const MpiSession&) = delete;

  int rank() const { return rank_; }
  int size() const { return size_; }
  bool root() const { return rank_ == 0; }
  static bool BuiltWithMpi();

 private:
  int rank_ = 0;
  int size_ = 1;
  bool initialised_ = false;
};

// Collective (every rank calls it): every rank learns whether any rank failed (`error` is this
// rank's failure, null for none). The failing rank rethrows its own error, the others throw
// std::runtime_error naming `activity`; so a rank whose inputs fail (a file its node does not see)
// does not leave the others waiting in a later collective. A single-process session rethrows
// `error` if any.
void ThrowIfAnyRankFailed(const MpiSession& session, const std::exception_ptr& error,
                          const std::string& activity);

// Collective (every rank calls it): one byte string per rank gathered on rank 0, indexed by rank;
// other ranks get an empty vector. `error` is this rank's failure before the call (null: none):
// every rank first learns whether any rank failed, then the failing rank rethrows its own error
// and the others throw std::runtime_error naming `activity`, so no rank waits for data that never
// comes. A single-process session returns {bytes} (or rethrows `error`).
std::vector<std::string> GatherBytes(const MpiSession& session, const std::string& bytes,
                                     std::exception_ptr error, const std::string& activity);

// RunCases over all ranks. On rank 0: every case's result in case order, and `summary` for the
// whole run (cases, failures, this rank's threads, wall time to the gathered result). On other
// ranks: an empty vector. A single-process session is RunCases itself.
std::vector<CaseResult> RunCasesDistributed(const MpiSession& session, const CaseFunction& evaluate,
                                            const CaseList& cases, const RunnerOptions& options,
                                            RunnerSummary* summary = nullptr);

}  // namespace millkit::sweep
