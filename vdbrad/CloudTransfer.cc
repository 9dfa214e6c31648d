#include "vdbrad/CloudTransfer.h"

#include "vdbrad/Denormals.h"
#include "vdbrad/Errors.h"
#include "vdbrad/LeafOrder.h"
#include "vdbrad/LinePartition.h"
#include "vdbrad/LineSweep.h"
#include "vdbrad/OutputGrids.h"
#include "vdbrad/PhaseFunction.h"
#include "vdbrad/SolarBeam.h"
#include "vdbrad/Version.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>

namespace vdbrad {

namespace {

using openvdb::Coord;
using openvdb::Vec3d;

constexpr double kPi = 3.14159265358979323846;
// Periodic boundaries: wrap-around passes per direction and iteration before the rest of the
// wrapping light is carried over to the next iteration.
constexpr int kMaxWraps = 64;

// Across a step of optical depth tau: the absorbed fraction 1 - e^-tau and the mean factor
// (1 - e^-tau) / tau, with one exponential, and without cancellation for thin voxels. The
// radiance is updated as L += (S - L) (1 - e^-tau) rather than S + (L - S) e^-tau: at tau = 1e-8
// e^-tau rounds to 1 in float and the latter would lose all the light a thin voxel adds.
inline void
stepFactors(float tau, float& absorb, float& mean)
{
    if (tau > 1e-3f) {
        const double e = std::exp(-double(tau));
        absorb = float(1.0 - e);
        mean = float((1.0 - e) / double(tau));
    } else {
        // Series to tau^3: relative error below 1e-12 here.
        absorb = tau * (1.f - 0.5f * tau * (1.f - tau / 3.f));
        mean = 1.f - 0.5f * tau * (1.f - tau / 3.f * (1.f - 0.25f * tau));
    }
}

// What a line carries: its radiance, whether it has met its first voxel yet (periodic boundaries
// give that voxel the light re-entering the box) and the last voxel it met (where it leaves).
struct Ray
{
    float radiance = 0.f;
    bool started = false;
    uint32_t last = 0;
};

// The side face a ray through index point p along unit t crosses first going backwards (-t)
// (entering) or forwards (+t) (leaving), over the box [lo, hi]: 2 * axis + (0: low, 1: high), or
// -1 if it is the top or bottom; and the up coordinate of the crossing.
int
crossedSide(const Vec3d& p, const Vec3d& t, const Vec3d& lo, const Vec3d& hi, int up,
    double& height)
{
    double best = 1e300;
    int face = -1;
    for (int k = 0; k < 3; ++k) {
        if (t[k] == 0.0) continue;
        const double bound = t[k] > 0.0 ? hi[k] : lo[k];
        const double s = (bound - p[k]) / t[k];
        if (s < best) {
            best = s;
            face = 2 * k + (t[k] > 0.0 ? 1 : 0);
        }
    }
    height = p[up] + best * t[up];
    return face / 2 == up ? -1 : face;
}

// A naive line of direction sigma advances one voxel per step along its major axis: the step is
// |sigma| / max_k |sigma_k| voxels long (float: the sweeps' and the self-scattering factors'
// optical depths must be the same numbers).
inline float
stepLength(const Coord& sigma)
{
    const int major = std::abs(sigma.x()) >= std::abs(sigma.y())
        ? (std::abs(sigma.x()) >= std::abs(sigma.z()) ? 0 : 2)
        : (std::abs(sigma.y()) >= std::abs(sigma.z()) ? 1 : 2);
    return float(sigma.asVec3d().length() / std::abs(sigma[major]));
}

} // namespace

struct CloudTransfer::Impl
{
    static constexpr int kGroups = 8;   // fixed: results do not depend on the thread count

    size_t n = 0;
    // A narrow periodic box is solved as copies side by side (periodicCopies()): that medium,
    // and per voxel of it, the voxel of the given cloud it copies. Null: the cloud as given.
    std::unique_ptr<Cloud> tiled;
    std::vector<uint32_t> copyOf;
    std::vector<float> kappa;        // optical depth per voxel length
    std::vector<float> omega;        // single-scattering albedo
    std::vector<float> beamJ;        // mean radiance of the direct beam, D / (4 pi kappa)
    std::vector<double> deposited;   // beam power lost per voxel
    double incident = 0.0, directOut = 0.0;   // at the internal irradiance (see outputScale)
    double outputScale = 1.0;        // F0 / the internal irradiance: a power of two
    std::vector<float> diffuseJ;     // diffuse mean radiance of the last sweep
    // Mean escape factor M_v per voxel: Y_00^2 sum_{directions, senses} Omega f(tau), from the
    // sweeps' own float factors; 1 - omega0 (1 - M_v) is what iterate() divides I_00 by.
    std::vector<double> escape;
    // Anisotropic scattering: M = (K + 1)^2 radiance moments per voxel (M = 1: isotropic).
    int M = 1;
    std::vector<double> chi;         // delta-M scaled Legendre coefficients, l = 0..K
    std::vector<float> moments;      // diffuse I_lm per voxel (n x M), from the last sweep
    std::unique_ptr<AndersonMixer> mixer;   // Acceleration::Anderson only
    // First scattering of the beam, per direction and sense: the full phase function (not its
    // truncation) divided by 1 - f, less the forward fraction f delta-M keeps in the beam, taken
    // from the directions closest to the beam's, so that sum_s Omega_s T_s = 4 pi exactly. A
    // voxel's source is then omega0' J_beam T_s (DISORT's TMS idea, applied to the source).
    std::vector<float> beamTable;
    // Per direction and sense (2 d + sense), Y_lm of the direction of travel: moments are
    // accumulated and sources evaluated with them.
    std::vector<float> yAccumulate;
    // Mean of Y_lm over the direction set (its solid-angle weights integrate high orders only
    // roughly: Y_00 exactly, order 8 a few per cent off).
    std::vector<double> quadratureMean;

    struct Pattern
    {
        std::vector<size_t> directions;
        std::vector<uint32_t> order;     // voxel index of the k-th visited voxel
        std::vector<float> kappa;        // in visiting order
        std::unique_ptr<LineSweep> sweep;
    };
    std::array<Pattern, 4> patterns;
    std::vector<char> reversed;

