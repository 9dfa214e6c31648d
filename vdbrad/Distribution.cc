#include "vdbrad/Distribution.h"

#include <chrono>
#include <cstdlib>
#include <limits>

#ifdef VDBRAD_WITH_MPI
#include <mpi.h>
#endif

namespace vdbrad {

namespace {

// Started by a launcher: each of these is set in every process mpirun starts.
bool
launched()
{
    for (const char* name : {"OMPI_COMM_WORLD_SIZE", "PMI_SIZE", "PMIX_RANK"}) {
        if (std::getenv(name)) return true;
    }
    return false;
}

} // namespace

Distribution&
Distribution::world()
{
    static Distribution d;
    static bool once = false;
    if (once) return d;
    once = true;
#ifdef VDBRAD_WITH_MPI
    if (launched()) {
        // Only the calling (main) thread talks to MPI: the exchanges are between sweeps.
        int provided = 0;
        MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
        d.mInitialised = true;
        MPI_Comm_rank(MPI_COMM_WORLD, &d.mRank);
        MPI_Comm_size(MPI_COMM_WORLD, &d.mRanks);
        MPI_Comm local;
        MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, d.mRank, MPI_INFO_NULL, &local);
        MPI_Comm_size(local, &d.mLocalRanks);
        MPI_Comm_free(&local);
    }
#endif
    return d;
}

void
Distribution::share(void* data, size_t bytes, int owner) const
{
    if (mRanks == 1 || bytes == 0) return;
#ifdef VDBRAD_WITH_MPI
    // MPI counts are int: large arrays go in pieces.
    const auto t0 = std::chrono::steady_clock::now();
    constexpr size_t kPiece = size_t(1) << 30;
    char* p = static_cast<char*>(data);
    for (size_t at = 0; at < bytes; at += kPiece) {
        const size_t n = bytes - at < kPiece ? bytes - at : kPiece;
        MPI_Bcast(p + at, int(n), MPI_BYTE, owner, MPI_COMM_WORLD);
    }
    mBytes += bytes;
    mSeconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
#else
    (void)data;
    (void)owner;
#endif
}

#ifdef VDBRAD_WITH_MPI
namespace {

template<typename T>
void
allSum(T* values, size_t count, MPI_Datatype type, size_t& bytes, double& seconds)
{
    const auto t0 = std::chrono::steady_clock::now();
    constexpr size_t kPiece = size_t(1) << 27;
    for (size_t at = 0; at < count; at += kPiece) {
        const size_t n = count - at < kPiece ? count - at : kPiece;
        MPI_Allreduce(MPI_IN_PLACE, values + at, int(n), type, MPI_SUM, MPI_COMM_WORLD);
    }
    bytes += count * sizeof(T);
    seconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

} // namespace
#endif

void
Distribution::combine(std::vector<double>& values) const
{
    if (mRanks == 1 || values.empty()) return;
#ifdef VDBRAD_WITH_MPI
    allSum(values.data(), values.size(), MPI_DOUBLE, mBytes, mSeconds);
#endif
}

void
Distribution::combine(float* values, size_t count) const
{
    if (mRanks == 1 || count == 0) return;
#ifdef VDBRAD_WITH_MPI
    allSum(values, count, MPI_FLOAT, mBytes, mSeconds);
#else
    (void)values;
#endif
}

double
Distribution::sum(double value) const
{
    if (mRanks == 1) return value;
#ifdef VDBRAD_WITH_MPI
    double out = 0.0;
    MPI_Allreduce(&value, &out, 1, MPI_DOUBLE, MPI_SUM, MPI_COMM_WORLD);
    return out;
#else
    return value;
#endif
}

void
Distribution::abort(int code) const
{
#ifdef VDBRAD_WITH_MPI
    if (mInitialised && mRanks > 1) MPI_Abort(MPI_COMM_WORLD, code);
#endif
    std::exit(code);
}

void
Distribution::finalize()
{
#ifdef VDBRAD_WITH_MPI
    if (mInitialised) {
        int done = 0;
        MPI_Finalized(&done);
        if (!done) MPI_Finalize();
    }
#endif
    mInitialised = false;
}

} // namespace vdbrad
