#include "vdbrad/distribute/Distribution.h"

#include <openvdb/Exceptions.h>

#include <chrono>
#include <climits>
#include <cstdlib>
#include <limits>
#include <list>

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

std::unique_ptr<Distribution>
Distribution::join()
{
    std::unique_ptr<Distribution> d(new Distribution);
#ifdef VDBRAD_WITH_MPI
    if (launched()) {
        int initialised = 0;
        MPI_Initialized(&initialised);
        if (initialised) {
            OPENVDB_THROW(openvdb::RuntimeError, "MPI is already initialised: join the job once "
                "per process");
        }
        // Only the calling (main) thread talks to MPI: the exchanges are between sweeps.
        int provided = 0;
        MPI_Init_thread(nullptr, nullptr, MPI_THREAD_FUNNELED, &provided);
        d->mInitialised = true;
        MPI_Comm_rank(MPI_COMM_WORLD, &d->mRank);
        MPI_Comm_size(MPI_COMM_WORLD, &d->mRanks);
        MPI_Comm local;
        MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, d->mRank, MPI_INFO_NULL,
            &local);
        MPI_Comm_size(local, &d->mLocalRanks);
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

#ifdef VDBRAD_WITH_MPI
namespace {

// One value reduced over the ranks.
double
allReduce(double value, MPI_Op op)
{
    double out = 0.0;
    MPI_Allreduce(&value, &out, 1, MPI_DOUBLE, op, MPI_COMM_WORLD);
    return out;
}

} // namespace
#endif

double
Distribution::sum(double value) const
{
#ifdef VDBRAD_WITH_MPI
    if (mRanks > 1) return allReduce(value, MPI_SUM);
#endif
    return value;
}

double
Distribution::maximum(double value) const
{
#ifdef VDBRAD_WITH_MPI
    if (mRanks > 1) return allReduce(value, MPI_MAX);
#endif
    return value;
}

struct Distribution::Sends
{
#ifdef VDBRAD_WITH_MPI
    struct Message
    {
        MPI_Request request;
        std::vector<char> bytes;
    };
    std::list<Message> pending;
#endif
};

Distribution::Distribution() = default;
Distribution::~Distribution() = default;


void
Distribution::send(int to, int tag, std::vector<char>&& bytes) const
{
    if (bytes.size() > size_t(INT_MAX)) {
        OPENVDB_THROW(openvdb::ValueError, "a message of " << bytes.size()
            << " bytes between ranks (over MPI's 2 GiB)");
    }
#ifdef VDBRAD_WITH_MPI
    if (!mSends) mSends.reset(new Sends);
    // Delivered ones first, so that the list stays short.
    for (auto it = mSends->pending.begin(); it != mSends->pending.end();) {
        int done = 0;
        MPI_Test(&it->request, &done, MPI_STATUS_IGNORE);
        it = done ? mSends->pending.erase(it) : std::next(it);
    }
    mSends->pending.push_back({MPI_Request(), std::move(bytes)});
    Sends::Message& m = mSends->pending.back();
    MPI_Isend(m.bytes.data(), int(m.bytes.size()), MPI_BYTE, to, tag, MPI_COMM_WORLD,
        &m.request);
    mBytes += m.bytes.size();
#else
    (void)to;
    (void)tag;
    (void)bytes;
#endif
}

bool
Distribution::receive(int from, int tag, std::vector<char>& bytes) const
{
#ifdef VDBRAD_WITH_MPI
    int flag = 0;
    MPI_Status status;
    MPI_Iprobe(from, tag, MPI_COMM_WORLD, &flag, &status);
    if (!flag) return false;
    int count = 0;
    MPI_Get_count(&status, MPI_BYTE, &count);
    bytes.resize(size_t(count));
    MPI_Recv(bytes.data(), count, MPI_BYTE, from, tag, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
    mBytes += size_t(count);
    return true;
#else
    (void)from;
    (void)tag;
    (void)bytes;
    return false;
#endif
}

void
Distribution::finishSends() const
{
#ifdef VDBRAD_WITH_MPI
    if (!mSends) return;
    for (Sends::Message& m : mSends->pending) MPI_Wait(&m.request, MPI_STATUS_IGNORE);
    mSends->pending.clear();
#endif
}

std::vector<std::vector<char>>
Distribution::gather(const void* data, size_t bytes, int root) const
{
    std::vector<std::vector<char>> out;
    const char* p = static_cast<const char*>(data);
    if (mRanks == 1) {
        out.emplace_back(p, p + bytes);
        return out;
    }
#ifdef VDBRAD_WITH_MPI
    const auto t0 = std::chrono::steady_clock::now();
    constexpr size_t kPiece = size_t(1) << 30;   // MPI counts are int
    constexpr int kTag = 1000;
    if (mRank != root) {
        unsigned long long size = bytes;
        MPI_Send(&size, 1, MPI_UNSIGNED_LONG_LONG, root, kTag, MPI_COMM_WORLD);
        for (size_t at = 0; at < bytes; at += kPiece) {
            const size_t n = bytes - at < kPiece ? bytes - at : kPiece;
            MPI_Send(p + at, int(n), MPI_BYTE, root, kTag, MPI_COMM_WORLD);
        }
    } else {
        out.resize(size_t(mRanks));
        for (int r = 0; r < mRanks; ++r) {
            std::vector<char>& v = out[size_t(r)];
            if (r == root) {
                v.assign(p, p + bytes);
                continue;
            }
            unsigned long long size = 0;
            MPI_Recv(&size, 1, MPI_UNSIGNED_LONG_LONG, r, kTag, MPI_COMM_WORLD,
                MPI_STATUS_IGNORE);
            v.resize(size_t(size));
            for (size_t at = 0; at < v.size(); at += kPiece) {
                const size_t n = v.size() - at < kPiece ? v.size() - at : kPiece;
                MPI_Recv(v.data() + at, int(n), MPI_BYTE, r, kTag, MPI_COMM_WORLD,
                    MPI_STATUS_IGNORE);
            }
            mBytes += v.size();
        }
    }
    mSeconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
#endif
    return out;
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
