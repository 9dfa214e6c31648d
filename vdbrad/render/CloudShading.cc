#include "vdbrad/render/CloudShading.h"

#include "vdbrad/core/Constants.h"
#include "vdbrad/core/Errors.h"
#include "vdbrad/sweep/RealHarmonics.h"

#include <openvdb/Exceptions.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <atomic>
#include <cmath>
#include <limits>
#include <optional>

namespace vdbrad {

using openvdb::Coord;
using openvdb::Vec3d;
using openvdb::Vec3f;

namespace {
// A shadow ray whose transmittance falls below this carries no visible light.
constexpr double kShadowOpaque = 1e-7;

// Equal steps of at most @a step over @a length (index units), without the extra step that
// rounding would add where the length is a whole number of them (16/15 x 15 is a hair over 16).
int
stepsOver(double length, double step)
{
    return std::max(1, int(std::ceil(length / step * (1.0 - 1e-12))));
}
} // namespace

CloudShading::CloudShading(const Cloud& cloud, const openvdb::GridBase::ConstPtr& J,
    const openvdb::GridPtrVec& grids, double step, int maxOrder, const VoxelIndex* blockers,
    openvdb::util::NullInterrupter* interrupt)
    : mCloud(cloud), mStep(step)
{
    if (!(step > 0.0 && step <= 4.0)) {
        OPENVDB_THROW(openvdb::ValueError, "cloud march step must be in (0, 4] voxels, got "
            << step);
    }
    const size_t n = cloud.size();
    mBox = cloud.voxels().bbox();
    if (J) {
        mScattering = ScatteredSource::read(*J, grids);
        if (mScattering) {
            if (maxOrder >= 0 && maxOrder < mScattering->order) {
                mScattering->order = maxOrder;
                mScattering->moments.resize(size_t((maxOrder + 1) * (maxOrder + 1)));
            }
            for (const openvdb::GridBase::ConstPtr& g : mScattering->moments) {
                mMoments.push_back(Attribute::sample(*g, cloud.voxels(), g->getName(),
                    std::numeric_limits<float>::lowest()));
            }
        } else {
            mJ = Attribute::sample(*J, cloud.voxels(), J->getName(), 0.f);
        }
        mHasJ = true;
    }
    // Delta-M scaled extinction, per channel: the albedo sets how much of it the forward peak
    // takes back.
    const double f = mScattering ? mScattering->deltaM : 0.0;
    mSigma.resize(n);
    for (size_t i = 0; i < n; ++i) {
        const Vec3f a = cloud.albedo().rgb(i);
        const double s = cloud.extinction(i);
        for (int c = 0; c < 3; ++c) mSigma[i][c] = float(s * (1.0 - double(a[c]) * f));
    }
    mSunT.assign(n, Vec3f(1.f));
    if (mScattering && mScattering->sunIrradiance.length() > 0.0) traceShadows(blockers, interrupt);
}

// The fields at the eight voxel centres around a dual cell (the cube between them whose
// lowest corner is voxel `base`), in trilinear order (bit 0 x, bit 1 y, bit 2 z); absent
// voxels hold 0. Wrap: the horizontal axes of a periodic box wrap around.
template<bool Wrap>
bool
CloudShading::loadCell(Accessor& acc, const Coord& base, Cell& cell, bool emit) const
{
    bool any = false;
    const Coord dim = mBox.dim();
    for (int d = 0; d < 8; ++d) {
        Coord c = base.offsetBy(d & 1, (d >> 1) & 1, (d >> 2) & 1);
        if (Wrap) {
            for (int k = 0; k < 3; ++k) {
                if (k == mScattering->up) continue;
                const int32_t r = (c[k] - mBox.min()[k]) % dim[k];
                c[k] = mBox.min()[k] + (r < 0 ? r + dim[k] : r);
            }
        }
        const int32_t i = acc.getValue(c);
        if (i < 0) {
            cell.sigma[d] = cell.emit[d] = Vec3d(0.0);
            continue;
        }
        any = true;
        cell.sigma[d] = Vec3d(mSigma[size_t(i)]);
        cell.emit[d] = emit ? Vec3d(mEmit[size_t(i)]) : Vec3d(0.0);
    }
    return any;
}

namespace {

// Trilinear interpolation of the eight corner values @a v at local point w in [0, 1]^3.
Vec3d
trilinear(const Vec3d* v, const Vec3d& w)
{
    const Vec3d x0 = v[0] + (v[1] - v[0]) * w[0], x1 = v[2] + (v[3] - v[2]) * w[0];
    const Vec3d x2 = v[4] + (v[5] - v[4]) * w[0], x3 = v[6] + (v[7] - v[6]) * w[0];
    const Vec3d y0 = x0 + (x1 - x0) * w[1], y1 = x2 + (x3 - x2) * w[1];
    return y0 + (y1 - y0) * w[2];
}

// The two Gauss-Legendre points of [0, 1]: exact for cubics, and a trilinear field is a
// cubic along any line.
constexpr double kGaussLo = 0.5 - 0.28867513459481287, kGaussHi = 0.5 + 0.28867513459481287;

} // namespace

// Along p(t) = o + d t, t in [ta, tb], through the dual cells (a 3D DDA over the lattice of
// voxel centres): @a segment(cell, base, t0, t1) for each piece of the ray inside a cell whose
// corners are not all empty (@a empty: every cell), in order, until it returns false.
template<bool Wrap, typename SegmentF>
void
CloudShading::walk(Accessor& acc, const Vec3d& o, const Vec3d& d, double ta, double tb,
    bool emit, bool empty, SegmentF&& segment) const
{
    if (!(tb > ta)) return;
    const Vec3d start = o + d * ta;
    Coord base;
    double tNext[3], tStep[3];
    int step[3];
    for (int k = 0; k < 3; ++k) {
        base[k] = int32_t(std::floor(start[k]));
        // A start on a cell face going down belongs to the cell below.
        if (double(base[k]) == start[k] && d[k] < 0.0) --base[k];
        if (d[k] > 0.0) {
            step[k] = 1;
            tNext[k] = ta + (double(base[k]) + 1.0 - start[k]) / d[k];
            tStep[k] = 1.0 / d[k];
        } else if (d[k] < 0.0) {
            step[k] = -1;
            tNext[k] = ta + (double(base[k]) - start[k]) / d[k];
            tStep[k] = -1.0 / d[k];
        } else {
            step[k] = 0;
            tNext[k] = tStep[k] = std::numeric_limits<double>::infinity();
        }
    }
    Cell cell;
    double t = ta;
    while (t < tb) {
        const int k = tNext[0] < tNext[1] ? (tNext[0] < tNext[2] ? 0 : 2)
                                          : (tNext[1] < tNext[2] ? 1 : 2);
        const double t1 = std::min(tNext[k], tb);
        if (t1 > t && (loadCell<Wrap>(acc, base, cell, emit) || empty)) {
            if (!segment(cell, base, t, t1)) return;
        }
        t = t1;
        base[k] += step[k];
        tNext[k] += tStep[k];
    }
}

// From each voxel centre towards the sun, in index space, through the trilinear extinction:
// midpoint steps until the ray leaves the box's trilinear support (a periodic box: through
// its top only).
void
CloudShading::traceShadows(const VoxelIndex* blockers, openvdb::util::NullInterrupter* interrupt)
{
    const ScatteredSource& s = *mScattering;
    const Vec3d dir = s.toSun;
    const double h = mCloud.voxelSize();   // world units per index unit (the cloud's voxels
                                           // are cubes: Cloud.h)
    // The ray ends where it leaves the medium's trilinear support, or the blockers' cubes.
    openvdb::CoordBBox box = mBox;
    if (blockers && blockers->size() > 0) box.expand(blockers->bbox());
    const Vec3d lo = box.min().asVec3d() - Vec3d(1.0), hi = box.max().asVec3d() + Vec3d(1.0);
    std::atomic<bool> stop{false};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, mCloud.size()),
        [&](const tbb::blocked_range<size_t>& r) {
            if (stop) return;
            if (openvdb::util::wasInterrupted(interrupt)) { stop = true; return; }
            Accessor acc(mCloud.voxels().tree());
            std::optional<Accessor> block;
            if (blockers) block.emplace(blockers->tree());
            // A blocker's cube at index point p (voxel cubes are centred on integers).
            auto blocked = [&](const Vec3d& p) {
                return block && block->getValue(Coord{int32_t(std::floor(p[0] + 0.5)),
                    int32_t(std::floor(p[1] + 0.5)), int32_t(std::floor(p[2] + 0.5))}) >= 0;
            };
            for (size_t i = r.begin(); i != r.end(); ++i) {
                const Vec3d o = mCloud.voxels().coord(i).asVec3d();
                // Where the ray leaves the support: along the axes it can leave by.
                double tMax = std::numeric_limits<double>::max();
                for (int k = 0; k < 3; ++k) {
                    if (s.periodic && k != s.up) continue;
                    if (dir[k] > 0.0) tMax = std::min(tMax, (hi[k] - o[k]) / dir[k]);
                    else if (dir[k] < 0.0) tMax = std::min(tMax, (lo[k] - o[k]) / dir[k]);
                }
                // Each cell's piece: the exact optical depth of the trilinear field.
                Vec3d depth(0.0);
                auto add = [&](const Cell& cell, const Coord& base, double t0, double t1) {
                    const Vec3d b = base.asVec3d();
                    const Vec3d p0 = o + dir * (t0 + (t1 - t0) * kGaussLo);
                    const Vec3d p1 = o + dir * (t0 + (t1 - t0) * kGaussHi);
                    if (blocked(p0) || blocked(p1)) {
                        depth = Vec3d(std::numeric_limits<double>::infinity());
                        return false;
                    }
                    const Vec3d s0 = trilinear(cell.sigma, p0 - b);
                    const Vec3d s1 = trilinear(cell.sigma, p1 - b);
                    depth += (s0 + s1) * (0.5 * (t1 - t0) * h);
                    return std::min({depth[0], depth[1], depth[2]}) < -std::log(kShadowOpaque);
                };
                // With blockers every cell is visited (one may lie where the medium is not).
                if (s.periodic) walk<true>(acc, o, dir, 0.0, tMax, false, bool(block), add);
                else walk<false>(acc, o, dir, 0.0, tMax, false, bool(block), add);
                for (int c = 0; c < 3; ++c) mSunT[i][c] = float(std::exp(-depth[c]));
            }
        });
    if (stop || openvdb::util::wasInterrupted(interrupt)) throw Cancelled("cloud shadows");
}

