// FixedPointIteration: what every solver's iteration x -> G(x) shares, and how a solve is driven.
//
// The surface solver iterates B = E + rho V B (thesis eq. 4.11), the cloud solver the source
// iteration of the transfer equation (thesis §6.3); both stop when the relative residual of an
// iteration falls below a tolerance or at an iteration cap, both may be accelerated by Anderson
// mixing (Acceleration.h) with the same rule for a mixed iterate that is not physical (a negative
// radiance: keep the plain step), and both checkpoint and resume the same way (Checkpoint.h).
// The solvers keep their physics; this file keeps that bookkeeping, once:
//   - FixedPointIteration: option checks, the residual history, timing, convergence, and the
//     bookkeeping's part of a checkpoint;
//   - andersonStep(): one accelerated step with the physical-iterate rule;
//   - iterateSolve(): resume from a checkpoint, iterate to the tolerance or the cap, save a
//     checkpoint every K iterations (atomically), report each iteration.
#pragma once

#include "vdbrad/core/Checkpoint.h"
#include "vdbrad/core/Errors.h"
#include "vdbrad/sweep/Acceleration.h"

#include <openvdb/Exceptions.h>
#include <openvdb/util/NullInterrupter.h>

#include <chrono>
#include <functional>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

namespace vdbrad {

class FixedPointIteration
{
public:
    /// @throw openvdb::ValueError if @a maxIterations < 1, @a tolerance is negative or NaN, or
    ///        (with Acceleration::Anderson) @a andersonDepth < 1
    FixedPointIteration(int maxIterations, double tolerance, Acceleration accelerate,
        int andersonDepth);

    /// @brief Run one iteration: @a sweep() returns its relative residual, which is recorded,
    /// and its wall time is added to seconds().
    template<typename SweepT> double iterate(SweepT&& sweep)
    {
        const auto t0 = std::chrono::steady_clock::now();
        const double residual = sweep();
        addSeconds(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count());
        mResiduals.push_back(residual);
        return residual;
    }

    /// True once the last residual is at or below the tolerance.
    bool converged() const { return !mResiduals.empty() && mResiduals.back() <= mTolerance; }
    /// Converged, or at the iteration cap.
    bool finished() const { return converged() || iterationCount() >= mMaxIterations; }
    int iterationCount() const { return int(mResiduals.size()); }
    int maxIterations() const { return mMaxIterations; }
    const std::vector<double>& residuals() const { return mResiduals; }
    double lastResidual() const { return mResiduals.empty() ? 0.0 : mResiduals.back(); }
    /// Wall time of the iterations (and of whatever else the solver adds), seconds.
    double seconds() const { return mSeconds; }
    void addSeconds(double s) { mSeconds += s; }

    /// How the iteration is accelerated.
    Acceleration acceleration() const { return mAccelerate; }
    /// @brief A mixer for a state of @a size unknowns of type T (Acceleration.h), or null
    /// when the iteration is not accelerated.
    template<typename T> std::unique_ptr<AndersonMixerT<T>> makeMixer(size_t size) const
    {
        if (mAccelerate != Acceleration::Anderson) return nullptr;
        return std::make_unique<AndersonMixerT<T>>(size, mAndersonDepth);
    }

