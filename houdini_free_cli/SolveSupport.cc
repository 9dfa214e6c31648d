#include "SolveSupport.h"

#include "ToolSupport.h"

#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/request/SurfaceRequest.h"
#include "vdbrad/scene/OutputGrids.h"

#include <cmath>
#include <cstdio>
#include <malloc.h>

#include <iostream>
#include <memory>
#include <sstream>

namespace vdbrad {
namespace cli {

namespace {

// A checkpoint is a file of its own: not the input or output, not a standard stream.
const std::string&
checkpointFiles(const Arguments& a, const std::string& in, const std::string& out)
{
    for (const char* option : {"checkpoint", "resume"}) {
        const std::string f = a.getString(option);
        if (!f.empty() && (f == in || f == out || isStdin(f) || isStdout(f))) {
            throw UsageError("a checkpoint must be its own file, not '" + f + "'");
        }
    }
    return in;
}

} // namespace

SolveSession::SolveSession(const Arguments& a, const std::string& in, const std::string& out)
    : mArgs(a)
    , mThreads((checkpointFiles(a, in, out), threadLimit(a.request())))
    , mFile((checkOutput(out, {in}, a.flag("overwrite")), readInput(in)))
    , mLabel(inputLabel(in))
    // Under mpirun rank 0 alone prints, saves checkpoints and writes the output.
    , mQuiet(a.flag("quiet") || job().rank() != 0)
    , mProgress(mQuiet)
    , mEta(a.getFloat("tolerance"), a.getInt("iterations"))
{
}

SolveControl
SolveSession::control(const std::string& preface)
{
    SolveControl c;
    auto first = std::make_shared<bool>(true);
    c.note = [quiet = mQuiet, preface, first](const std::string& line) {
        if (quiet) return;
        std::cerr << (*first ? preface : std::string()) << line << "\n";
        *first = false;
    };
    c.beforeIteration = [this](int k) {
        mIterationStart = std::chrono::steady_clock::now();
        mProgress.start(("iteration " + std::to_string(k)).c_str());
    };
    c.afterIteration = [this](int k, double residual) {
        const std::chrono::duration<double> took =
            std::chrono::steady_clock::now() - mIterationStart;
        mEta.add(k, residual, took.count());
        std::ostringstream result;
        result << "residual " << residual;
        // Seconds are worth saying only when they are there to wait.
        if (const auto left = mEta.secondsLeft(); left && *left >= 1.0) {
            result << " (about " << std::llround(*left) << " s left)";
        }
        mProgress.end(result.str());
    };
    return c;
}

void
SolveSession::warn(const std::vector<std::string>& warnings)
{
    for (; mWarned < warnings.size(); ++mWarned) cli::warn(mLabel, warnings[mWarned]);
}

void
SolveSession::releaseInput()
{
    if (job().rank() == 0) return;
    openvdb::GridPtrVec().swap(mFile.grids);
#ifdef __GLIBC__
    // Leaf nodes are small blocks: glibc keeps them in the heap unless asked to give it back.
    ::malloc_trim(0);
#endif
}

void
SolveSession::finish(const SolveResult& result, const std::string& out)
{
    warn(result.warnings);
    if (!mQuiet && !result.converged) cli::warn(mLabel, stoppedShort(result, mArgs.request()));
    const Distribution& ranks = job();
    if (ranks.rank() != 0) return;
    if (ranks.distributed() && !mQuiet) {
        std::ostringstream line;
        line << "vdbrad: " << ranks.ranks() << " ranks: rank 0 exchanged "
             << ranks.exchangedBytes() / 1048576.0 << " MB in " << ranks.exchangeSeconds()
             << " s\n";
        std::cerr << line.str();
    }
    for (const openvdb::GridBase::Ptr& grid : result.grids) {
        grid->insertMeta(meta::kRanks, openvdb::Int32Metadata(ranks.ranks()));
    }
    writeOutput(withGrids(mFile, result.grids), out);
    if (mArgs.has("checkpoint")) std::remove(mArgs.getString("checkpoint").c_str());
}

} // namespace cli
} // namespace vdbrad
