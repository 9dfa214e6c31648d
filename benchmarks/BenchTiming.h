// What every benchmark times with: the best of a few runs of a piece of work.
#pragma once

#include <algorithm>
#include <chrono>
#include <functional>
#include <memory>
#include <utility>

#include <sys/resource.h>

namespace vdbrad {
namespace bench {

/// Best of @a reps runs of @a f, in seconds (the least disturbed by the rest of the machine).
inline double
timeIt(const std::function<void()>& f, int reps = 3)
{
    double best = 1e300;
    for (int i = 0; i < reps; ++i) {
        const auto t0 = std::chrono::steady_clock::now();
        f();
        best = std::min(best, std::chrono::duration<double>(std::chrono::steady_clock::now() - t0)
            .count());
    }
    return best;
}

/// CPU seconds (user + sys, all threads) this process has used so far: what SHDOM's figures
/// give, so a difference of two is comparable with them.
inline double
processCpuSeconds()
{
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return double(u.ru_utime.tv_sec + u.ru_stime.tv_sec)
        + 1e-6 * double(u.ru_utime.tv_usec + u.ru_stime.tv_usec);
}

/// CPU (processCpuSeconds()) and wall seconds of one run of @a f.
struct Spent
{
    double cpu = 0.0, wall = 0.0;
};
template<typename F>
inline Spent
spent(F&& f)
{
    const double cpu0 = processCpuSeconds();
    const auto t0 = std::chrono::steady_clock::now();
    f();
    return {processCpuSeconds() - cpu0,
        std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count()};
}

/// A solver made from @a args and solved to its tolerance or cap, with the CPU and wall seconds
/// that took, its setup included, in @a took.
template<typename SolverT, typename... ArgsT>
inline std::unique_ptr<SolverT>
solved(Spent& took, ArgsT&&... args)
{
    std::unique_ptr<SolverT> solver;
    took = spent([&] {
        solver.reset(new SolverT(std::forward<ArgsT>(args)...));
        solver->solve();
    });
    return solver;
}

} // namespace bench
} // namespace vdbrad
