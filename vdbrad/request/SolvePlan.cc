#include "vdbrad/request/SolvePlan.h"

#include "vdbrad/request/SharedOptions.h"

#include "vdbrad/core/ProcessInfo.h"
#include "vdbrad/core/TextFormat.h"
#include "vdbrad/distribute/Distribution.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace vdbrad {

std::string
SolvePlan::describe() const
{
    std::ostringstream os;
    os << "memory: about " << formatBytes(peakBytes()) << " at peak (held now "
       << formatBytes(heldBytes) << ", solver " << formatBytes(solverBytes) << "; limit "
       << formatBytes(limitBytes) << ")\n";
    if (directions > 0 && secondsPerIteration > 0.0) {
        os.precision(2);
        os << "plan: " << directions << " direction pairs, about " << secondsPerIteration
           << " s per iteration, at most " << maxIterations << " iterations\n";
    }
    return os.str();
}

void
SolvePlan::checkMemory(const std::string& option, const std::string& cheaper) const
{
    if (peakBytes() <= limitBytes) return;
    throw MemoryLimitError("the solve needs about " + formatBytes(peakBytes()) + " of memory, "
        "over the " + formatBytes(limitBytes) + " allowed (" + option + "; " + cheaper
        + " need less)");
}

SolveControl
reportingInto(SolveResult& result, SolveControl control, const Request& request,
    const Distribution* ranks)
{
    options::setCheckpoints(request, ranks ? ranks->rank() : 0, control);
    auto stopped = std::move(control.stopped);
    control.stopped = [&result, stopped](int k, double residual, bool converged) {
        result.iterations = k;
        result.residual = residual;
        result.converged = converged;
        if (stopped) stopped(k, residual, converged);
    };
    return control;
}

double
memoryLimit(const Request& request, const Distribution* ranks)
{
    if (request.has("max-memory")) return request.bytes("max-memory", false);
    const double physical = physicalMemory();
    const int local = ranks ? ranks->localRanks() : 1;
    return physical > 0.0 ? 0.75 * physical / double(local) : 1e300;
}

double
heldBytes(double fallback)
{
    const double resident = residentBytes();
    return resident > 0.0 ? resident : fallback;
}

std::unique_ptr<tbb::global_control>
threadLimit(const Request& request)
{
    const int threads = request.getInt("threads");
    if (threads == 0) return nullptr;
    return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
        size_t(threads));
}

int
workerThreads()
{
    return int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
}

IterationEta::IterationEta(double tolerance, int maxIterations)
    : mTolerance(tolerance)
    , mMaxIterations(maxIterations)
{
}

void
IterationEta::add(int k, double residual, double seconds)
{
    mLast = k;
    mSeconds += seconds;
    mResiduals.push_back(residual);
}

std::optional<double>
IterationEta::secondsLeft() const
{
    const size_t n = mResiduals.size();
    if (n < 3 || mLast >= mMaxIterations) return std::nullopt;
    // The first iterations fall fastest (the unscattered light): the trend of the last few.
    const size_t span = std::min<size_t>(n - 1, 5);
    const double first = mResiduals[n - 1 - span], last = mResiduals[n - 1];
    if (!(first > 0.0 && last > 0.0 && last < first)) return std::nullopt;
    const double perIteration = mSeconds / double(n);
    const double factor = std::pow(last / first, 1.0 / double(span));
    double left = double(mMaxIterations - mLast);
    if (mTolerance > 0.0 && last > mTolerance) {
        left = std::min(left, std::ceil(std::log(mTolerance / last) / std::log(factor)));
    } else if (mTolerance > 0.0) {
        left = 0.0;
    }
    return left * perIteration;
}

} // namespace vdbrad
