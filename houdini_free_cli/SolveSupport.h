// SolveSupport: what `solve` and `solve-cloud` share: threads, the memory check, and the
// checkpoint options and progress lines they hand the library's one-call solves.
#pragma once

#include "CommandLine.h"
#include "Progress.h"

#include "vdbrad/core/GridIO.h"
#include "vdbrad/sweep/FixedPointIteration.h"

#include <tbb/global_control.h>

#include <memory>
#include <string>

namespace vdbrad {
namespace cli {

/// Threads TBB will run with now (after any --threads limit).
int workerThreads();

/// --threads: a TBB limit for the rest of the command (null: all cores).
std::unique_ptr<tbb::global_control> threadLimit(const Arguments& a);

/// @brief Bytes this process holds now (resident set: the program, the input, the scene), or,
/// where /proc is missing, @a fallback.
double heldBytes(double fallback);

/// Bytes the input's grids hold in memory.
size_t fileBytes(const VdbFile& file);

/// @brief A size in bytes ("512M", "8G", "1.5T", "1000000"; binary units), > 0 or, if @a zero,
/// >= 0.
/// @throw UsageError naming @a option
double parseBytes(const std::string& option, const std::string& text, bool zero);

/// --max-memory: bytes, given or 3/4 of physical memory.
double memoryLimit(const Arguments& a);

/// @brief The estimated peak (@a held now plus @a solver, what the solver will allocate), as a
/// line to print.
/// @throw UserError past --max-memory, before the solver allocates anything
std::string checkMemory(const Arguments& a, const std::string& label, double held,
    double solver);

/// --checkpoint FILE --checkpoint-every K and --resume FILE.
struct Checkpointing
{
    std::string save, resume;
    int every = 10;

    /// @throw UsageError where the options contradict each other or name @a in or @a out
    Checkpointing(const Arguments& a, const std::string& in, const std::string& out);

    /// Once the output is written the checkpoint has served.
    void finish() const;
};

/// How a one-call solve went, as the command reports it afterwards.
struct SolveOutcome
{
    bool converged = true;
    double residual = 0.0;
};

/// What `solve` and `solve-cloud` set up once their own options are read, in this order: the
/// checkpoint options, --max-memory and --threads checked, the output checked (nothing is
/// overwritten by a failed run), the input read; then what they hand the library's one-call
/// solve and do with its result.
class SolveSession
{
public:
    /// @throw UsageError, UserError
    SolveSession(const Arguments& a, const std::string& in, const std::string& out);

    /// @brief The SolveControl (FixedPointIteration.h) of the solve: the checkpoint options, one
    /// progress step per iteration with its residual, and the solve's notes on stderr unless
    /// --quiet, the first one after @a preface (the memory line).
    SolveControl control(const std::string& preface);
    /// @brief Warn if the solve stopped at @a maxIterations short of --tolerance, write
    /// @a results beside the input's grids to @a out, and remove the checkpoint, which has
    /// served.
    void finish(const openvdb::GridPtrVec& results, const std::string& out, int maxIterations);

    const VdbFile& file() const { return mFile; }
    /// @brief Under mpirun, on the ranks that write nothing (all but 0): drop the input's
    /// grids, once what the solve needs of them is built (as much memory as the scene again).
    void releaseInput();
    const std::string& label() const { return mLabel; }
    bool quiet() const { return mQuiet; }
    ProgressInterrupter& progress() { return mProgress; }

private:
    Checkpointing mCheckpoints;
    std::unique_ptr<tbb::global_control> mThreads;
    VdbFile mFile;
    std::string mLabel;
    bool mQuiet;
    ProgressInterrupter mProgress;
    SolveOutcome mOutcome;
};

} // namespace cli
} // namespace vdbrad
