#include "millkit/sweep/mpi_runner.h"

#include <algorithm>
#include <chrono>
#include <climits>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <string>

#include "millkit/io/input_error.h"

#if MILLKIT_WITH_MPI
#include <mpi.h>
#endif

namespace millkit::sweep {
namespace {

// Ranks in the job as the launcher tells it; 0 when not started by an MPI launcher.
int LaunchedRanks() {
  for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE"}) {
    if (const char* value = std::getenv(name)) return std::max(1, std::atoi(value));
  }
  return 0;
}

#if MILLKIT_WITH_MPI
void Append(std::string* buffer, const void* data, size_t bytes) {
  buffer->append(static_cast<const char*>(data), bytes);
}

template <class T>
void AppendValue(std::string* buffer, T value) {
  Append(buffer, &value, sizeof(T));
}

void AppendDoubles(std::string* buffer, const std::vector<double>& values) {
  AppendValue<std::uint32_t>(buffer, static_cast<std::uint32_t>(values.size()));
  Append(buffer, values.data(), values.size() * sizeof(double));
}

struct Reader {
  const char* at;
  template <class T>
  T Value() {
    T value;
    std::memcpy(&value, at, sizeof(T));
    at += sizeof(T);
    return value;
  }
  std::vector<double> Doubles() {
    std::vector<double> values(Value<std::uint32_t>());
    std::memcpy(values.data(), at, values.size() * sizeof(double));
    at += values.size() * sizeof(double);
    return values;
  }
};

void Pack(const CaseResult& r, std::string* buffer) {
  AppendValue<std::uint8_t>(buffer, r.success ? 1 : 0);
  AppendValue<std::int64_t>(buffer, r.events);
  for (const auto* v : {&r.kd, &r.peak_torque_Nm, &r.peak_time_s, &r.static_torque_Nm}) {
    AppendDoubles(buffer, *v);
  }
  AppendValue<std::uint32_t>(buffer, static_cast<std::uint32_t>(r.message.size()));
  Append(buffer, r.message.data(), r.message.size());
}

CaseResult Unpack(Reader* in) {
  CaseResult r;
  r.success = in->Value<std::uint8_t>() != 0;
  r.events = static_cast<long>(in->Value<std::int64_t>());
  for (auto* v : {&r.kd, &r.peak_torque_Nm, &r.peak_time_s, &r.static_torque_Nm}) {
    *v = in->Doubles();
  }
  const auto length = in->Value<std::uint32_t>();
  r.message.assign(in->at, length);
  in->at += length;
  return r;
}
#endif

}  // namespace

bool MpiSession::BuiltWithMpi() { return MILLKIT_WITH_MPI != 0; }

MpiSession::MpiSession() {
  const int launched = LaunchedRanks();
#if MILLKIT_WITH_MPI
  if (launched > 0) {
    int already = 0;
    MPI_Initialized(&already);
    if (!already) {
      MPI_Init(nullptr, nullptr);
      initialised_ = true;
    }
    MPI_Comm_rank(MPI_COMM_WORLD, &rank_);
    MPI_Comm_size(MPI_COMM_WORLD, &size_);
  }
#else
  if (launched > 1) {
    throw InputError("started by mpirun with " + std::to_string(launched) +
                     " ranks, but this millkit was built without MPI (configure with "
                     "-DMILLKIT_WITH_MPI=ON)");
  }
#endif
}

MpiSession::~MpiSession() {
#if MILLKIT_WITH_MPI
  if (!initialised_) return;
  if (std::uncaught_exceptions() > 0) {
    // Leaving on an error: the program prints it after this. MPI_Finalize waits for every rank,
    // so it runs at exit, after the print; finalized here, a failed rank could exit (and mpirun
    // stop the job) before another rank has printed why it stops too.
    std::atexit([] {
      int finalized = 0;
      MPI_Finalized(&finalized);
      if (!finalized) MPI_Finalize();
    });
    return;
  }
  MPI_Finalize();
#endif
}

void ThrowIfAnyRankFailed(const MpiSession& session, const std::exception_ptr& error,
                          const std::string& activity) {
  if (session.size() > 1) {
#if MILLKIT_WITH_MPI
    int failed_here = error ? 1 : 0, failed_anywhere = 0;
    MPI_Allreduce(&failed_here, &failed_anywhere, 1, MPI_INT, MPI_MAX, MPI_COMM_WORLD);
    if (!error && failed_anywhere) {
      throw std::runtime_error("another MPI rank failed " + activity + " (see its own message)");
    }
#else
    (void)activity;
    throw std::logic_error("ThrowIfAnyRankFailed: a multi-rank session without MPI");
#endif
  }
  if (error) std::rethrow_exception(error);
}

