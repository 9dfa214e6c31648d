// SolveSupport: what `solve` and `solve-cloud` do around the library's solve (SurfaceSolve,
// CloudSolve: vdbrad/request/): the threads, the output checked and the input read before any
// work, progress lines with the time left, warnings, and the output written.
#pragma once

#include "CommandLine.h"
#include "Progress.h"

#include "vdbrad/core/GridIO.h"
#include "vdbrad/request/SolvePlan.h"
#include "vdbrad/sweep/FixedPointIteration.h"

#include <tbb/global_control.h>

#include <chrono>
#include <memory>
#include <string>
#include <vector>

namespace vdbrad {
namespace cli {

/// What `solve` and `solve-cloud` set up once the library has read their options, in this order:
/// the checkpoint files checked against the input and output, --threads, the output checked
/// (nothing is overwritten by a failed run), the input read; then the progress and reports of
/// the library's solve, and its result written.
class SolveSession
{
public:
    /// @throw UsageError, UserError
    SolveSession(const Arguments& a, const std::string& in, const std::string& out);

    /// @brief The SolveControl (FixedPointIteration.h) of the solve: one progress step per
    /// iteration with its residual and the time left, and the solve's notes on stderr unless
    /// --quiet, the first one after @a preface (the plan).
    SolveControl control(const std::string& preface);
    /// @brief The library's warnings not said yet, on stderr.
    void warn(const std::vector<std::string>& warnings);
    /// @brief Warn if the solve stopped short of --tolerance, write @a result's grids beside
    /// the input's to @a out, and remove the checkpoint, which has served.
    void finish(const SolveResult& result, const std::string& out);

    const VdbFile& file() const { return mFile; }
    /// @brief Under mpirun, on the ranks that write nothing (all but 0): drop the input's
    /// grids, once what the solve needs of them is built (as much memory as the scene again).
    void releaseInput();
    const std::string& label() const { return mLabel; }
    ProgressInterrupter& progress() { return mProgress; }

private:
    const Arguments& mArgs;
    std::unique_ptr<tbb::global_control> mThreads;
    VdbFile mFile;
    std::string mLabel;
    bool mQuiet;
    ProgressInterrupter mProgress;
    size_t mWarned = 0;
    IterationEta mEta;
    std::chrono::steady_clock::time_point mIterationStart;
};

} // namespace cli
} // namespace vdbrad
