// SolvePlan and SolveResult: what a solve will take, said before any work, and what it gave.
//
// A plan is made once the scene is read and before the solver allocates: the directions it
// sweeps, its peak memory (what the process holds now plus the solver's arrays, from their
// sizes) against the limit (--max-memory), and an estimated time per iteration. During the
// solve IterationEta turns the residual's trend into the time left.
#pragma once

#include "vdbrad/request/Request.h"

#include "vdbrad/sweep/FixedPointIteration.h"

#include <openvdb/Grid.h>
#include <openvdb/util/NullInterrupter.h>

#include <tbb/global_control.h>

#include <memory>
#include <optional>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace vdbrad {

class Distribution;

/// A solve refused before it allocates: it would exceed the memory limit. Python: MemoryError.
class MemoryLimitError : public std::runtime_error
{
public:
    using std::runtime_error::runtime_error;
};

struct SolvePlan
{
    int directions = 0;            ///< direction pairs swept per iteration (0: no sweeps)
    double heldBytes = 0.0;        ///< what the process holds now (input, scene)
    double solverBytes = 0.0;      ///< what the solver will allocate
    double limitBytes = 0.0;       ///< the memory limit
    /// Estimated from the sweep costs measured on the CI machine (docs/performance.md), per
    /// core; 0: no estimate (Monte Carlo).
    double secondsPerIteration = 0.0;
    int maxIterations = 0;

    double peakBytes() const { return heldBytes + solverBytes; }
    /// The lines the tool prints before the solve starts ("memory: about ...", "plan: ...").
    std::string describe() const;
    /// @throw MemoryLimitError naming @a option (the limit) and @a cheaper (options that need
    ///        less) if the peak exceeds the limit
    void checkMemory(const std::string& option, const std::string& cheaper) const;
};

/// What a solve gives: the grids it adds to the input's, how it stopped, what it warns of.
struct SolveResult
{
    /// Each named and carrying the solve's metadata (OutputGrids.h), none null.
    openvdb::GridPtrVec grids;
    int iterations = 0;
    double residual = 0.0;
    bool converged = true;
    std::vector<std::string> warnings;
    SolvePlan plan;
};

/// @brief @a control with @a request's checkpoint files (saved by rank 0 of @a ranks alone) and
/// a report of how the iterations stopped into @a result (which must outlive it).
/// @throw OptionError where the checkpoint options contradict each other
SolveControl reportingInto(SolveResult& result, SolveControl control, const Request& request,
    const Distribution* ranks);

/// @brief A solve's steps in order: read @a grids, plan, run (SurfaceSolve, CloudSolve).
template<typename SolveT>
SolveResult
runSteps(SolveT& solve, const openvdb::GridPtrVec& grids,
    openvdb::util::NullInterrupter* interrupt, SolveControl control)
{
    solve.read(grids, interrupt);
    solve.plan();
    return solve.run(interrupt, std::move(control));
}

/// @brief The memory limit of @a request's `max-memory`: the bytes given, or 3/4 of physical
/// memory shared by the ranks of @a ranks on this machine (each would otherwise plan for 3/4 of
/// it and together they would run out).
double memoryLimit(const Request& request, const Distribution* ranks);

/// @brief Bytes this process holds now (resident set), or, where the system does not say,
/// @a fallback.
double heldBytes(double fallback);

/// @brief A TBB limit for @a request's `threads` (0, all cores: null); the results do not
/// depend on it.
std::unique_ptr<tbb::global_control> threadLimit(const Request& request);

/// Threads TBB runs with now.
int workerThreads();

/// @brief The time left to a fixed-point iteration, from the residual's trend: iterations
/// shrink the residual by a nearly constant factor, so the iterations left to @a tolerance
/// follow from the mean factor of the last few and the mean time of one.
class IterationEta
{
public:
    IterationEta(double tolerance, int maxIterations);
    /// Iteration @a k ended after @a seconds with @a residual.
    void add(int k, double residual, double seconds);
    /// Seconds left, once two iterations show a trend; nullopt before, or where it does not fall.
    std::optional<double> secondsLeft() const;

private:
    double mTolerance;
    int mMaxIterations;
    int mLast = 0;
    double mSeconds = 0.0;
    std::vector<double> mResiduals;
};

} // namespace vdbrad