std::vector<std::string> GatherBytes(const MpiSession& session, const std::string& bytes,
                                     std::exception_ptr error, const std::string& activity) {
  if (session.size() == 1) {
    if (error) std::rethrow_exception(error);
    return {bytes};
  }
#if MILLKIT_WITH_MPI
  const int rank = session.rank(), size = session.size();
  if (!error && bytes.size() > static_cast<size_t>(INT_MAX)) {
    error = std::make_exception_ptr(
        std::runtime_error("rank " + std::to_string(rank) + ": results exceed 2 GiB"));
  }
  // Everyone learns whether anyone failed before any data moves.
  ThrowIfAnyRankFailed(session, error, activity);

  const int count = static_cast<int>(bytes.size());
  std::vector<int> counts(session.root() ? size : 0), offsets(counts.size());
  MPI_Gather(&count, 1, MPI_INT, counts.data(), 1, MPI_INT, 0, MPI_COMM_WORLD);
  // The total is checked on rank 0 and its verdict broadcast, so no rank enters the Gatherv alone.
  int too_large = 0;
  std::string all;
  if (session.root()) {
    long total = 0;
    for (int r = 0; r < size; ++r) {
      offsets[r] = static_cast<int>(std::min<long>(total, INT_MAX));
      total += counts[r];
    }
    too_large = total > INT_MAX ? 1 : 0;
    if (!too_large) all.resize(static_cast<size_t>(total));
  }
  MPI_Bcast(&too_large, 1, MPI_INT, 0, MPI_COMM_WORLD);
  if (too_large) throw std::runtime_error("gathered results exceed 2 GiB (" + activity + ")");
  MPI_Gatherv(bytes.data(), count, MPI_BYTE, all.data(), counts.data(), offsets.data(), MPI_BYTE, 0,
              MPI_COMM_WORLD);
  if (!session.root()) return {};
  std::vector<std::string> parts(size);
  for (int r = 0; r < size; ++r) parts[r] = all.substr(offsets[r], counts[r]);
  return parts;
#else
  (void)bytes;
  (void)error;
  (void)activity;
  throw std::logic_error("GatherBytes: a multi-rank session without MPI");
#endif
}

std::vector<CaseResult> RunCasesDistributed(const MpiSession& session, const CaseFunction& evaluate,
                                            const CaseList& cases, const RunnerOptions& options,
                                            RunnerSummary* summary) {
  if (session.size() == 1) return RunCases(evaluate, cases, options, summary);
#if MILLKIT_WITH_MPI
  const auto started = std::chrono::steady_clock::now();
  const int rank = session.rank(), size = session.size();
  CaseList mine;
  for (size_t i = rank; i < cases.size(); i += size) mine.push_back(cases[i]);
  RunnerOptions local = options;
  if (!session.root()) local.progress = nullptr;
  local.label = "sweep rank " + std::to_string(rank);

  std::vector<CaseResult> results;
  RunnerSummary local_summary;
  std::exception_ptr error;
  std::string packed;
  try {
    results = RunCases(evaluate, mine, local, &local_summary);
    for (const auto& r : results) Pack(r, &packed);
  } catch (...) {
    error = std::current_exception();
  }
  const std::vector<std::string> parts = GatherBytes(session, packed, error, "during the sweep");
  int failed_cases = 0;
  MPI_Reduce(&local_summary.failed, &failed_cases, 1, MPI_INT, MPI_SUM, 0, MPI_COMM_WORLD);
  if (!session.root()) return {};

  std::vector<CaseResult> ordered(cases.size());
  for (int r = 0; r < size; ++r) {
    Reader in{parts[r].data()};
    for (size_t i = r; i < cases.size(); i += size) ordered[i] = Unpack(&in);
  }
  if (summary != nullptr) {
    *summary = {static_cast<int>(cases.size()), failed_cases, local_summary.threads,
                std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count()};
  }
  return ordered;
#else
  (void)evaluate;
  (void)cases;
  (void)options;
  (void)summary;
  throw std::logic_error("RunCasesDistributed: a multi-rank session without MPI");
#endif
}

}  // namespace millkit::sweep
