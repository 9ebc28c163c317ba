// The --threads default of the commands that run work in parallel (identify, sweep, coupling).
#pragma once

namespace millkit::cli {

// The cores this process may run on (its CPU affinity mask), shared evenly among the MPI ranks
// the launcher started on this node (OMPI_COMM_WORLD_LOCAL_SIZE of Open MPI, MPI_LOCALNRANKS of
// MPICH), at least 1 and at most 256. Every command's result is the same for any thread count, so
// the default only decides how fast it comes.
int DefaultThreads();

}  // namespace millkit::cli
