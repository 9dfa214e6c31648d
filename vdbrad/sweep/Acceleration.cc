#include "vdbrad/sweep/Acceleration.h"

#include "vdbrad/core/Checkpoint.h"

#include <openvdb/Exceptions.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>

namespace vdbrad {

namespace {

// Dot products are summed per block of this many values, then over the blocks in order: the same
// bits for any thread count.
constexpr size_t kBlock = size_t(1) << 14;

// A column whose squared distance to the span of the newer ones is below this fraction of its
// squared norm adds nothing a float history can resolve: it is left out of the combination.
constexpr double kDependent = 1e-8;

// The new column @a dF's products with the @a used columns of @a deltaF (a row of the Gram
// matrix: row and column @a slot of @a gram, m x m) and every column's product with f_k (the
// right-hand side, into @a rhs), all of @a n values: per block in parallel, then over the blocks
// in order.
template<typename T>
void
gramRow(const std::vector<T>& deltaF, const T* dF, const std::vector<T>& f, size_t n, size_t m,
    size_t used, size_t slot, std::vector<double>& gram, std::vector<double>& rhs)
{
    const size_t blocks = (n + kBlock - 1) / kBlock;
    std::vector<double> partial(blocks * 2 * m, 0.0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, blocks),
        [&](const tbb::blocked_range<size_t>& r) {
        for (size_t b = r.begin(); b != r.end(); ++b) {
            const size_t lo = b * kBlock, hi = std::min(n, lo + kBlock);
            double* row = &partial[b * 2 * m];
            double* blockRhs = row + m;
            for (size_t j = 0; j < used; ++j) {
                const T* c = &deltaF[j * n];
                double sRow = 0.0, sRhs = 0.0;
                for (size_t i = lo; i < hi; ++i) {
                    sRow += double(dF[i]) * double(c[i]);
                    sRhs += double(c[i]) * double(f[i]);
                }
                row[j] = sRow;
                blockRhs[j] = sRhs;
            }
        }
    });
    for (size_t j = 0; j < used; ++j) {
        double sRow = 0.0, sRhs = 0.0;
        for (size_t b = 0; b < blocks; ++b) {
            sRow += partial[b * 2 * m + j];
            sRhs += partial[b * 2 * m + m + j];
        }
        gram[slot * m + j] = gram[j * m + slot] = sRow;
        rhs[j] = sRhs;
    }
}

// Least squares min |f_k - dF gamma| by the normal equations (@a gram, m x m, and @a rhs),
// columns newest first from ring slot @a slot back over the @a used ones; a column (nearly) in
// the span of newer ones is skipped. Returns the ring slots of the columns kept, with their
// coefficients in @a gamma; none if no column is kept.
std::vector<size_t>
leastSquares(const std::vector<double>& gram, const std::vector<double>& rhs, size_t m,
    size_t slot, size_t used, std::vector<double>& gamma)
{
    std::vector<size_t> order;           // ring slots, newest first
    for (size_t t = 0; t < used; ++t) order.push_back((slot + m - t) % m);
    std::vector<size_t> kept;
    std::vector<double> L(m * m, 0.0);   // L[a * m + b]: Cholesky factor, rows of kept columns
    for (size_t c : order) {
        const double diag = gram[c * m + c];
        if (!(diag > 0.0)) continue;
        const size_t a = kept.size();
        double pivot = diag;
        for (size_t k = 0; k < a; ++k) {
            double v = gram[c * m + kept[k]];
            for (size_t p = 0; p < k; ++p) v -= L[a * m + p] * L[k * m + p];
            L[a * m + k] = v / L[k * m + k];
            pivot -= L[a * m + k] * L[a * m + k];
        }
        if (!(pivot > kDependent * diag)) continue;
        L[a * m + a] = std::sqrt(pivot);
        kept.push_back(c);
    }
    if (kept.empty()) return kept;
    const size_t K = kept.size();
    std::vector<double> y(K);
    gamma.assign(K, 0.0);
    for (size_t a = 0; a < K; ++a) {
        double v = rhs[kept[a]];
        for (size_t p = 0; p < a; ++p) v -= L[a * m + p] * y[p];
        y[a] = v / L[a * m + a];
    }
    for (size_t a = K; a-- > 0;) {
        double v = y[a];
        for (size_t p = a + 1; p < K; ++p) v -= L[p * m + a] * gamma[p];
        gamma[a] = v / L[a * m + a];
    }
    return kept;
}

} // namespace

Acceleration
accelerationFromString(const std::string& name)
{
    if (name == "none") return Acceleration::None;
    if (name == "anderson") return Acceleration::Anderson;
    OPENVDB_THROW(openvdb::ValueError, "unknown acceleration '" << name
        << "' (expected none or anderson)");
}

const char*
toString(Acceleration a)
{
    return a == Acceleration::Anderson ? "anderson" : "none";
}

template<typename T>
AndersonMixerT<T>::AndersonMixerT(size_t size, int depth)
    : mSize(size)
    , mDepth(depth)
{
    if (depth < 1) OPENVDB_THROW(openvdb::ValueError, "Anderson depth must be >= 1, got " << depth);
    mDeltaF.resize(size * size_t(depth));
    mDeltaG.resize(size * size_t(depth));
    mPreviousF.resize(size);
    mPreviousG.resize(size);
    mGram.assign(size_t(depth) * size_t(depth), 0.0);
}

template<typename T>
size_t
AndersonMixerT<T>::bytes(size_t size, int depth)
{
    return (2 * size_t(std::max(depth, 0)) + 2) * size * sizeof(T);
}