    // Periodic boundaries, per direction and sense: power that left each side face per voxel
    // layer in the last sweep, and how many lines enter through each side face per layer.
    Vec3d lo, hi;
    Coord boxMin, boxMax;
    int layers = 0, layer0 = 0;
    int up = 1;
    std::vector<double> leftFace;    // [dir][sense][face 0..5][layer]: power carried over
    std::vector<uint32_t> enterCount;
    size_t faceIndex(size_t dir, int sense, int face, int layer) const
    {
        return ((dir * 2 + size_t(sense)) * 6 + size_t(face)) * size_t(layers) + size_t(layer);
    }
    int layerOf(double height) const
    {
        return std::clamp(int(std::floor(height + 0.5)) - layer0, 0, layers - 1);
    }
    // Slot (within a direction's slice) of the side face and layer a line whose first voxel is
    // at p enters through, light travelling along t; -1: it enters through the top or bottom.
    int entrySlot(const Vec3d& p, const Vec3d& t, bool forward) const
    {
        double height = 0.0;
        const int face = crossedSide(p, -t, lo, hi, up, height);
        return face < 0 ? -1 : ((forward ? 0 : 1) * 6 + face) * layers + layerOf(height);
    }
    // Likewise for the face a line whose last voxel is at p leaves through.
    int exitSlot(const Vec3d& p, const Vec3d& t, bool forward) const
    {
        double height = 0.0;
        const int face = crossedSide(p, t, lo, hi, up, height);
        return face < 0 ? -1 : ((forward ? 0 : 1) * 6 + face) * layers + layerOf(height);
    }
    // Slot of the side face and layer that the digital step from voxel a (in the box) to its
    // neighbour b on the line (outside) crosses: the step's midpoint height, so that the light
    // leaving one face and the lines entering the opposite one are matched without a bias (a
    // voxel centre can lie up to 1/2 voxel off the line's axis, which projected along a steep
    // direction moved light several layers down per wrap). -1: b is above or below the box.
    int stepSlot(const Coord& a, const Coord& b, bool forward) const
    {
        if (b[up] < boxMin[up] || b[up] > boxMax[up]) return -1;
        int face = -1;
        for (int k = 0; k < 3 && face < 0; ++k) {
            if (k == up) continue;
            if (b[k] > boxMax[k]) face = 2 * k + 1;
            else if (b[k] < boxMin[k]) face = 2 * k;
        }
        if (face < 0) return -2;   // b is inside the box (a sparse medium): no face here
        return ((forward ? 0 : 1) * 6 + face) * layers + layerOf(0.5 * (a[up] + b[up]));
    }
    // Slots where the line whose first voxel is `first` enters, and where the line whose last
    // voxel is `last` leaves, travelling along t (the pass's sense); by the digital step where
    // there is one, else by projecting the voxel centre.
    int entering(const LinePartition& part, const Coord& sigma, const Coord& first, const Vec3d& t,
        bool forward) const
    {
        Coord prev;
        if (stepAlong(part, sigma, first, forward ? -1 : 1, prev)) {
            const int slot = stepSlot(first, prev, forward);
            if (slot != -2) return slot;
        }
        return entrySlot(first.asVec3d(), t, forward);
    }
    int leaving(const LinePartition& part, const Coord& sigma, const Coord& last, const Vec3d& t,
        bool forward) const
    {
        Coord next;
        if (stepAlong(part, sigma, last, forward ? 1 : -1, next)) {
            const int slot = stepSlot(last, next, forward);
            if (slot != -2) return slot;
        }
        return exitSlot(last.asVec3d(), t, forward);
    }
    // The neighbour of c on its line, one step along +sigma (dir 1) or -sigma (dir -1): a naive
    // line has one voxel per major coordinate, so it is one of four candidates. Returns false
    // where the line has no voxel there (a centred partition's central line at its bound).
    static bool stepAlong(const LinePartition& part, const Coord& sigma, const Coord& c, int dir,
        Coord& out)
    {
        const int major = part.majorAxis();
        const LineKey key = part.key(c);
        Coord base = c;
        base[major] += dir * (sigma[major] > 0 ? 1 : -1);
        int minor[2], n = 0;
        for (int k = 0; k < 3; ++k) if (k != major) minor[n++] = k;
        for (int d1 = 0; d1 < 2; ++d1) {
            if (d1 && sigma[minor[0]] == 0) continue;
            for (int d2 = 0; d2 < 2; ++d2) {
                if (d2 && sigma[minor[1]] == 0) continue;
                Coord q = base;
                q[minor[0]] += dir * d1 * (sigma[minor[0]] > 0 ? 1 : -1);
                q[minor[1]] += dir * d2 * (sigma[minor[1]] > 0 ? 1 : -1);
                if (part.key(q) == key) { out = q; return true; }
            }
        }
        return false;
    }
    // The slot light leaving through slot e re-enters by: the opposite face, same sense, layer.
    size_t oppositeSlot(size_t e) const
    {
        const size_t layer = e % size_t(layers), sf = e / size_t(layers);
        return ((sf / 6) * 6 + ((sf % 6) ^ 1)) * size_t(layers) + layer;
    }