void
CloudShading::aim(const Vec3d& eye, openvdb::util::NullInterrupter* interrupt)
{
    const size_t n = mCloud.size();
    mEmit.assign(n, Vec3f(0.f));
    const Vec3d eyeIndex = mCloud.transform().worldToIndex(eye);
    const Attribute& albedo = mCloud.albedo();
    const Attribute& emission = mCloud.emission();
    const int K = mScattering ? mScattering->order : 0;
    const double f = mScattering ? mScattering->deltaM : 0.0;
    const Vec3d F = mScattering ? mScattering->sunIrradiance : Vec3d(0.0);
    const bool sun = F.length() > 0.0;
    std::atomic<bool> stop{false};
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
        if (stop) return;
        if (openvdb::util::wasInterrupted(interrupt)) { stop = true; return; }
        std::vector<double> y(size_t((K + 1) * (K + 1)));
        for (size_t i = r.begin(); i != r.end(); ++i) {
            const Vec3f a = albedo.rgb(i);
            Vec3d S(0.0);   // per unit of scaled extinction, radiance
            if (mScattering) {
                // The direction of travel towards the eye.
                Vec3d s = eyeIndex - mCloud.voxels().coord(i).asVec3d();
                const double len = s.length();
                s = len > 0.0 ? s / len : Vec3d(0.0, 0.0, 1.0);
                realSphericalHarmonics(K, s, y.data());
                for (size_t k = 0; k < y.size(); ++k) S += Vec3d(mMoments[k].rgb(i)) * y[k];
                if (sun) {
                    const double p = mScattering->phase.value(-mScattering->toSun.dot(s));
                    for (int c = 0; c < 3; ++c) {
                        const double w = a[c], scaled = 1.0 - w * f;
                        if (scaled > 0.0) {
                            S[c] += w / scaled * p * F[c] * double(mSunT[i][c]) / (4.0 * kPi);
                        }
                    }
                }
            } else if (mHasJ) {
                const Vec3f J = mJ.rgb(i);
                for (int c = 0; c < 3; ++c) S[c] = double(a[c]) * double(J[c]);
            }
            // The medium emits through its extinction (Cloud.h): none where it has none.
            const Vec3f e = mCloud.extinction(i) > 0.f ? emission.rgb(i) : Vec3f(0.f);
            for (int c = 0; c < 3; ++c) {
                // A truncated harmonic series may dip below 0 where the light is faint.
                const double j = double(mSigma[i][c]) * S[c] + double(e[c]);
                mEmit[i][c] = float(kPi * std::max(0.0, j));
            }
        }
    });
    if (stop || openvdb::util::wasInterrupted(interrupt)) throw Cancelled("cloud source");
    mEmits = std::any_of(mEmit.begin(), mEmit.end(),
        [](const Vec3f& v) { return v[0] > 0.f || v[1] > 0.f || v[2] > 0.f; });
}

