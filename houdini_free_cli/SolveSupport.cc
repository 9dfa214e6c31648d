#include "SolveSupport.h"

#include "ToolSupport.h"

#include "vdbrad/core/ProcessInfo.h"
#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/scene/OutputGrids.h"

#include <cctype>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <malloc.h>
#include <unistd.h>

#include <fstream>
#include <iostream>
#include <memory>
#include <sstream>

namespace vdbrad {
namespace cli {

int
workerThreads()
{
    return int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
}

std::unique_ptr<tbb::global_control>
threadLimit(const Arguments& a)
{
    const int threads = a.getInt("threads");
    if (threads == 0) return nullptr;
    return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
        size_t(threads));
}

double
heldBytes(double fallback)
{
    const double resident = residentBytes();
    return resident > 0.0 ? resident : fallback;
}

size_t
fileBytes(const VdbFile& file)
{
    size_t bytes = 0;
    for (const auto& g : file.grids) bytes += size_t(g->memUsage());
    return bytes;
}

double
parseBytes(const std::string& option, const std::string& text, bool zero)
{
    char* end = nullptr;
    double v = std::strtod(text.c_str(), &end);
    std::string unit(end ? end : "");
    if (!unit.empty() && (unit.back() == 'B' || unit.back() == 'b')) unit.pop_back();
    if (unit.size() > 1 && (unit.back() == 'i' || unit.back() == 'I')) unit.pop_back();
    const std::string units = "KMGT";
    if (unit.size() == 1 && units.find(char(std::toupper(unit[0]))) != std::string::npos) {
        v *= std::pow(1024.0, double(units.find(char(std::toupper(unit[0]))) + 1));
    } else if (!unit.empty()) {
        v = -1.0;
    }
    if (end == text.c_str() || !(v > 0.0 || (zero && v == 0.0)) || !std::isfinite(v)) {
        throw UsageError("--" + option + ": '" + text + "' is not a size (e.g. 8G, 512M, "
            "1000000" + (zero ? ", 0" : "") + ")");
    }
    return v;
}

double
memoryLimit(const Arguments& a)
{
    if (!a.has("max-memory")) {
        // Ranks started on one machine share its memory (each would otherwise plan for 3/4
        // of it, the visibility cache's auto budget included, and together run out).
        const double physical = physicalMemory();
        return physical > 0.0 ? 0.75 * physical / double(job().localRanks())
                              : 1e300;
    }
    return parseBytes("max-memory", a.getString("max-memory"), false);
}

std::string
checkMemory(const Arguments& a, const std::string& label, double held, double solver)
{
    const double limit = memoryLimit(a), peak = held + solver;
    if (peak > limit) {
        throw UserError(label + ": the solve needs about " + formatBytes(peak)
            + " of memory, over the " + formatBytes(limit) + " allowed (--max-memory; fewer "
            "voxels or directions, or no --accelerate, need less)");
    }
    return "memory: about " + formatBytes(peak) + " at peak (held now " + formatBytes(held)
        + ", solver " + formatBytes(solver) + "; limit " + formatBytes(limit) + ")\n";
}

Checkpointing::Checkpointing(const Arguments& a, const std::string& in, const std::string& out)
{
    if (a.has("checkpoint")) save = a.getString("checkpoint");
    if (a.has("resume")) resume = a.getString("resume");
    every = a.getInt("checkpoint-every");
    if (a.has("checkpoint") && save.empty()) throw UsageError("--checkpoint needs a file");
    if (a.has("resume") && resume.empty()) throw UsageError("--resume needs a file");
    if (a.has("checkpoint-every") && save.empty()) {
        throw UsageError("--checkpoint-every needs --checkpoint FILE");
    }
    for (const std::string& f : {save, resume}) {
        if (!f.empty() && (f == in || f == out || isStdin(f) || isStdout(f))) {
            throw UsageError("a checkpoint must be its own file, not '" + f + "'");
        }
    }
}

void
Checkpointing::finish() const
{
    if (!save.empty()) std::remove(save.c_str());
}

SolveSession::SolveSession(const Arguments& a, const std::string& in, const std::string& out)
    : mCheckpoints(a, in, out)
    , mThreads((memoryLimit(a), threadLimit(a)))   // a bad --max-memory fails before any work
    , mFile((checkOutput(out, {in}, a.flag("overwrite")), readInput(in)))
    , mLabel(inputLabel(in))
    // Under mpirun rank 0 alone prints, saves checkpoints and writes the output.
    , mQuiet(a.flag("quiet") || job().rank() != 0)
    , mProgress(mQuiet)
{
}

SolveControl
SolveSession::control(const std::string& preface)
{
    SolveControl c;
    if (job().rank() == 0) c.checkpoint = mCheckpoints.save;
    c.checkpointEvery = mCheckpoints.every;
    c.resume = mCheckpoints.resume;
    auto first = std::make_shared<bool>(true);
    c.note = [quiet = mQuiet, preface, first](const std::string& line) {
        if (quiet) return;
        std::cerr << (*first ? preface : std::string()) << line << "\n";
        *first = false;
    };
    c.beforeIteration = [this](int k) {
        mProgress.start(("iteration " + std::to_string(k)).c_str());
    };
    c.afterIteration = [this](int, double residual) {
        std::ostringstream result;
        result << "residual " << residual;
        mProgress.end(result.str());
    };
    c.stopped = [this](int, double residual, bool converged) {
        mOutcome.converged = converged;
        mOutcome.residual = residual;
    };
    return c;
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
SolveSession::finish(const openvdb::GridPtrVec& results, const std::string& out,
    int maxIterations)
{
    if (!mQuiet && !mOutcome.converged) {
        warn(mLabel, "stopped at --iterations " + std::to_string(maxIterations)
            + " with residual " + std::to_string(mOutcome.residual) + " > --tolerance");
    }
    const Distribution& ranks = job();
    if (ranks.rank() != 0) return;
    if (ranks.distributed() && !mQuiet) {
        std::ostringstream line;
        line << "vdbrad: " << ranks.ranks() << " ranks: rank 0 exchanged "
             << ranks.exchangedBytes() / 1048576.0 << " MB in " << ranks.exchangeSeconds()
             << " s\n";
        std::cerr << line.str();
    }
    for (const openvdb::GridBase::Ptr& grid : results) {
        grid->insertMeta(meta::kRanks, openvdb::Int32Metadata(ranks.ranks()));
    }
    writeOutput(withGrids(mFile, results), out);
    mCheckpoints.finish();
}

} // namespace cli
} // namespace vdbrad