template<typename T>
void
AndersonMixerT<T>::save(SolverState& state, const std::string& prefix) const
{
    const int64_t scalars[6] = {int64_t(mSize), mDepth, mUsed, mNewest, mHavePrevious ? 1 : 0,
        mScaleExponent};
    state.put(prefix + "scalars", scalars, 6);
    state.put(prefix + "deltaF", mDeltaF);
    state.put(prefix + "deltaG", mDeltaG);
    state.put(prefix + "previousF", mPreviousF);
    state.put(prefix + "previousG", mPreviousG);
    state.put(prefix + "gram", mGram);
}

template<typename T>
void
AndersonMixerT<T>::restore(const SolverState& state, const std::string& prefix)
{
    const std::vector<int64_t> s = state.get<int64_t>(prefix + "scalars", 6);
    if (s[0] != int64_t(mSize) || s[1] != mDepth || s[2] < 0 || s[2] > mDepth || s[3] < -1
        || s[3] >= mDepth) {
        OPENVDB_THROW(openvdb::ValueError, "checkpoint's Anderson history does not match "
            "(size " << s[0] << ", depth " << s[1] << ")");
    }
    mDeltaF = state.get<T>(prefix + "deltaF", mDeltaF.size());
    mDeltaG = state.get<T>(prefix + "deltaG", mDeltaG.size());
    mPreviousF = state.get<T>(prefix + "previousF", mSize);
    mPreviousG = state.get<T>(prefix + "previousG", mSize);
    mGram = state.get<double>(prefix + "gram", mGram.size());
    mUsed = int(s[2]);
    mNewest = int(s[3]);
    mHavePrevious = s[4] != 0;
    mScaleExponent = int(s[5]);
    mCombined = 0;
}

template<typename T>
void
AndersonMixerT<T>::restart()
{
    mUsed = 0;
    mNewest = -1;
    mCombined = 0;
    mHavePrevious = false;
}

template<typename T>
void
AndersonMixerT<T>::mix(const T* x, T* gx)
{
    const size_t n = mSize;
    const size_t m = size_t(mDepth);
    mCombined = 0;

    if (!mHavePrevious) {
        // The first step only starts the history: x_{k+1} = G(x_k). It also fixes the history's
        // scale: a power of two that brings max |G(x)| near 1, so that differences of a state
        // of 1e-30 (or 1e30) stay in float's normal range, and a scaled problem gives scaled
        // bits.
        T top = 0;
        for (size_t i = 0; i < n; ++i) top = std::max(top, std::abs(gx[i]));
        int e = 0;
        if (top > 0 && std::isfinite(top)) std::frexp(top, &e);
        mScaleExponent = -e;
        const double scale = std::ldexp(1.0, mScaleExponent);
        for (size_t i = 0; i < n; ++i) {
            mPreviousF[i] = T((double(gx[i]) - double(x[i])) * scale);
            mPreviousG[i] = T(double(gx[i]) * scale);
        }
        mHavePrevious = true;
        return;
    }
    const double scale = std::ldexp(1.0, mScaleExponent), unscale = 1.0 / scale;

    // New column: dF = f_k - f_{k-1}, dG = G(x_k) - G(x_{k-1}); f_k and G(x_k) become "previous".
    mNewest = (mNewest + 1) % mDepth;
    mUsed = std::min(mUsed + 1, mDepth);
    const size_t slot = size_t(mNewest);
    T* dF = &mDeltaF[slot * n];
    T* dG = &mDeltaG[slot * n];
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const T f = T((double(gx[i]) - double(x[i])) * scale);
            const T g = T(double(gx[i]) * scale);
            dF[i] = f - mPreviousF[i];
            dG[i] = g - mPreviousG[i];
            mPreviousF[i] = f;
            mPreviousG[i] = g;
        }
    });

    // The new column's products with every column (a row of the Gram matrix), and every
    // column's product with f_k (the right-hand side).
    const size_t used = size_t(mUsed);
    std::vector<double> rhs(m, 0.0);
    gramRow(mDeltaF, dF, mPreviousF, n, m, used, slot, mGram, rhs);

    // The combination gamma of the kept columns that minimises |f_k - dF gamma|.
    std::vector<double> gamma;
    const std::vector<size_t> kept = leastSquares(mGram, rhs, m, slot, used, gamma);
    if (kept.empty()) return;
    const size_t K = kept.size();
    mCombined = int(K);

    // x_{k+1} = G(x_k) - dG gamma.
    std::atomic<bool> finite{true};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
        bool ok = true;
        for (size_t i = r.begin(); i != r.end(); ++i) {
            double v = double(gx[i]);
            for (size_t a = 0; a < K; ++a) {
                v -= gamma[a] * double(mDeltaG[kept[a] * n + i]) * unscale;
            }
            gx[i] = T(v);
            ok = ok && std::isfinite(gx[i]);
        }
        if (!ok) finite = false;
    });
    if (!finite) rejectLastStep(gx);
}

template<typename T>
void
AndersonMixerT<T>::rejectLastStep(T* gx)
{
    if (!mHavePrevious) return;
    const double unscale = std::ldexp(1.0, -mScaleExponent);
    for (size_t i = 0; i < mSize; ++i) gx[i] = T(double(mPreviousG[i]) * unscale);
    ++mRejected;
    // Keep G(x_k) and f_k as the start of the new history.
    mUsed = 0;
    mNewest = -1;
    mCombined = 0;
}

template class AndersonMixerT<float>;
template class AndersonMixerT<double>;

} // namespace vdbrad