    /// The residuals and seconds, for a checkpoint, and back.
    void save(SolverState& state) const;
    /// @throw openvdb::ValueError if @a state lacks them
    void restore(const SolverState& state);

private:
    int mMaxIterations;
    double mTolerance;
    Acceleration mAccelerate;
    int mAndersonDepth;
    std::vector<double> mResiduals;
    double mSeconds = 0.0;
};

/// What every solver exposes of its iteration (RadiositySolver, CloudTransfer,
/// MonteCarloSolver derive from it).
class IterativeSolver
{
public:
    /// True once the last residual is at or below the tolerance.
    bool converged() const { return mIteration.converged(); }
    /// Converged, or at the iteration cap.
    bool finished() const { return mIteration.finished(); }
    int iterationCount() const { return mIteration.iterationCount(); }
    const std::vector<double>& residuals() const { return mIteration.residuals(); }
    /// Wall time spent setting up and iterating, seconds.
    double seconds() const { return mIteration.seconds(); }

protected:
    explicit IterativeSolver(FixedPointIteration iteration) : mIteration(std::move(iteration)) {}
    FixedPointIteration mIteration;
};

/// @brief One Anderson step: @a gx, the map's image of @a x, becomes the mixed iterate; if
/// @a physical(gx) is then false (a mixed iterate that overshot: the least-squares step
/// extrapolates), the plain step G(x) is kept and the history restarts.
template<typename T, typename PhysicalT>
void
andersonStep(AndersonMixerT<T>& mixer, const T* x, T* gx, PhysicalT&& physical)
{
    mixer.mix(x, gx);
    if (!physical(static_cast<const T*>(gx))) mixer.rejectLastStep(gx);
}

/// How a solve is driven beyond the solver's options: checkpoints and reports.
struct SolveControl
{
    /// Save everything the next iteration reads to this file every checkpointEvery iterations
    /// (not once converged: the output follows at once), atomically; empty: never.
    std::string checkpoint;
    int checkpointEvery = 10;
    /// Restore the solver from this checkpoint first; empty: start afresh.
    std::string resume;
    /// Lines describing the solve: once it is set up (and resumed), and what the solver has
    /// to say at the end (e.g. how much of the visibility cache it used).
    std::function<void(const std::string&)> note;
    /// Called before each iteration (its number, from 1) and after it (with its residual).
    /// When given, the one-call solve functions leave the interrupter's start() and end() to
    /// them (one progress step per iteration); otherwise they frame the whole solve as one.
    std::function<void(int)> beforeIteration;
    std::function<void(int, double)> afterIteration;
    /// Called once iterating stops: iterations done, last residual, whether it converged.
    std::function<void(int, double, bool)> stopped;

    /// @throw openvdb::ValueError if checkpointEvery < 1 or a file name is empty but given
    void validate() const;
};

/// @brief Read a checkpoint file for @a fingerprint. @throw vdbrad::CheckpointError naming
/// @a path (missing, unreadable, corrupt, another problem's)
SolverState readCheckpoint(const std::string& path, uint64_t fingerprint);
/// @brief Write @a state as a checkpoint file atomically. @throw vdbrad::CheckpointError
void writeCheckpoint(const std::string& path, const SolverState& state, uint64_t fingerprint);

/// @brief Run @a restore (a solver's restoreState), turning any error it throws into a
/// vdbrad::CheckpointError naming @a path.
void restoreFrom(const std::string& path, const std::function<void()>& restore);

/// Whether a solver can be checkpointed (has saveState(), restoreState() and fingerprint()).
template<typename T, typename = void> struct KeepsCheckpoints : std::false_type {};
template<typename T>
struct KeepsCheckpoints<T, std::void_t<decltype(std::declval<const T&>().fingerprint())>>
    : std::true_type {};

/// @brief Resume @a solver (RadiositySolver or CloudTransfer) from @a control.resume if given,
/// then iterate it to its tolerance or its iteration cap, saving checkpoints and reporting as
/// @a control says.
/// (MonteCarloSolver keeps no checkpoints: a control naming files is refused.)
/// @throw vdbrad::Cancelled if @a interrupt asks to stop; vdbrad::CheckpointError;
///        openvdb::ValueError for checkpoint files given to a solver that keeps none
template<typename SolverT>
void
iterateSolve(SolverT& solver, const SolveControl& control,
    openvdb::util::NullInterrupter* interrupt = nullptr)
{
    control.validate();
    constexpr bool checkpoints = KeepsCheckpoints<SolverT>::value;
    if constexpr (checkpoints) {
        if (!control.resume.empty()) {
            const SolverState state = readCheckpoint(control.resume, solver.fingerprint());
            restoreFrom(control.resume, [&] { solver.restoreState(state); });
        }
    } else if (!control.resume.empty() || !control.checkpoint.empty()) {
        OPENVDB_THROW(openvdb::ValueError, "this solver keeps no checkpoints");
    }
    if (control.note) control.note(solver.describe());
    while (!solver.finished()) {
        const int next = solver.iterationCount() + 1;
        if (control.beforeIteration) control.beforeIteration(next);
        const double residual = solver.iterate(interrupt);
        if (control.afterIteration) control.afterIteration(next, residual);
        if constexpr (checkpoints) {
            if (!control.checkpoint.empty() && !solver.converged()
                && solver.iterationCount() % control.checkpointEvery == 0) {
                SolverState state;
                solver.saveState(state);
                writeCheckpoint(control.checkpoint, state, solver.fingerprint());
            }
        }
    }
    if (control.stopped) {
        control.stopped(solver.iterationCount(),
            solver.residuals().empty() ? 0.0 : solver.residuals().back(), solver.converged());
    }
}

} // namespace vdbrad
