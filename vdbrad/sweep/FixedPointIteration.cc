#include "vdbrad/sweep/FixedPointIteration.h"

#include "vdbrad/core/Errors.h"
#include "vdbrad/core/GridIO.h"

#include <openvdb/Exceptions.h>

#include <fstream>
#include <sstream>

namespace vdbrad {

FixedPointIteration::FixedPointIteration(int maxIterations, double tolerance,
    Acceleration accelerate, int andersonDepth)
    : mMaxIterations(maxIterations)
    , mTolerance(tolerance)
    , mAccelerate(accelerate)
    , mAndersonDepth(andersonDepth)
{
    if (maxIterations < 1) {
        OPENVDB_THROW(openvdb::ValueError, "iterations must be >= 1, got " << maxIterations);
    }
    if (!(tolerance >= 0.0)) {
        OPENVDB_THROW(openvdb::ValueError, "tolerance must be >= 0, got " << tolerance);
    }
    if (accelerate == Acceleration::Anderson && andersonDepth < 1) {
        OPENVDB_THROW(openvdb::ValueError, "Anderson depth must be >= 1, got " << andersonDepth);
    }
}

void
FixedPointIteration::save(SolverState& state) const
{
    state.put("residuals", mResiduals);
    state.put("seconds", &mSeconds, 1);
}

void
FixedPointIteration::restore(const SolverState& state)
{
    mResiduals = state.get<double>("residuals");
    mSeconds = state.get<double>("seconds", 1)[0];
}

void
SolveControl::validate() const
{
    if (checkpointEvery < 1) {
        OPENVDB_THROW(openvdb::ValueError, "checkpoint interval must be >= 1, got "
            << checkpointEvery);
    }
}

SolverState
readCheckpoint(const std::string& path, uint64_t fingerprint)
{
    std::ifstream f(path, std::ios::binary);
    if (!f.is_open()) throw CheckpointError(path + ": cannot open the checkpoint");
    std::ostringstream bytes;
    bytes << f.rdbuf();
    if (f.bad()) throw CheckpointError(path + ": cannot read the checkpoint");
    try {
        return SolverState::parse(bytes.str(), fingerprint);
    } catch (const openvdb::Exception& e) {
        throw CheckpointError(path + ": " + errorMessage(e));
    }
}

void
writeCheckpoint(const std::string& path, const SolverState& state, uint64_t fingerprint)
{
    try {
        writeFileAtomic(path, state.serialize(fingerprint));
    } catch (const std::exception& e) {
        throw CheckpointError(path + ": " + errorMessage(e));
    }
}

void
restoreFrom(const std::string& path, const std::function<void()>& restore)
{
    try {
        restore();
    } catch (const std::exception& e) {
        throw CheckpointError(path + ": " + errorMessage(e));
    }
}

} // namespace vdbrad