void
CloudShading::march(Accessor& acc, const Vec3d& eye, const Vec3d& dir, double t0, double t1,
    Vec3d& L, Vec3d& T, double opaque) const
{
    const Vec3d o = mCloud.transform().worldToIndex(eye);
    const Vec3d d = mCloud.transform().baseMap()->applyInverseJacobian(dir);
    // Clip to the trilinear fields' support, the voxel centres' box grown by one.
    const Vec3d lo = mBox.min().asVec3d() - Vec3d(1.0), hi = mBox.max().asVec3d() + Vec3d(1.0);
    double ta = t0, tb = t1;
    for (int k = 0; k < 3; ++k) {
        if (d[k] == 0.0) {
            if (o[k] < lo[k] || o[k] > hi[k]) return;
            continue;
        }
        double a = (lo[k] - o[k]) / d[k], b = (hi[k] - o[k]) / d[k];
        if (a > b) std::swap(a, b);
        ta = std::max(ta, a);
        tb = std::min(tb, b);
    }
    if (!(tb > ta)) return;
    // Each cell's piece in steps of at most mStep voxels: per step, the optical depth and the
    // mean emission density exactly (two Gauss points: the fields are cubic along the ray),
    // and the exact exponential for a source constant over the step.
    const double perWorld = d.length();   // index units per world unit
    walk<false>(acc, o, d, ta, tb, mEmits, false,
        [&](const Cell& cell, const Coord& base, double t0, double t1) {
            const Vec3d b = base.asVec3d();
            const int steps = stepsOver((t1 - t0) * perWorld, mStep);
            const double dt = (t1 - t0) / steps;
            for (int k = 0; k < steps; ++k) {
                const double a = t0 + double(k) * dt;
                const Vec3d p0 = o + d * (a + dt * kGaussLo) - b;
                const Vec3d p1 = o + d * (a + dt * kGaussHi) - b;
                const Vec3d sigma = (trilinear(cell.sigma, p0) + trilinear(cell.sigma, p1)) * 0.5;
                const Vec3d j = mEmits
                    ? (trilinear(cell.emit, p0) + trilinear(cell.emit, p1)) * 0.5 : Vec3d(0.0);
                for (int c = 0; c < 3; ++c) {
                    const double x = sigma[c] * dt;
                    if (mEmits) {
                        // j / sigma (1 - e^-x), which tends to j dt where the medium is thin.
                        L[c] += T[c] * (x > 1e-12 ? j[c] / sigma[c] * -std::expm1(-x) : j[c] * dt);
                    }
                    T[c] *= std::exp(-x);
                }
                if (std::max({T[0], T[1], T[2]}) < opaque) return false;
            }
            return true;
        });
}

} // namespace vdbrad
