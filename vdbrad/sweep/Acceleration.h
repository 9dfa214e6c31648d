// Acceleration: Anderson acceleration of the solvers' fixed-point iterations.
//
// Both solvers iterate an affine map x -> G(x) = T x + b: one Jacobi sweep of every direction
// for surfaces (x = B, T = rho x visibility), one source iteration for clouds (x = the radiance
// moments). Plain iteration converges like rho(T)^k, hopeless when rho(T) -> 1 (a furnace at
// albedo rho needs ~ln(tolerance) / ln(rho) sweeps: ~11,500 at rho = 0.999 for 1e-5). Anderson
// mixing (Walker & Ni 2011, "type II", mixing 1) keeps the last m differences of iterates
// dF = f_{k} - f_{k-1} (f = G(x) - x, the residual) and dG = G(x_k) - G(x_{k-1}), finds the
// combination gamma that minimises |f_k - dF gamma|_2 and moves to
//
//     x_{k+1} = G(x_k) - dG gamma.
//
// For an affine map this is GMRES on (I - T) x = b with the sweep as the operator, restarted
// by truncation of the history: it removes the few slow modes of T (the furnace's uniform mode,
// the thick cloud's diffusion modes) that plain iteration leaves for last. The cost is one
// sweep per iteration, as before, plus 3m multiply-adds per unknown; the memory is 2m + 2
// vectors of the state (bytes() says how much).
//
// Precision: the history is stored in the state's own type T (float, or double for a surface
// solve with albedos near 1, RadiositySolver.h: there the combination's coefficients grow like
// 1 / (1 - rho), and a float history would amplify its rounding by as much); the small
// least-squares problem is solved in double. Its normal equations are factored by a Cholesky
// decomposition that skips columns whose pivot is below 1e-8 of their squared norm (nearly
// dependent differences, which appear as the iteration converges), newest first, so the oldest
// redundant ones are dropped.
//
// Determinism: every dot product is summed over fixed blocks of the state in a fixed order, so
// the result does not depend on the thread count.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace vdbrad {

class SolverState;

/// How the solvers' iterations are accelerated.
enum class Acceleration
{
    /// Plain fixed-point iteration (the solver's own update scheme).
    None,
    /// Anderson mixing of the last `andersonDepth` iterates (see above).
    Anderson
};

/// "none" or "anderson"; throws openvdb::ValueError otherwise.
Acceleration accelerationFromString(const std::string& name);
const char* toString(Acceleration a);

template<typename T>
class AndersonMixerT
{
public:
    /// @param size  unknowns in the state
    /// @param depth history length m >= 1
    AndersonMixerT(size_t size, int depth);

    /// @brief One Anderson step.
    /// @param x   the iterate the map was applied to (size() values)
    /// @param gx  its image G(x); on return, the next iterate
    void mix(const T* x, T* gx);

    /// @brief Undo the last mix(): @a gx becomes G(x) again, the plain step, and the history
    /// restarts. For a mixed iterate the caller finds unphysical (a negative radiance: the
    /// least-squares step extrapolates, and on a nearly singular problem it can overshoot).
    /// mix() itself does this when the mixed iterate is not finite.
    void rejectLastStep(T* gx);

    /// Forget the history (the next mix() is a plain step that starts a new one).
    void restart();

    size_t size() const { return mSize; }
    int depth() const { return mDepth; }
    /// Columns of history in use after the last mix(), and of those how many it combined.
    int historyUsed() const { return mUsed; }
    int columnsCombined() const { return mCombined; }
    /// Steps undone so far (rejectLastStep() or a non-finite mix).
    size_t rejectedSteps() const { return mRejected; }

    /// Save the history under names starting with @a prefix (Checkpoint.h), and restore it.
    /// @throw openvdb::ValueError from restore() if the saved sizes do not match this mixer's
    void save(SolverState& state, const std::string& prefix) const;
    void restore(const SolverState& state, const std::string& prefix);

    /// Bytes a mixer of @a size unknowns and @a depth columns holds.
    static size_t bytes(size_t size, int depth);

private:
    size_t mSize;
    int mDepth;
    int mUsed = 0;          // valid columns in the ring
    int mNewest = -1;       // ring slot of the newest column
    int mCombined = 0;
    bool mHavePrevious = false;
    size_t mRejected = 0;
    int mScaleExponent = 0;                // the history holds values x 2^mScaleExponent
    std::vector<T> mDeltaF, mDeltaG;       // depth columns of size values each
    std::vector<T> mPreviousF, mPreviousG;
    std::vector<double> mGram;             // depth x depth, dF_i . dF_j
};

using AndersonMixer = AndersonMixerT<float>;

} // namespace vdbrad