    // Directions of group g: pattern g / 2, every other one.
    template<typename F>
    void forDirections(int g, F&& f) const
    {
        const Pattern& p = patterns[size_t(g / 2)];
        for (size_t i = size_t(g % 2); i < p.directions.size(); i += 2) f(p.directions[i]);
    }
};

CloudTransfer::CloudTransfer(const Cloud& given, const CloudTransferOptions& options,
    openvdb::util::NullInterrupter* interrupt)
    : mCloud(given), mOptions(options), mImpl(new Impl)
{
    const auto start = std::chrono::steady_clock::now();
    if (options.maxIterations < 1) {
        OPENVDB_THROW(openvdb::ValueError, "iterations must be >= 1, got " << options.maxIterations);
    }
    if (!(options.tolerance >= 0.0)) OPENVDB_THROW(openvdb::ValueError, "tolerance must be >= 0");
    if (!(options.sunZenith >= 0.0 && options.sunZenith <= 89.9)) {
        OPENVDB_THROW(openvdb::ValueError, "sun zenith angle must be in [0, 89.9] degrees, got "
            << options.sunZenith);
    }
    if (!std::isfinite(options.sunAzimuth)) {
        OPENVDB_THROW(openvdb::ValueError, "sun azimuth must be finite");
    }
    if (options.up < 0 || options.up > 2) OPENVDB_THROW(openvdb::ValueError, "up must be 0, 1 or 2");
    if (options.accelerate == Acceleration::Anderson && options.andersonDepth < 1) {
        OPENVDB_THROW(openvdb::ValueError, "Anderson depth must be >= 1, got "
            << options.andersonDepth);
    }
    if (options.minPeriod < -1) {
        OPENVDB_THROW(openvdb::ValueError, "minimum period must be >= 0 voxels (or -1: auto), got "
            << options.minPeriod);
    }
    if (given.albedo().isRgb()) {
        OPENVDB_THROW(openvdb::ValueError, "RGB single-scattering albedo is not supported yet; "
            "give a float albedo grid");
    }
    mDirections = DirectionSet::fromCount(options.directions);
    Impl& impl = *mImpl;
    mCopies = copiesFor(given, options, mDirections.size());
    if (mCopies != Coord(1)) impl.tiled.reset(new Cloud(tileCloud(given, mCopies, &impl.copyOf)));
    // From here on, the medium solved.
    const Cloud& cloud = impl.tiled ? *impl.tiled : given;
    const size_t n = impl.n = cloud.size();
    const double h = cloud.voxelSize();
    impl.kappa.resize(n);
    impl.omega.resize(n);
    for (size_t i = 0; i < n; ++i) {
        const double k = double(cloud.extinction(i)) * h;
        if (!std::isfinite(k)) {
            OPENVDB_THROW(openvdb::ValueError, "voxel optical depth overflows (extinction "
                << cloud.extinction(i) << " per unit, voxel size " << h << ")");
        }
        impl.kappa[i] = float(k);
        impl.omega[i] = cloud.albedo().grey(i);
    }
    // Phase function: order K and delta-M scaling of extinction and albedo.
    const int order = options.phase.isIsotropic() ? 0 : options.phaseOrder;
    const PhaseFunction::Truncated trunc = options.phase.truncate(order);
    impl.chi = trunc.chi;
    impl.M = (order + 1) * (order + 1);
    if (trunc.f > 0.0) {
        for (size_t i = 0; i < n; ++i) {
            const double w = impl.omega[i], scaled = 1.0 - w * trunc.f;
            impl.kappa[i] = float(impl.kappa[i] * scaled);
            impl.omega[i] = scaled > 0.0 ? float(w * (1.0 - trunc.f) / scaled) : 0.f;
        }
    }

    // The sun, in index space (the transform is a uniform scale plus rotation: world
    // directions map to index directions by the inverse Jacobian).
    const int up = options.up, a1 = (up + 1) % 3, a2 = (up + 2) % 3;
    // Horizontal axes in the documented order: up y -> (x, z), up z -> (x, y), up x -> (y, z).
    const int first = std::min(a1, a2), second = std::max(a1, a2);
    const double zen = options.sunZenith * kPi / 180.0, az = options.sunAzimuth * kPi / 180.0;
    Vec3d toSunWorld(0.0);
    toSunWorld[up] = std::cos(zen);
    toSunWorld[first] = std::sin(zen) * std::cos(az);
    toSunWorld[second] = std::sin(zen) * std::sin(az);
    const Vec3d toSun = cloud.transform().baseMap()->applyInverseJacobian(toSunWorld);
    if (interrupt) interrupt->start("solar beam");
    // The transfer runs at the irradiance divided by a power of two that brings it to [0.5, 1),
    // and intensities are multiplied back on output (both exact): flush-to-zero (Denormals.h)
    // then cuts at the same relative level for any F0, and F0 = 2^k F gives 2^k times the bits.
    int exponent = 0;
    if (options.irradiance > 0.0 && std::isfinite(options.irradiance)) {
        std::frexp(options.irradiance, &exponent);
    }
    impl.outputScale = std::ldexp(1.0, exponent);
    SolarBeamResult beam = traceSolarBeam(cloud.voxels(), impl.kappa, toSun, up, options.periodic,
        options.beamRaysPerVoxel, options.irradiance / impl.outputScale, interrupt);
    if (interrupt) interrupt->end();
    impl.incident = beam.incident;
    impl.directOut = beam.transmitted;
    impl.deposited = std::move(beam.deposited);
    impl.beamJ.resize(n);
    for (size_t i = 0; i < n; ++i) {
        impl.beamJ[i] = impl.kappa[i] > 0.f
            ? float(impl.deposited[i] / (4.0 * kPi * double(impl.kappa[i]))) : 0.f;
    }
    impl.diffuseJ.assign(n, 0.f);
    impl.moments.assign(n * size_t(impl.M), 0.f);
    {
        const size_t M = size_t(impl.M), dirs = mDirections.size();
        std::vector<double> y(M);
        impl.yAccumulate.resize(dirs * 2 * M);
        std::vector<double> mean(M, 0.0);
        for (size_t d = 0; d < dirs; ++d) {
            const double omega = kPi * mDirections.factor(d);
            for (int sense = 0; sense < 2; ++sense) {
                realSphericalHarmonics(order, sense == 0 ? mDirections.unit(d) : -mDirections.unit(d),
                    y.data());
                for (size_t lm = 0; lm < M; ++lm) {
                    impl.yAccumulate[(2 * d + size_t(sense)) * M + lm] = float(y[lm]);
                    mean[lm] += omega * y[lm] / (4.0 * kPi);
                }
            }
        }
        impl.quadratureMean = mean;

        const Vec3d beam = (-toSun).unit();
        std::vector<double> weight(dirs * 2);
        std::vector<std::pair<double, size_t>> byAngle(dirs * 2);
        for (size_t e = 0; e < dirs * 2; ++e) {
            const Vec3d s = (e % 2 == 0 ? 1.0 : -1.0) * mDirections.unit(e / 2);
            const double mu = std::clamp(s.dot(beam), -1.0, 1.0);
            weight[e] = kPi * mDirections.factor(e / 2) * options.phase.value(mu)
                / (4.0 * kPi * (1.0 - trunc.f));
            byAngle[e] = {-mu, e};
        }
        std::sort(byAngle.begin(), byAngle.end());
        // The sampled weights add up to about 1 + f / (1 - f): the forward part delta-M keeps
        // in the beam, plus the quadrature error of the sharp forward peak. Both live in the
        // forward cone, so the directions closest to the beam absorb the difference to exactly
        // 1, and the side and backward weights stay the phase function's own.
        double excess = -1.0;
        for (double w : weight) excess += w;
        for (const auto& [negMu, e] : byAngle) {
            if (excess <= 0.0) break;
            const double take = std::min(excess, weight[e]);
            weight[e] -= take;
            excess -= take;
        }
        if (excess < 0.0) weight[byAngle.front().second] -= excess;
        const double total = 1.0;
        impl.beamTable.resize(dirs * 2);
        for (size_t e = 0; e < dirs * 2; ++e) {
            impl.beamTable[e] = float(4.0 * kPi * weight[e] / total
                / (kPi * mDirections.factor(e / 2)));
        }
    }

    // Sweep orders: one per base sign pattern, naive lines (their steps have exact lengths).
    const size_t dirs = mDirections.size();
    LeafOrder::Patterns dealt = LeafOrder::patterns(dirs,
        [&](size_t k) { return mDirections.direction(k); });
    impl.reversed = std::move(dealt.reversed);
    for (size_t p = 0; p < 4; ++p) {
        Impl::Pattern& pattern = impl.patterns[p];
        pattern.directions = std::move(dealt.directions[p]);
        if (pattern.directions.empty()) continue;
        const LeafOrder order(cloud.voxels(), dealt.signs[p]);
        pattern.order = order.voxels();
        pattern.kappa.resize(n);
        for (size_t k = 0; k < n; ++k) pattern.kappa[k] = impl.kappa[pattern.order[k]];
        pattern.sweep.reset(new LineSweep(cloud.voxels(), order, nullptr, LineType::Naive));
    }
    const openvdb::CoordBBox box = cloud.voxels().bbox();
    impl.boxMin = box.min();
    impl.boxMax = box.max();
    impl.lo = box.min().asVec3d() - Vec3d(0.5);
    impl.hi = box.max().asVec3d() + Vec3d(0.5);
    impl.up = up;
    if (options.periodic) {
        impl.layer0 = box.min()[up];
        impl.layers = box.max()[up] - box.min()[up] + 1;
        impl.leftFace.assign(dirs * 2 * 6 * size_t(impl.layers), 0.0);
        impl.enterCount.assign(impl.leftFace.size(), 0);
        // How many lines enter through each side face per layer: geometry only, one walk per
        // direction (each direction counts into its own slice: no races).
        tbb::parallel_for(tbb::blocked_range<int>(0, Impl::kGroups, 1),
            [&](const tbb::blocked_range<int>& r) {
                for (int g = r.begin(); g != r.end(); ++g) {
                    const Impl::Pattern& pattern = impl.patterns[size_t(g / 2)];
                    if (pattern.directions.empty()) continue;
                    LineSweep::Lanes<Ray> lanes;
                    impl.forDirections(g, [&](size_t d) {
                        const Vec3d unit = mDirections.unit(d);
                        const size_t slice = impl.faceIndex(d, 0, 0, 0);
                        LinePartition part(mDirections.direction(d), LineType::Naive);
                        part.centreOn(impl.boxMin + impl.boxMax);
                        pattern.sweep->walk(mDirections.direction(d), impl.reversed[d] != 0, lanes,
                            [&](uint32_t x, Ray& ray, bool forward) {
                                if (ray.started) return;
                                ray.started = true;
                                const int at = impl.entering(part, mDirections.direction(d),
                                    pattern.sweep->coord(x), forward ? unit : -unit, forward);
                                if (at >= 0) ++impl.enterCount[slice + size_t(at)];
                            },
                            [](const Ray*, size_t, bool) {});
                    });
                }
            });
    }
    if (options.accelerate == Acceleration::Anderson) {
        // The moments and the light carried across periodic side faces (see iterate()).
        impl.mixer.reset(new AndersonMixer(n * size_t(impl.M) + impl.leftFace.size(),
            options.andersonDepth));
    }
    // Escape factors for the self-scattering elimination (iterate()): per direction, the float
    // step and the weight Omega (Y_00^2 of both senses) the sweeps use; voxels of equal kappa
    // (a homogeneous cloud) share one sum.
    {
        std::vector<float> step(dirs);
        std::vector<double> weight(dirs);
        const size_t M = size_t(impl.M);
        for (size_t d = 0; d < dirs; ++d) {
            step[d] = stepLength(mDirections.direction(d));
            const double y0 = impl.yAccumulate[2 * d * M], y1 = impl.yAccumulate[(2 * d + 1) * M];
            weight[d] = double(float(kPi * mDirections.factor(d))) * (y0 * y0 + y1 * y1);
        }
        impl.escape.resize(n);
        tbb::parallel_for(tbb::blocked_range<size_t>(0, n),
            [&](const tbb::blocked_range<size_t>& r) {
                const ScopedFlushDenormals flush;   // as in the sweeps
                float kappa = -1.f;
                double sum = 0.0;
                for (size_t i = r.begin(); i != r.end(); ++i) {
                    if (impl.kappa[i] != kappa) {
                        kappa = impl.kappa[i];
                        sum = 0.0;
                        for (size_t d = 0; d < dirs; ++d) {
                            float absorb, mean;
                            stepFactors(kappa * step[d], absorb, mean);
                            sum += weight[d] * double(mean);
                        }
                    }
                    impl.escape[i] = sum;
                }
            });
    }
    mSeconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

CloudTransfer::~CloudTransfer() = default;

Coord
CloudTransfer::periodicCopies(const Cloud& cloud, const CloudTransferOptions& options)
{
    if (!options.periodic || options.minPeriod == 0) return Coord(1);
    return copiesFor(cloud, options, DirectionSet::fromCount(options.directions).size());
}

Coord
CloudTransfer::copiesFor(const Cloud& cloud, const CloudTransferOptions& options, size_t dirs)
{
    Coord copies(1);
    if (!options.periodic || options.minPeriod == 0 || cloud.size() == 0) return copies;
    const int width = options.minPeriod > 0 ? options.minPeriod
        : int(std::ceil(0.5 * std::sqrt(double(dirs))));
    const Coord dim = cloud.voxels().bbox().dim();
    // Mean optical depth per voxel of the box (empty cells count as clear air).
    double depth = 0.0;
    for (float e : cloud.extinctionArray()) depth += double(e);
    depth *= cloud.voxelSize() / (double(dim.x()) * double(dim.y()) * double(dim.z()));
    for (int k = 0; k < 3; ++k) {
        if (k == options.up || dim[k] >= width) continue;
        int c = (width + dim[k] - 1) / dim[k];
        if (options.minPeriod < 0 && depth > 0.0) {
            c = int(std::min<double>(c, std::max(1.0, std::ceil(8.0 / (depth * dim[k])))));
        }
        copies[k] = c;
    }
    return copies;
}

bool
CloudTransfer::converged() const
{
    return !mResiduals.empty() && mResiduals.back() <= mOptions.tolerance;
}

double
CloudTransfer::iterate(openvdb::util::NullInterrupter* interrupt)
{
    const auto t0 = std::chrono::steady_clock::now();
    Impl& impl = *mImpl;
    const size_t n = impl.n;
    const int up = mOptions.up;
    const bool periodic = mOptions.periodic;

    // Source per voxel: omega0 chi_l times the moments of the diffuse radiance, so that
    // S(s) = sum_lm c_lm Y_lm(s), plus the beam's first scattering omega0 J_beam T(s).
    const size_t M = size_t(impl.M);
    std::vector<float> source(n * M), beamSource(n);
    // Anisotropic: (alpha - 1) omega0 I_00 per voxel, the part of the isotropic source that
    // alpha adds (see the self-scattering elimination below).
    std::vector<double> isoExcess(M > 1 ? n : 0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
        std::vector<double> c(M);
        for (size_t i = r.begin(); i != r.end(); ++i) {
            double total = 0.0;
            for (int l = 0, lm = 0; lm < int(M); ++l) {
                const double w = double(impl.omega[i]) * impl.chi[size_t(l)];
                for (int m = -l; m <= l; ++m, ++lm) {
                    c[size_t(lm)] = w * double(impl.moments[i * M + size_t(lm)]);
                    total += c[size_t(lm)] * impl.quadratureMean[size_t(lm)];
                }
            }
            // The direction set integrates this source to 4 pi x total, not exactly to its
            // isotropic part (the scattered power): scale it to that, keeping its angular shape.
            // (Subtracting each harmonic's quadrature mean instead would spread the error
            // evenly over all directions: a forward peak then leaks into backscatter, +30%
            // slab albedo at order 16.)
            const double target = c[0] * impl.quadratureMean[0];
            const double alpha = total > 0.0 ? target / total : 1.0;
            for (size_t lm = 0; lm < M; ++lm) source[i * M + lm] = float(alpha * c[lm]);
            if (M > 1) isoExcess[i] = total > 0.0 ? (target - total) / total * c[0] : 0.0;
            beamSource[i] = impl.omega[i] * impl.beamJ[i];
        }
    });

    std::array<std::vector<float>, Impl::kGroups> gathered;
    std::array<std::array<double, 2>, Impl::kGroups> escaped{};   // [group][0 down, 1 up]
    std::vector<double> leftNow(impl.leftFace.size(), 0.0);
    std::atomic<bool> cancelled{false};
    std::atomic<size_t> done{0};
    const size_t dirs = mDirections.size();

    tbb::parallel_for(tbb::blocked_range<int>(0, Impl::kGroups, 1),
        [&](const tbb::blocked_range<int>& r) {
            const ScopedFlushDenormals flush;   // Denormals.h
            for (int g = r.begin(); g != r.end(); ++g) {
                const Impl::Pattern& pattern = impl.patterns[size_t(g / 2)];
                if (pattern.directions.empty()) continue;
                std::vector<float> S(n * M), B(n);
                for (size_t k = 0; k < n; ++k) {
                    B[k] = beamSource[pattern.order[k]];
                    std::copy_n(source.begin() + long(pattern.order[k] * M), M,
                        S.begin() + long(k * M));
                }
                std::vector<float>& G = gathered[size_t(g)];
                G.assign(n * M, 0.f);
                LineSweep::Lanes<Ray> lanes;
                impl.forDirections(g, [&](size_t d) {
                    if (cancelled.load(std::memory_order_relaxed)) return;
                    const Coord& sigma = mDirections.direction(d);
                    const Vec3d unit = mDirections.unit(d);
                    // A naive line's step, in voxels, and its tube's etendue (cross-section
                    // 1 / step voxel faces times the solid angle of one orientation).
                    const float step = stepLength(sigma);
                    const float omega = float(kPi * mDirections.factor(d));
                    const double etendue = double(omega) / double(step);
                    const size_t slice = impl.faceIndex(d, 0, 0, 0);
                    const size_t sliceSize = size_t(2 * 6 * impl.layers);
                    // Periodic: power entering each side face per layer (what left the opposite
                    // face), and what leaves this pass.
                    std::vector<double> entry, exits(sliceSize, 0.0);
                    if (periodic) {
                        entry.assign(impl.leftFace.begin() + long(slice),
                            impl.leftFace.begin() + long(slice + sliceSize));
                    }
                    LinePartition part(sigma, LineType::Naive);
                    part.centreOn(impl.boxMin + impl.boxMax);
                    const float beamT[2] = {impl.beamTable[2 * d], impl.beamTable[2 * d + 1]};
                    const float* yAcc[2] = {&impl.yAccumulate[2 * d * M],
                        &impl.yAccumulate[(2 * d + 1) * M]};
                    // Exactly horizontal directions in a periodic box (see the file comment):
                    // the rise per wrap, in layers, of either half of the direction's cell.
                    double rise = 0.0;
                    if (periodic && unit[up] == 0.0) {
                        const int a1 = (up + 1) % 3, a2 = (up + 2) % 3;
                        const double w1 = impl.boxMax[a1] - impl.boxMin[a1] + 1;
                        const double w2 = impl.boxMax[a2] - impl.boxMin[a2] + 1;
                        // Mean chord of the box's cross-section along the direction: its area
                        // over its width seen from the direction.
                        const double chord = w1 * w2
                            / (w1 * std::abs(unit[a2]) + w2 * std::abs(unit[a1]));
                        // The cell spans elevations up to beta = sqrt(Omega) / 2 either way;
                        // its half's mean slope is tan(beta / 2).
                        const double beta = 0.5 * std::sqrt(kPi * mDirections.factor(d));
                        rise = chord * std::tan(0.5 * beta);
                    }
                    auto pass = [&](bool sources) {
                        std::fill(exits.begin(), exits.end(), 0.0);
                        pattern.sweep->walk(sigma, impl.reversed[d] != 0, lanes,
                            [&](uint32_t x, Ray& ray, bool forward) {
                                if (!ray.started) {
                                    ray.started = true;
                                    if (periodic) {
                                        const Vec3d t = forward ? unit : -unit;
                                        const int at = impl.entering(part, sigma,
                                            pattern.sweep->coord(x), t, forward);
                                        if (at >= 0) {
                                            const uint32_t c = impl.enterCount[slice + size_t(at)];
                                            ray.radiance = float(entry[size_t(at)] / c / etendue);
                                        }
                                    }
                                }
                                ray.last = x;
                                float absorb, mean;
                                stepFactors(pattern.kappa[x] * step, absorb, mean);
                                const size_t sense = forward ? 0 : 1;
                                const float* y = yAcc[sense];
                                // The source: its isotropic part s0, its higher moments' part
                                // r and the beam's first scattering b.
                                float s0 = 0.f, r = 0.f, b = 0.f;
                                if (sources) {
                                    const float* c = &S[size_t(x) * M];
                                    s0 = c[0] * y[0];
                                    for (size_t lm = 1; lm < M; ++lm) r += c[lm] * y[lm];
                                    b = B[x] * beamT[sense];
                                }
                                const float s = s0 + r + b;
                                // Mean over the step: s + (L - s) f. I_00 gathers only
                                // b + (L - b - r) f; iterate() adds the rest, s0 (1 - f) + r,
                                // summed over the directions in closed form (the self-
                                // scattering elimination), so that an opaque voxel's I_00 is
                                // not a small difference of floats.
                                const float rest = omega * (b + (ray.radiance - b - r) * mean);
                                float* acc = &G[size_t(x) * M];
                                acc[0] += rest * y[0];
                                if (M > 1) {
                                    const float lbar = omega * (s + (ray.radiance - s) * mean);
                                    for (size_t lm = 1; lm < M; ++lm) acc[lm] += lbar * y[lm];
                                }
                                ray.radiance += (s - ray.radiance) * absorb;
                            },
                            [&](const Ray* fronts, size_t lines, bool forward) {
                                const Vec3d t = forward ? unit : -unit;
                                for (size_t l = 0; l < lines; ++l) {
                                    const Ray& ray = fronts[l];
                                    if (!ray.started || ray.radiance == 0.f) continue;
                                    const double p = double(ray.radiance) * etendue;
                                    if (periodic) {
                                        const int at = impl.leaving(part, sigma,
                                            pattern.sweep->coord(ray.last), t, forward);
                                        if (at >= 0) { exits[size_t(at)] += p; continue; }
                                    }
                                    if (t[up] == 0.0) {
                                        escaped[size_t(g)][0] += 0.5 * p;
                                        escaped[size_t(g)][1] += 0.5 * p;
                                    } else {
                                        escaped[size_t(g)][t[up] > 0.0 ? 1 : 0] += p;
                                    }
                                }
                            });
                    };
                    // What left a side face (exits, times share) enters through the opposite
                    // one at the same height, unless no line enters there: then it has left for
                    // good. Light of a horizontal direction's upper (drift 1) or lower (-1) half
                    // cell enters `rise` layers higher or lower, split between the two nearest
                    // layers; above the top or below the bottom it has left. Returns the power
                    // that wraps.
                    auto wrapAround = [&](double share, int drift, std::vector<double>& into) {
                        double transit = 0.0;
                        const double shift = drift * rise, whole = std::floor(shift);
                        const double part[2] = {1.0 - (shift - whole), shift - whole};
                        for (size_t e = 0; e < sliceSize; ++e) {
                            if (exits[e] == 0.0) continue;
                            const size_t to = impl.oppositeSlot(e);
                            const int layer = int(to % size_t(impl.layers));
                            for (int k = 0; k < 2; ++k) {
                                const double p = share * exits[e] * part[k];
                                if (p == 0.0) continue;
                                const int at = layer + int(whole) + k;
                                const size_t slot = to - size_t(layer) + size_t(at);
                                if (at >= 0 && at < impl.layers
                                    && impl.enterCount[slice + slot] > 0) {
                                    into[slot] += p;
                                    transit += p;
                                } else {
                                    const double tUp = drift != 0 ? double(drift)
                                        : e < sliceSize / 2 ? unit[up] : -unit[up];
                                    escaped[size_t(g)][tUp > 0.0 ? 1 : 0] += p;
                                }
                            }
                        }
                        return transit;
                    };
                    // First the sources and the light carried over from the last iteration;
                    // then the light wrapping around the period is followed at once, pass after
                    // pass, until what still wraps is negligible; the rest is carried over. A
                    // horizontal direction's two half cells wrap separately, so that each keeps
                    // drifting its own way.
                    pass(true);
                    if (periodic) {
                        const int halves = rise > 0.0 ? 2 : 1;
                        const int drift[2] = {halves == 1 ? 0 : 1, -1};   // per half
                        std::array<std::vector<double>, 2> wrapping;
                        std::array<double, 2> transit{0.0, 0.0};
                        for (int h = 0; h < halves; ++h) {
                            wrapping[size_t(h)].assign(sliceSize, 0.0);
                            transit[size_t(h)] = wrapAround(1.0 / halves, drift[h],
                                wrapping[size_t(h)]);
                        }
                        const double first = transit[0] + transit[1];
                        for (int h = 0; h < halves; ++h) {
                            for (int wrap = 0; wrap < kMaxWraps
                                 && transit[size_t(h)] > 1e-9 * first; ++wrap) {
                                entry.swap(wrapping[size_t(h)]);
                                pass(false);
                                std::fill(wrapping[size_t(h)].begin(), wrapping[size_t(h)].end(),
                                    0.0);
                                transit[size_t(h)] = wrapAround(1.0, drift[h],
                                    wrapping[size_t(h)]);
                            }
                        }
                        for (size_t e = 0; e < sliceSize; ++e) {
                            leftNow[slice + e] = wrapping[0][e]
                                + (halves == 2 ? wrapping[1][e] : 0.0);
                        }
                    }
                    const size_t k = ++done;
                    if (interrupt && interrupt->wasInterrupted(int(100 * k / dirs))) {
                        cancelled = true;
                    }
                });
            }
        });
    if (cancelled) throw Cancelled("cloud transfer");

    // Moments from the groups, in a fixed order (bit-identical for any thread count).
    std::vector<double> sum(n * M, 0.0);
    for (int g = 0; g < Impl::kGroups; ++g) {
        const std::vector<float>& G = gathered[size_t(g)];
        if (G.empty()) continue;
        const std::vector<uint32_t>& order = impl.patterns[size_t(g / 2)].order;
        for (size_t k = 0; k < n; ++k) {
            for (size_t lm = 0; lm < M; ++lm) sum[order[k] * M + lm] += double(G[k * M + lm]);
        }
    }
    // The state this sweep started from, for the Anderson step below: the moments and, with
    // periodic boundaries, the light carried across the side faces (in a thin periodic slab
    // light wraps many times, and that carry-over is then the slowest mode).
    std::vector<float> x;
    if (impl.mixer) {
        x = impl.moments;
        x.insert(x.end(), impl.leftFace.begin(), impl.leftFace.end());
    }
    // Self-scattering elimination. Of what a voxel scatters isotropically, the fraction
    // 1 - M_v is extinguished again in the voxel itself: the sweep maps I_00 to
    // swept = rest + alpha c_v I_00 + (1 - alpha) omega0 I_00 (the second term s0 (1 - f), the
    // third the quadrature of r: alpha makes the higher moments integrate to
    // (1 - alpha) times the isotropic source), with c_v = omega0 (1 - M_v). In an opaque
    // conservative voxel that local mode decays like c_v ~ 1 - 1 / tau per sweep. Solving the
    // local term exactly,
    //     I_00' = (swept - c_v I_00) / (1 - c_v) = (rest - (alpha - 1) omega0 M_v I_00) / (1 - c_v),
    // has the same fixed point (I_00' = I_00 iff I_00 = swept) and removes that mode; what is
    // left is voxel-to-voxel diffusion, for Anderson. The beam's first scattering stays in rest
    // (a constant: fixed point unchanged), and so does the light a periodic box carries over.
    // 1 - c_v = (1 - omega0) + omega0 M_v, formed without cancellation in double: at the fixed
    // point a conservative voxel's I_00 M_v is then exactly the light it gathers, so the energy
    // balance closes however opaque it is. It is > 0 for any finite optical depth; the clamp
    // only keeps voxels whose float f underflowed (tau past ~1e37 per step: nothing gets in or
    // out of them) at J = 0 instead of 0 / 0. Higher moments need no elimination: a sweep maps
    // I_lm to about omega0 chi_l' (1 - M_v) I_lm, and |chi_l'| < 1 for l >= 1 does not tend to
    // 1 with the optical depth (delta-M keeps a forward peak's chi_l' <= K / (K + 1)), so their
    // local modes decay at a rate independent of tau.
    for (size_t i = 0; i < n; ++i) {
        const double w = impl.omega[i], m = impl.escape[i];
        const double free = std::max((1.0 - w) + w * m, double(std::numeric_limits<float>::min()));
        const double excess = M > 1 ? isoExcess[i] * m : 0.0;
        sum[i * M] = (sum[i * M] - excess) / free;
    }
    for (size_t e = 0; e < n * M; ++e) impl.moments[e] = float(sum[e]);
    double maxChange = 0.0, maxJ = 0.0, absorbed = 0.0;
    const double y00 = 1.0 / std::sqrt(4.0 * kPi);
    for (size_t i = 0; i < n; ++i) {
        const float J = float(sum[i * M] * y00);
        maxChange = std::max(maxChange, double(std::abs(J - impl.diffuseJ[i])));
        maxJ = std::max(maxJ, double(J + impl.beamJ[i]));
        impl.diffuseJ[i] = J;
        // Extinguished here: the beam's deposit and, per unit volume, 4 pi kappa J.
        absorbed += double(1.f - impl.omega[i])
            * (impl.deposited[i] + 4.0 * kPi * double(impl.kappa[i]) * double(J));
    }

    if (periodic) impl.leftFace.swap(leftNow);
    if (impl.mixer) {
        // The next sweep starts from the mixed state; J follows it, so that the next residual
        // measures that sweep's change and the output is the mixed iterate. A mixed state with
        // negative mean radiance or carried power is refused (the plain step is kept).
        std::vector<float> gx = impl.moments;
        gx.insert(gx.end(), impl.leftFace.begin(), impl.leftFace.end());
        impl.mixer->mix(x.data(), gx.data());
        bool physical = true;
        for (size_t i = 0; i < n && physical; ++i) physical = gx[i * M] >= 0.f;
        for (size_t k = n * M; k < gx.size() && physical; ++k) physical = gx[k] >= 0.f;
        if (!physical) impl.mixer->rejectLastStep(gx.data());
        std::copy(gx.begin(), gx.begin() + long(n * M), impl.moments.begin());
        std::copy(gx.begin() + long(n * M), gx.end(), impl.leftFace.begin());
        for (size_t i = 0; i < n; ++i) impl.diffuseJ[i] = float(double(impl.moments[i * M]) * y00);
    }
    double up0 = 0.0, down0 = 0.0;
    for (const auto& e : escaped) { down0 += e[0]; up0 += e[1]; }
    const double in = impl.incident > 0.0 ? impl.incident : 1.0;
    mBudget.incident = impl.incident * impl.outputScale;
    mBudget.albedo = up0 / in;
    mBudget.transmittance = (down0 + impl.directOut) / in;
    mBudget.directTransmittance = impl.directOut / in;
    mBudget.absorptance = absorbed / in;

    const double residual = maxJ > 0.0 ? maxChange / maxJ : 0.0;
    mResiduals.push_back(residual);
    mSeconds += std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return residual;
}

void
CloudTransfer::solve(openvdb::util::NullInterrupter* interrupt)
{
    while (!converged() && iterationCount() < mOptions.maxIterations) iterate(interrupt);
}

size_t
CloudTransfer::memoryEstimate(const Cloud& cloud, const CloudTransferOptions& options,
    int threads)
{
    const Coord copies = periodicCopies(cloud, options);
    const size_t tiles = size_t(copies.x()) * size_t(copies.y()) * size_t(copies.z());
    const size_t n = cloud.size() * tiles, t = size_t(std::max(threads, 1));
    const int order = options.phase.isIsotropic() ? 0 : options.phaseOrder;
    const size_t M = size_t(order + 1) * size_t(order + 1);
    size_t perVoxel = 4 + 4 + 4 + 8 + 4;            // kappa, omega, beam J, deposit, diffuse J
    perVoxel += 8 + (M > 1 ? 8 : 0);                // escape factor, alpha's excess of I_00
    perVoxel += 4 * (4 + 4 + 12);                   // per pattern: order, kappa, sweep coords
    perVoxel += 4 * M + 4 * M + 4;                  // moments, their source, the beam's source
    perVoxel += size_t(Impl::kGroups) * 4 * M;      // gathered moments per group
    perVoxel += 8 * M;                              // their double sum
    perVoxel += t * (4 * M + 4 + 4 + 16);           // per thread: S, B, slots, line state
    if (options.accelerate == Acceleration::Anderson) {
        perVoxel += 8 * M + AndersonMixer::bytes(M, options.andersonDepth);   // + x, G(x)
    }
    // The copies of a narrow periodic box: coordinates, extinction, the copy's source, index.
    if (tiles > 1) perVoxel += 12 + 4 + 4 + 8;
    size_t bytes = n * perVoxel;
    if (options.periodic) {
        // Light carried across the side faces: per direction, sense, face and layer, twice.
        const openvdb::CoordBBox box = cloud.voxels().bbox();
        const size_t layers = size_t(box.dim()[options.up]);   // copies stack sideways only
        const size_t dirs = DirectionSet::fromCount(options.directions).size();
        const size_t faces = dirs * 2 * 6 * layers;
        bytes += faces * (8 + 8 + 4);
        if (options.accelerate == Acceleration::Anderson) {
            bytes += 8 * faces + AndersonMixer::bytes(faces, options.andersonDepth);
        }
    }
    return bytes;
}

uint64_t
CloudTransfer::fingerprint() const
{
    const Impl& impl = *mImpl;
    uint64_t h = hashBytes("vdbrad solve-cloud", 18);
    const VoxelIndex& v = mCloud.voxels();
    h = hashBytes(v.coords().data(), v.size() * sizeof(openvdb::Coord), h);
    h = hashBytes(impl.kappa.data(), impl.kappa.size() * sizeof(float), h);
    h = hashBytes(impl.omega.data(), impl.omega.size() * sizeof(float), h);
    h = hashBytes(impl.deposited.data(), impl.deposited.size() * sizeof(double), h);
    h = hashBytes(impl.chi.data(), impl.chi.size() * sizeof(double), h);
    h = hashBytes(impl.beamTable.data(), impl.beamTable.size() * sizeof(float), h);
    const int64_t options[10] = {int64_t(mDirections.size()), mOptions.periodic ? 1 : 0,
        mOptions.phaseOrder, int64_t(mOptions.accelerate), mOptions.andersonDepth, mOptions.up,
        impl.M, mCopies.x(), mCopies.y(), mCopies.z()};
    return hashBytes(options, sizeof options, h);
}

void
CloudTransfer::saveState(SolverState& state) const
{
    const Impl& impl = *mImpl;
    state.put("residuals", mResiduals);
    const double budget[6] = {mSeconds, mBudget.incident, mBudget.albedo,
        mBudget.transmittance, mBudget.directTransmittance, mBudget.absorptance};
    state.put("budget", budget, 6);
    state.put("diffuseJ", impl.diffuseJ);
    state.put("moments", impl.moments);
    state.put("leftFace", impl.leftFace);
    if (impl.mixer) impl.mixer->save(state, "anderson.");
}

void
CloudTransfer::restoreState(const SolverState& state)
{
    Impl& impl = *mImpl;
    mResiduals = state.get<double>("residuals");
    const std::vector<double> budget = state.get<double>("budget", 6);
    impl.diffuseJ = state.get<float>("diffuseJ", impl.diffuseJ.size());
    impl.moments = state.get<float>("moments", impl.moments.size());
    impl.leftFace = state.get<double>("leftFace", impl.leftFace.size());
    if (impl.mixer) impl.mixer->restore(state, "anderson.");
    mSeconds = budget[0];
    mBudget.incident = budget[1];
    mBudget.albedo = budget[2];
    mBudget.transmittance = budget[3];
    mBudget.directTransmittance = budget[4];
    mBudget.absorptance = budget[5];
}

std::vector<float>
CloudTransfer::meanIntensity() const
{
    const Impl& impl = *mImpl;
    const double scale = impl.outputScale;
    std::vector<float> J(mCloud.size());
    if (!impl.tiled) {
        for (size_t i = 0; i < J.size(); ++i) {
            J[i] = float(double(impl.diffuseJ[i] + impl.beamJ[i]) * scale);
        }
        return J;
    }
    // The mean over a voxel's copies (every voxel has the same number of them).
    std::vector<double> sum(J.size(), 0.0);
    for (size_t i = 0; i < impl.n; ++i) {
        sum[impl.copyOf[i]] += double(impl.diffuseJ[i] + impl.beamJ[i]);
    }
    const double per = scale / double(impl.n / J.size());
    for (size_t i = 0; i < J.size(); ++i) J[i] = float(sum[i] * per);
    return J;
}

openvdb::GridBase::Ptr
CloudTransfer::grid(const std::string& name) const
{
    openvdb::FloatGrid::Ptr g = arrayToGrid(mCloud.voxels(), meanIntensity(), mCloud.transform(),
        name);
    g->insertMeta("vdbrad:albedo", openvdb::FloatMetadata(float(mBudget.albedo)));
    g->insertMeta("vdbrad:transmittance", openvdb::FloatMetadata(float(mBudget.transmittance)));
    g->insertMeta("vdbrad:absorptance", openvdb::FloatMetadata(float(mBudget.absorptance)));
    g->insertMeta(meta::kIterations, openvdb::Int32Metadata(iterationCount()));
    g->insertMeta(meta::kResidual, openvdb::FloatMetadata(
        mResiduals.empty() ? 0.f : float(mResiduals.back())));
    g->insertMeta(meta::kDirections, openvdb::Int32Metadata(int(mDirections.size())));
    g->insertMeta(meta::kSeconds, openvdb::FloatMetadata(float(mSeconds)));
    g->insertMeta(meta::kVersion, openvdb::StringMetadata(VDBRAD_VERSION_STRING));
    return g;
}

openvdb::GridBase::Ptr
solveCloud(const Cloud& cloud, const CloudTransferOptions& options,
    openvdb::util::NullInterrupter* interrupt)
{
    CloudTransfer transfer(cloud, options, interrupt);
    transfer.solve(interrupt);
    return transfer.grid();
}

} // namespace vdbrad
