#include "vdbrad/cloud/DiffusionAcceleration.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <cmath>

namespace vdbrad {

namespace {

// Sums over fixed blocks of unknowns, added in block order: the same bits for any thread count.
constexpr size_t kBlock = 4096;

// N sums at once: @a partial returns a block's N partial sums.
template<size_t N, typename F>
std::array<double, N>
blockSums(size_t size, const F& partial)
{
    const size_t blocks = (size + kBlock - 1) / kBlock;
    std::vector<std::array<double, N>> sums(blocks);
    using Range = tbb::blocked_range<size_t>;
    tbb::parallel_for(Range(0, blocks), [&](const Range& r) {
        for (size_t b = r.begin(); b != r.end(); ++b) {
            sums[b] = partial(b * kBlock, std::min(size, (b + 1) * kBlock));
        }
    });
    std::array<double, N> total{};
    for (const auto& s : sums) {
        for (size_t k = 0; k < N; ++k) total[k] += s[k];
    }
    return total;
}

template<typename F>
double
blockSum(size_t size, const F& partial)
{
    return blockSums<1>(size, [&](size_t begin, size_t end) {
        return std::array<double, 1>{partial(begin, end)};
    })[0];
}

} // namespace

DiffusionAcceleration::DiffusionAcceleration(const VoxelIndex& voxels,
    const std::vector<float>& kappa, const std::vector<float>& omega,
    const std::vector<double>& escape, double chi1, const std::vector<float>& wall,
    const std::optional<openvdb::CoordBBox>& period, int up)
    : mVoxels(voxels.size())
{
    const size_t n = voxels.size();
    // The unknowns and each one's half-voxel conductance (see the file comment).
    std::vector<uint32_t> unknown(n, kNone);
    std::vector<double> half;
    // Faces across which something varies: a periodic box one voxel deep along a horizontal
    // axis has none there. The escape-limited conductance shares X_v among the others.
    double faces = kFaces;
    if (period) {
        for (int axis = 0; axis < 3; ++axis) {
            if (axis != up && period->dim()[axis] == 1) faces -= 2.0;
        }
    }
    for (size_t v = 0; v < n; ++v) {
        const double k = kappa[v], m = escape[v];
        if (!(wall[v] == kMedium && k > 0.0 && std::isfinite(k) && m > 0.0)) continue;
        unknown[v] = uint32_t(mVoxel.size());
        mVoxel.push_back(uint32_t(v));
        const double transport = std::max(k, kMinDepth)
            * std::max(1.0 - double(omega[v]) * chi1, 1e-3);
        const double escaping = m < 1.0 ? k * m / (1.0 - m) : 0.0;
        half.push_back(std::max(2.0 / (3.0 * transport), escaping * 2.0 / faces));
    }
    const size_t count = mVoxel.size();
    mNeighbour.assign(count * kFaces, kNone);
    mCoupling.assign(count * kFaces, 0.0);
    mDiagonal.resize(count);
    mSource.resize(count);
    using Range = tbb::blocked_range<size_t>;
    tbb::parallel_for(Range(0, count), [&](const Range& r) {
        VoxelIndex::Accessor acc(voxels.tree());
        for (size_t u = r.begin(); u != r.end(); ++u) {
            const uint32_t v = mVoxel[u];
            const openvdb::Coord c = voxels.coord(v);
            double diagonal = double(kappa[v]) * (1.0 - double(omega[v]));
            for (int f = 0; f < kFaces; ++f) {
                const int axis = f / 2;
                openvdb::Coord next = c;
                next[axis] += f % 2 ? 1 : -1;
                if (period && axis != up) {
                    if (next[axis] > period->max()[axis]) next[axis] = period->min()[axis];
                    if (next[axis] < period->min()[axis]) next[axis] = period->max()[axis];
                    if (next == c) continue;   // one voxel deep: nothing varies along it
                }
                const int32_t i = acc.getValue(next);
                if (i >= 0 && unknown[size_t(i)] != kNone) {
                    const double a = half[u], b = half[unknown[size_t(i)]];
                    const double coupling = a * b / (a + b);
                    mNeighbour[u * kFaces + size_t(f)] = unknown[size_t(i)];
                    mCoupling[u * kFaces + size_t(f)] = coupling;
                    diagonal += coupling;
                    continue;
                }
                // A wall, or nothing (a vacuum): Marshak's condition. Walls reflect at most 0.99
                // here, so that no group of voxels is sealed in (a singular system).
                const float w = i >= 0 ? wall[size_t(i)] : -1.f;
                const double rho = w >= 0.f && w != kMedium ? std::min(double(w), 0.99) : 0.0;
                diagonal += 1.0 / (1.0 / half[u] + 2.0 * (1.0 + rho) / (1.0 - rho));
            }
            mDiagonal[u] = diagonal;
            mSource[u] = double(kappa[v]) * double(omega[v]);
        }
    });
}

int
DiffusionAcceleration::correct(const std::vector<double>& residual,
    std::vector<double>& delta) const
{
    const size_t count = mVoxel.size();
    delta.assign(mVoxels, 0.0);
    std::vector<double> x(count, 0.0), r(count), z(count), p(count), q(count);
    // r.r and r.z in one pass (each block's two sums in the order of two passes: the same bits).
    const auto first = blockSums<2>(count, [&](size_t begin, size_t end) {
        std::array<double, 2> s{};
        for (size_t u = begin; u < end; ++u) {
            r[u] = mSource[u] * residual[mVoxel[u]];
            z[u] = r[u] / mDiagonal[u];
            p[u] = z[u];
            s[0] += r[u] * r[u];
            s[1] += r[u] * z[u];
        }
        return s;
    });
    const double bb = first[0];
    if (!(bb > 0.0) || !std::isfinite(bb)) return 0;
    double rz = first[1];
    int it = 0;
    while (it < kMaxIterations) {
        ++it;
        const double pq = blockSum(count, [&](size_t begin, size_t end) {
            double s = 0.0;
            for (size_t u = begin; u < end; ++u) {
                double a = mDiagonal[u] * p[u];
                for (int f = 0; f < kFaces; ++f) {
                    const uint32_t j = mNeighbour[u * kFaces + size_t(f)];
                    if (j != kNone) a -= mCoupling[u * kFaces + size_t(f)] * p[j];
                }
                q[u] = a;
                s += p[u] * a;
            }
            return s;
        });
        if (!(pq > 0.0)) break;
        const double alpha = rz / pq;
        const auto next = blockSums<2>(count, [&](size_t begin, size_t end) {
            std::array<double, 2> s{};
            for (size_t u = begin; u < end; ++u) {
                x[u] += alpha * p[u];
                r[u] -= alpha * q[u];
                z[u] = r[u] / mDiagonal[u];
                s[0] += r[u] * z[u];
                s[1] += r[u] * r[u];
            }
            return s;
        });
        const double rzNext = next[0], rr = next[1];
        if (rr <= kTolerance * kTolerance * bb) break;
        const double beta = rzNext / rz;
        rz = rzNext;
        using Range = tbb::blocked_range<size_t>;
        tbb::parallel_for(Range(0, count), [&](const Range& b) {
            for (size_t u = b.begin(); u != b.end(); ++u) p[u] = z[u] + beta * p[u];
        });
    }
    for (size_t u = 0; u < count; ++u) delta[mVoxel[u]] = x[u];
    return it;
}

size_t
DiffusionAcceleration::bytes(size_t voxels)
{
    // Held: the unknown's voxel, six neighbours and couplings, diagonal, source; correcting:
    // five vectors of the unknowns and the voxels' delta (the caller's residual besides).
    return voxels * (4 + kFaces * (4 + 8) + 8 + 8) + voxels * (5 * 8 + 8) + voxels * (4 + 8);
}

} // namespace vdbrad
