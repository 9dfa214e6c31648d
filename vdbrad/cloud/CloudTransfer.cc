#include "vdbrad/cloud/CloudTransfer.h"

#include "vdbrad/cloud/FogSurfaces.h"
#include "vdbrad/cloud/Ground.h"
#include "vdbrad/cloud/HarmonicQuadrature.h"
#include "vdbrad/cloud/PeriodicBoundary.h"
#include "vdbrad/cloud/PhaseFunction.h"
#include "vdbrad/cloud/SolarBeam.h"
#include "vdbrad/cloud/VoxelStep.h"
#include "vdbrad/core/Constants.h"
#include "vdbrad/core/Denormals.h"
#include "vdbrad/core/Errors.h"
#include "vdbrad/core/TextFormat.h"
#include "vdbrad/core/Version.h"
#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/scene/OutputGrids.h"
#include "vdbrad/sweep/Enclosure.h"
#include "vdbrad/sweep/LinePartition.h"
#include "vdbrad/sweep/LineSweep.h"
#include "vdbrad/sweep/SweepSchedule.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <limits>
#include <sstream>
#include <type_traits>
#include <unordered_map>

namespace vdbrad {

namespace {

using openvdb::Coord;
using openvdb::Vec3d;


// Channel @a c of voxel @a i: an RGB problem is solved one colour at a time.
float channelOf(const Attribute& a, size_t i, int c)
{
    return a.isRgb() ? a.rgb(i)[c] : a.grey(i);
}

// Whether the problem has colours: an RGB albedo (medium or surfaces) or surface emission.
bool isRgb(const Cloud& cloud, const CloudTransferOptions& o)
{
    return cloud.albedo().isRgb() || cloud.emission().isRgb()
        || (o.surfaces && o.surfaces->isRgb());
}
// What a line carries: its radiance, whether it has met its first voxel yet (periodic boundaries
// give that voxel the light re-entering the box) and the last voxel it met (where it leaves).
// A voxel is finished only when the next one on its line is met (or the pass ends), which gives
// a linear source its slope: until then `radiance` is what enters the pending voxel `last`.
struct Ray
{
    float radiance = 0.f;
    bool started = false;
    bool pending = false;      // `last` is not finished yet
    bool hasBefore = false;    // the voxel before `last` on the line is its neighbour
    bool receiving = false;    // `last` is a surface voxel that took the line's light
    bool medium = false;       // `last` is a medium voxel
    uint32_t run = FogSurfaces::kNone;   // the surface voxel `last` if it sends light along the line
    uint32_t last = 0;
    // A linear source only: last's source (total, higher moments, beam), the one before it's.
    float s = 0.f, r = 0.f, b = 0.f;
    float before = 0.f;
};

// The source's rise across a step, from the steps before (dm) and after (dp): the monotonized
// central difference (second order where the source is smooth, no new extremum where it is not),
// kept within +-2 s so that the source stays >= 0 across the step.
inline float
sourceSlope(float s, const float* before, const float* after)
{
    float slope = 0.f;
    if (before && after) {
        const float dm = s - *before, dp = *after - s;
        if (dm * dp > 0.f) {
            const float c = 0.5f * (dm + dp);
            slope = std::copysign(std::min({std::abs(c), 2.f * std::abs(dm), 2.f * std::abs(dp)}),
                c);
        }
    } else if (before) {
        slope = s - *before;
    } else if (after) {
        slope = *after - s;
    }
    const float bound = 2.f * std::max(s, 0.f);
    return std::clamp(slope, -bound, bound);
}

// out[0, w) (+)= sum over h < H of a[h] b[h * stride + (0, w)]: one row of a small matrix
// product, in blocks of 16 accumulators that stay in registers (the compiler cannot keep a
// row it might alias with its inputs there). Compiled for AVX too, chosen at run time where the
// CPU has it: 8 lanes instead of SSE2's 4, and the same bits (separate multiplies and adds in
// the same order: no FMA, whose single rounding would change them).
#if defined(__GNUC__) && !defined(__clang__) && defined(__x86_64__)
__attribute__((target_clones("avx", "default")))
#endif
void
rowTimesMatrix(const float* a, const float* b, size_t H, size_t stride, size_t w, float* out,
    bool add)
{
    constexpr size_t kBlock = 16;
    size_t k0 = 0;
    for (; k0 + kBlock <= w; k0 += kBlock) {
        float acc[kBlock];
        for (size_t k = 0; k < kBlock; ++k) acc[k] = add ? out[k0 + k] : 0.f;
        for (size_t h = 0; h < H; ++h) {
            const float ah = a[h];
            const float* bh = b + h * stride + k0;
            for (size_t k = 0; k < kBlock; ++k) acc[k] += ah * bh[k];
        }
        for (size_t k = 0; k < kBlock; ++k) out[k0 + k] = acc[k];
    }
    for (size_t k = k0; k < w; ++k) {
        float acc = add ? out[k] : 0.f;
        for (size_t h = 0; h < H; ++h) acc += a[h] * b[h * stride + k];
        out[k] = acc;
    }
}

} // namespace

// Whether positions @a x and @a y of @a sweep's order are neighbours on a naive line of major
// axis @a major: one step apart along it, no gap between them.
template<typename SweepT>
inline bool
lineNeighbours(const SweepT& sweep, int major, uint32_t x, uint32_t y)
{
    return std::abs(sweep.coord(x)[major] - sweep.coord(y)[major]) == 1;
}

// t . n for the sense (forward: along @a unit) a line is swept in.
inline double
senseCosine(const Vec3d& unit, bool forward, const openvdb::Vec3f& n)
{
    return (forward ? 1.0 : -1.0) * unit.dot(Vec3d(n));
}

// A line in sense t meets surface voxel v, t.n_v = c != 0 (FogSurfaces.h), @a adjacent if v
// is the neighbour on the line of the voxel before it. A run of senders ends before a receiver
// and before a sender that is not its neighbour, sending @a sent(u) (the radiance leaving its
// last voxel u). A sender that does not continue a run takes what comes in from the medium
// voxel just before it (the fog is on its front side, whatever its normal says at a digital
// edge) and otherwise absorbs with its back what comes from behind (into @a backs, times
// @a etendue). Returns whether v takes the line's radiance (the caller lands it; the line then
// goes on dark): the first of a run of receivers, or a sender right after the medium.
template<typename SentT>
inline bool
meetSurface(Ray& ray, uint32_t v, double c, bool adjacent, double etendue, SentT&& sent,
    double& backs)
{
    const bool inRun = ray.run != FogSurfaces::kNone;
    const bool afterMedium = ray.medium && adjacent;
    ray.medium = false;
    if (c > 0.0 && inRun && adjacent) {
        ray.run = v;
        return false;
    }
    if (inRun) ray.radiance = sent(ray.run);
    ray.run = FogSurfaces::kNone;
    if (c > 0.0) {
        ray.run = v;
        ray.receiving = false;
        if (afterMedium) return true;
        backs += double(ray.radiance) * etendue;
        ray.radiance = 0.f;
        return false;
    }
    const bool first = inRun || !(ray.receiving && adjacent);
    ray.receiving = true;
    return first;
}

struct CloudTransfer::Impl
{
    // The ranks of CloudTransferOptions::ranks, or this process alone where it gives none.
    Distribution alone;
    static constexpr int kGroups = SweepSchedule::kGroups;

    size_t n = 0;
    // The medium solved where it is not the cloud as given: a narrow periodic box as copies side
    // by side (periodicCopies()), and a ground's layer under it (Ground.h); per voxel of it, the
    // voxel of the given cloud it copies, or GroundLayer::kGround. Null: the cloud as given.
    std::unique_ptr<Cloud> solved;
    std::vector<uint32_t> copyOf;
    // A Lambertian ground (CloudTransferOptions::groundAlbedo): its layer and albedo, per cell
    // the direct beam's power landing there and the diffuse light's (the last sweep's), per
    // direction pair the radiance an upward line gains per unit of reflected power.
    std::optional<GroundLayer> ground;
    double groundAlbedo = 0.0;
    std::vector<double> groundDirect, groundDiffuse, groundGain;
    // Surfaces inside the medium (FogSurfaces.h): per solved voxel the surface voxel it is (or
    // kNone), also in each pattern's order; per surface voxel the direct beam's power on its
    // front, the diffuse light's (the last sweep's) and Z_v; the beam's power on their backs.
    std::unique_ptr<FogSurfaces> surfaces;
    std::vector<uint32_t> surfaceOf;
    std::array<std::vector<uint32_t>, SweepSchedule::kPatterns> surfaceOrdered;
    std::vector<double> surfaceDirect, surfaceLanded, surfaceNorm;
    std::vector<double> surfaceArea;   // A_v, voxel faces (FogSurfaces.h)
    std::vector<uint8_t> enclosed;     // per surface voxel: it faces a closed cavity
    double backDirect = 0.0, emitted = 0.0, mediumEmitted = 0.0;
    // The areas A_v: one sweep of every direction applying the surfaces' rule alone.
    std::vector<double> surfaceAreas() const;
    // What surface voxel v sends: B_v / Z_v, B_v = E_v + rho_v (direct + landed) / A_v.
    double surfaceSends(size_t v) const
    {
        if (!(surfaceArea[v] > 0.0) || !(surfaceNorm[v] > 0.0)) return 0.0;
        const double B = double(surfaces->emission(v)) / outputScale + double(surfaces->albedo(v))
            * (surfaceDirect[v] + surfaceLanded[v]) / surfaceArea[v];
        return B / surfaceNorm[v];
    }
    std::vector<float> kappa;        // optical depth per voxel length
    std::vector<float> omega;        // single-scattering albedo
    std::vector<float> beamJ;        // mean radiance of the direct beam, D / (4 pi kappa)
    // The medium's emission as a source, epsilon / sigma_t (empty where nothing emits): fixed,
    // like the beam's first scattering, and gathered with it.
    std::vector<float> emitSource;
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
    // The phase function on the directions: harmonics per direction and sense, their
    // quadrature means, the beam's first scattering (PhaseFunction::Tables).
    PhaseFunction::Tables phase;

    std::unique_ptr<SweepSchedule> schedule;
    std::array<std::vector<float>, SweepSchedule::kPatterns> kappaOrdered;   // per pattern
    mutable SweepSchedule::PerThread<LineSweep::Lanes<Ray>> lanes;   // per thread, reused
    // Periodic boundaries (null: open): the side faces, and per direction slice the power
    // that left each face per layer in the last sweep, carried over to the next.
    std::unique_ptr<PeriodicBoundary> boundary;
    std::vector<double> leftFace;
    // Axes along which a periodic box is one voxel deep: lines are swept in the plane of the
    // others (sweptLine()).
    FlatAxes flat{};

    // The sweeps of one iteration: every group's directions, from the sources S (n x M moments'
    // coefficients) and B (the beam's first scattering) in each pattern's order, and the power
    // each ground cell reflects, into the groups' moment sums G; light leaving the box goes to
    // escaped (0 down, 1 up), light wrapping around a periodic box to leftNow, light reaching
    // the ground to the group's landed (per cell).
    struct Sweep
    {
        const std::array<std::vector<float>, SweepSchedule::kPatterns>& S;
        const std::array<std::vector<float>, SweepSchedule::kPatterns>& B;
        const std::array<std::vector<float>, SweepSchedule::kPatterns>& E;   // emission
        const std::vector<double>& groundEmits;
        std::array<std::vector<float>, SweepSchedule::kGroups> G;
        std::array<std::array<double, 2>, SweepSchedule::kGroups> escaped{};
        std::vector<double> leftNow;
        std::array<std::vector<double>, SweepSchedule::kGroups> landed;
        // Surfaces: per surface voxel B_v / Z_v (the radiance it sends), and per group what lands on
        // each one's front and what reaches their backs.
        const std::vector<double>& surfaceEmits;
        std::array<std::vector<double>, SweepSchedule::kGroups> onSurface;
        std::array<double, SweepSchedule::kGroups> backs{};
    };
    // Anisotropic scattering works on a batch of a group's directions at a time: the sources'
    // higher-moment part for every voxel and (direction, sense) of the batch by one product of
    // the voxels' coefficients with the harmonics, then the sweeps reading one float per voxel
    // and column, writing the mean radiance over the step to another, and the moments by a
    // second product (81 multiply-adds per voxel and column in a vectorised loop, instead of
    // inside the sweep's sequential step). Per thread: the two matrices and the harmonics.
    struct Batch
    {
        size_t width = 0;            // columns: 2 x directions (both senses)
        std::vector<float> R;        // n x width: sum over l >= 1 of c_lm Y_lm(column)
        std::vector<float> Lbar;     // n x width: omega0 x the step's mean radiance
        std::vector<float> Yt;       // (M - 1) x width: the harmonics l >= 1, transposed
        // Per voxel, 1 - e^-tau of the direction swept: from the first pass's forward sense,
        // for its backward sense and the wrap passes (the exponential was a third of an
        // isotropic sweep).
        std::vector<double> absorbed;
    };
    mutable SweepSchedule::PerThread<Batch> batches;
    /// Directions per batch: as many as keep a thread's two matrices within kBatchBytes.
    static constexpr size_t kBatchBytes = size_t(64) << 20;
    static constexpr size_t kMaxBatch = 32;
    static size_t batchSize(size_t n, size_t M)
    {
        if (M == 1) return 1;
        return std::clamp<size_t>(kBatchBytes / (std::max<size_t>(n, 1) * 2 * 2 * 4), 1, kMaxBatch);
    }
    void sweepBatch(const CloudTransfer& t, int g, const size_t* dirs, size_t count,
        Sweep& sweep) const;
    void sweepDirection(const CloudTransfer& t, int g, size_t d, size_t column, Batch& batch,
        Sweep& sweep) const;
};

CloudTransfer::CloudTransfer(const Cloud& given, const CloudTransferOptions& options,
    openvdb::util::NullInterrupter* interrupt)
    : IterativeSolver(FixedPointIteration(options.maxIterations, options.tolerance,
          chooseAcceleration(given, options), options.andersonDepth))
    , mCloud(given), mOptions(options)
    , mImpl(new Impl)
{
    const auto start = std::chrono::steady_clock::now();
    if (!(options.sunZenith >= 0.0 && options.sunZenith <= 89.9)) {
        OPENVDB_THROW(openvdb::ValueError, "sun zenith angle must be in [0, 89.9] degrees, got "
            << options.sunZenith);
    }
    if (!std::isfinite(options.sunAzimuth)) {
        OPENVDB_THROW(openvdb::ValueError, "sun azimuth must be finite");
    }
    if (options.up < 0 || options.up > 2) {
        OPENVDB_THROW(openvdb::ValueError, "up must be 0, 1 or 2");
    }
    if (options.minPeriod < -1) {
        OPENVDB_THROW(openvdb::ValueError, "minimum period must be >= 0 voxels (or -1: auto), got "
            << options.minPeriod);
    }
    if (options.channel < 0 || options.channel > 2) {
        OPENVDB_THROW(openvdb::ValueError, "channel must be 0, 1 or 2, got " << options.channel);
    }
    if (options.phaseOrder < -1) {
        OPENVDB_THROW(openvdb::ValueError, "phase order must be >= 0 (or -1: auto), got "
            << options.phaseOrder);
    }
    if (options.groundAlbedo && !(*options.groundAlbedo >= 0.0 && *options.groundAlbedo <= 1.0)) {
        OPENVDB_THROW(openvdb::ValueError, "ground albedo must be in [0, 1], got "
            << *options.groundAlbedo);
    }
    mOptions.phaseOrder = phaseOrderFor(options);
    mOptions.directions = directionCount(options);
    mOptions.accelerate = mIteration.acceleration();   // chosen once, for the base class
    DirectionSet directions = DirectionSet::fromCount(mOptions.directions);
    // Anisotropic scattering projects the radiance on harmonics up to order K and evaluates
    // the source from them: weights exact for products of two of them (degree 2K) keep that
    // projection from aliasing (HarmonicQuadrature.h).
    const int order = phaseOrderFor(options);
    if (order > 0 && options.harmonicWeights) {
        HarmonicQuadrature fit = fitHarmonicQuadrature(directions,
            std::min(2 * order, kMaxQuadratureDegree));
        mQuadratureDegree = fit.degree;
        directions = directions.withFactors(std::move(fit.factors));
    }
    Impl& impl = *mImpl;
    mCopies = copiesFor(given, options, directions.size());
    if (mCopies != Coord(1)) impl.solved.reset(new Cloud(tileCloud(given, mCopies, &impl.copyOf)));
    if (options.groundAlbedo) {
        impl.groundAlbedo = *options.groundAlbedo;
        const Cloud& above = impl.solved ? *impl.solved : given;
        impl.ground.emplace(above.voxels().bbox(), options.up);
        std::vector<uint32_t> from;
        Cloud grounded = impl.ground->withGround(above, &from);
        if (impl.solved) {
            for (uint32_t& f : from) if (f != GroundLayer::kGround) f = impl.copyOf[f];
        }
        impl.copyOf = std::move(from);
        impl.solved.reset(new Cloud(std::move(grounded)));
    }
    if (options.surfaces) {
        if (options.periodic || options.groundAlbedo) {
            OPENVDB_THROW(openvdb::ValueError, "surfaces inside a cloud are solved in an open "
                "box without a ground (give the ground as surface voxels)");
        }
        impl.surfaces.reset(new FogSurfaces(*options.surfaces, options.channel));
        std::vector<uint32_t> from;
        Cloud merged = impl.surfaces->merged(given, from, impl.surfaceOf);
        static_assert(FogSurfaces::kNone == GroundLayer::kGround, "one mark for no cloud voxel");
        impl.copyOf = std::move(from);
        impl.solved.reset(new Cloud(std::move(merged)));
    }
    // From here on, the medium solved.
    const Cloud& cloud = impl.solved ? *impl.solved : given;
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
        impl.omega[i] = channelOf(cloud.albedo(), i, options.channel);
    }
    // Phase function: order K and delta-M scaling of extinction and albedo.
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

    const int up = options.up;
    const Vec3d toSun = sunDirection(options.sunZenith, options.sunAzimuth, up,
        cloud.transform());
    if (interrupt) interrupt->start("solar beam");
    // The transfer runs at the irradiance divided by a power of two that brings it to [0.5, 1),
    // and intensities are multiplied back on output (both exact): flush-to-zero (Denormals.h)
    // then cuts at the same relative level for any F0, and F0 = 2^k F gives 2^k times the bits.
    int exponent = 0;
    if (options.irradiance > 0.0 && std::isfinite(options.irradiance)) {
        std::frexp(options.irradiance, &exponent);
    }
    impl.outputScale = std::ldexp(1.0, exponent);
    const GroundLayer* layer = impl.ground ? &*impl.ground : nullptr;
    std::vector<uint8_t> opaque;
    if (impl.surfaces) {
        opaque.resize(n);
        for (size_t i = 0; i < n; ++i) opaque[i] = impl.surfaceOf[i] != FogSurfaces::kNone;
    }
    SolarBeamResult beam = traceSolarBeam(cloud.voxels(), impl.kappa, toSun, up, options.periodic,
        options.beamRaysPerVoxel, options.irradiance / impl.outputScale, interrupt, layer,
        impl.surfaces ? &opaque : nullptr);
    if (interrupt) interrupt->end();
    impl.incident = beam.incident;
    impl.deposited = std::move(beam.deposited);
    // What lands on the ground is counted there (sweep()); directOut is the rest.
    impl.directOut = beam.transmitted;
    if (impl.ground) {
        impl.groundDirect = std::move(beam.ground);
        impl.groundDiffuse.assign(impl.ground->size(), 0.0);
        for (double e : impl.groundDirect) impl.directOut -= e;
        impl.directOut = std::max(impl.directOut, 0.0);
    }
    if (impl.surfaces) {
        // The beam's power on a surface voxel: on its front if the beam meets it from there.
        impl.surfaceDirect.assign(impl.surfaces->size(), 0.0);
        impl.surfaceLanded.assign(impl.surfaces->size(), 0.0);
        for (size_t i = 0; i < n; ++i) {
            const uint32_t s = impl.surfaceOf[i];
            if (s == FogSurfaces::kNone) continue;
            if (toSun.dot(Vec3d(impl.surfaces->normal(s))) > 0.0) {
                impl.surfaceDirect[s] += impl.deposited[i];
            } else {
                impl.backDirect += impl.deposited[i];
            }
            impl.deposited[i] = 0.0;
        }
    }
    impl.beamJ.resize(n);
    for (size_t i = 0; i < n; ++i) {
        impl.beamJ[i] = impl.kappa[i] > 0.f
            ? float(impl.deposited[i] / (4.0 * kPi * double(impl.kappa[i]))) : 0.f;
    }
    if (!given.emission().isZero()) {
        // epsilon / sigma_t with sigma_t as the sweeps see it (delta-M scaled); copies, the
        // ground's layer and surface voxels take their source voxel's (none for the last two).
        impl.emitSource.assign(n, 0.f);
        double emitted = 0.0;
        for (size_t i = 0; i < n; ++i) {
            const uint32_t from = impl.copyOf.empty() ? uint32_t(i) : impl.copyOf[i];
            if (from == GroundLayer::kGround || !(impl.kappa[i] > 0.f)) continue;
            const double e = channelOf(given.emission(), from, options.channel) * h
                / impl.outputScale;
            impl.emitSource[i] = float(e / double(impl.kappa[i]));
            emitted += 4.0 * kPi * e;   // 4 pi epsilon V, in the beam's units (voxel faces)
        }
        impl.mediumEmitted = emitted;
    }
    impl.diffuseJ.assign(n, 0.f);
    impl.moments.assign(n * size_t(impl.M), 0.f);
    impl.phase = options.phase.tables(directions, order, (-toSun).unit());

    // Sweep orders: naive lines (their steps have exact lengths).
    const size_t dirs = directions.size();
    impl.schedule.reset(new SweepSchedule(cloud.voxels(), std::move(directions),
        SweepSchedule::Layout()));
    const SweepSchedule& schedule = *impl.schedule;
    for (size_t p = 0; p < impl.kappaOrdered.size(); ++p) {
        if (!schedule.pattern(p).empty()) {
            schedule.toPatternOrder(p, impl.kappa, impl.kappaOrdered[p]);
        }
    }
    if (impl.surfaces) {
        for (size_t p = 0; p < impl.surfaceOrdered.size(); ++p) {
            if (!schedule.pattern(p).empty()) {
                schedule.toPatternOrder(p, impl.surfaceOf, impl.surfaceOrdered[p]);
            }
        }
    }
    if (options.periodic) {
        impl.flat = PeriodicBoundary::flatAxes(cloud.voxels().bbox().dim(), up);
        impl.boundary.reset(new PeriodicBoundary(cloud.voxels().bbox(), up, schedule,
            impl.flat));
        impl.leftFace.assign(impl.boundary->size(), 0.0);
    }
    // The moments, the light carried across periodic side faces and the ground's (see
    // iterate()).
    impl.mixer = mIteration.makeMixer<float>(n * size_t(impl.M) + impl.leftFace.size()
        + impl.groundDiffuse.size() + impl.surfaceLanded.size());
    // Escape factors for the self-scattering elimination (iterate()): per direction, the
    // weight Omega (Y_00^2 of both senses) the sweeps use.
    {
        std::vector<double> weight(dirs);
        std::vector<float> step(dirs);
        const size_t M = size_t(impl.M);
        const std::vector<float>& y = impl.phase.harmonics;
        for (size_t d = 0; d < dirs; ++d) {
            const double y0 = y[2 * d * M], y1 = y[(2 * d + 1) * M];
            weight[d] = double(float(kPi * schedule.directions().factor(d))) * (y0 * y0 + y1 * y1);
            step[d] = sweptLine(schedule.directions().direction(d), impl.flat).step;
        }
        impl.escape = meanEscapeFactors(impl.kappa, step, weight);
        if (impl.ground) {
            std::vector<float> omega(dirs);
            std::vector<double> mu(dirs);
            for (size_t d = 0; d < dirs; ++d) {
                omega[d] = float(kPi * schedule.directions().factor(d));
                mu[d] = std::abs(schedule.directions().unit(d)[up]);
            }
            impl.groundGain = groundEmission(omega, mu, step);
        }
        if (impl.surfaces) {
            std::vector<Vec3d> units(dirs);
            std::vector<float> omega(dirs);
            for (size_t d = 0; d < dirs; ++d) {
                units[d] = sweptLine(schedule.directions().direction(d), impl.flat).unit;
                omega[d] = float(kPi * schedule.directions().factor(d));
            }
            impl.surfaceNorm = impl.surfaces->normalisers(units, omega);
            const Regions regions = findRegions(impl.surfaces->scene().voxels(),
                impl.surfaces->scene().normals(), LineType::Naive);
            impl.enclosed.resize(impl.surfaces->size());
            for (size_t v = 0; v < impl.enclosed.size(); ++v) {
                impl.enclosed[v] = regions.region[v] != 0;
            }
            impl.surfaceArea = impl.surfaceAreas();
            for (size_t v = 0; v < impl.surfaceArea.size(); ++v) {
                impl.emitted += double(impl.surfaces->emission(v)) * impl.surfaceArea[v];
            }
            impl.emitted /= impl.outputScale;
        }
    }
    mIteration.addSeconds(
        std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
}

CloudTransfer::~CloudTransfer() = default;

const DirectionSet&
CloudTransfer::directions() const
{
    return mImpl->schedule->directions();
}

Coord
CloudTransfer::periodicCopies(const Cloud& cloud, const CloudTransferOptions& options)
{
    if (!options.periodic || options.minPeriod == 0) return Coord(1);
    return copiesFor(cloud, options, DirectionSet::fromCount(directionCount(options)).size());
}

int
CloudTransfer::phaseOrderFor(const CloudTransferOptions& options)
{
    if (options.phase.isIsotropic()) return 0;
    if (options.phaseOrder >= 0) return options.phaseOrder;
    int order = 8;
    while (order < 16 && std::abs(options.phase.chi(order + 1)) > 0.17) ++order;
    return order;
}

int
CloudTransfer::directionCount(const CloudTransferOptions& options)
{
    if (options.directions != 0) return options.directions;
    if (options.phase.isIsotropic() || std::abs(options.phase.asymmetry()) <= 0.5) return 300;
    const double k = phaseOrderFor(options) / 10.0;
    return int(std::lround(2000.0 * k * k));
}

Acceleration
CloudTransfer::chooseAcceleration(const Cloud& cloud, const CloudTransferOptions& options)
{
    if (options.accelerate) return *options.accelerate;
    // The thickest column's optical thickness along the vertical and the largest albedo, both
    // delta-M scaled as the sweeps see them.
    const int order = phaseOrderFor(options);
    const double f = options.phase.truncate(order).f, h = cloud.voxelSize();
    std::unordered_map<Coord, double> column;
    double omegaMax = 0.0, tauMax = 0.0;
    for (size_t i = 0; i < cloud.size(); ++i) {
        Coord c = cloud.voxels().coord(i);
        c[options.up] = 0;
        const double w = channelOf(cloud.albedo(), i, options.channel), scaled = 1.0 - w * f;
        double& tau = column[c];
        tau += double(cloud.extinction(i)) * h * scaled;
        tauMax = std::max(tauMax, tau);
        if (scaled > 0.0) omegaMax = std::max(omegaMax, w * (1.0 - f) / scaled);
    }
    if (!std::isfinite(tauMax)) return Acceleration::Anderson;
    // A ground of albedo rho sends back up rho times what the cloud lets through, and the cloud
    // reflects about that same fraction of it down again: one more loop, at most rho s.
    const double cloudAlone = omegaMax * tauMax / (tauMax + 2.0);
    const double rho = options.groundAlbedo.value_or(0.0);
    double slowest = cloudAlone + (1.0 - cloudAlone) * rho * cloudAlone;
    // Surfaces facing each other (a room) pass light back and forth: their albedo is the loop.
    if (options.surfaces) {
        const Attribute& a = options.surfaces->albedo();
        for (size_t s = 0; s < options.surfaces->size(); ++s) {
            slowest = std::max(slowest, double(channelOf(a, s, options.channel)));
        }
    }
    return slowest > 0.5 ? Acceleration::Anderson : Acceleration::None;
}

Coord
CloudTransfer::copiesFor(const Cloud& cloud, const CloudTransferOptions& options, size_t dirs)
{
    if (!options.periodic || options.minPeriod == 0 || cloud.size() == 0) return Coord(1);
    // Mean optical depth per voxel of the box (empty cells count as clear air).
    const Coord dim = cloud.voxels().bbox().dim();
    double depth = 0.0;
    for (float e : cloud.extinctionArray()) depth += double(e);
    depth *= cloud.voxelSize() / (double(dim.x()) * double(dim.y()) * double(dim.z()));
    return PeriodicBoundary::copies(dim, options.up, options.minPeriod, dirs, depth);
}

void
CloudTransfer::Impl::sweepBatch(const CloudTransfer& t, int g, const size_t* dirs, size_t count,
    Sweep& sw) const
{
    const size_t M = size_t(this->M), p = SweepSchedule::patternOf(g);
    Batch& batch = batches.local();
    const size_t W = batch.width = 2 * count, H = M - 1;
    if (M > 1) {
        // The harmonics l >= 1 of the batch's columns, both ways round: H x W for the sources,
        // W x H for the moments.
        batch.Yt.resize(2 * H * W);
        float* Yt = batch.Yt.data();
        float* Y = Yt + H * W;
        for (size_t k = 0; k < W; ++k) {
            const float* y = &phase.harmonics[(2 * dirs[k / 2] + k % 2) * M + 1];
            for (size_t h = 0; h < H; ++h) Yt[h * W + k] = Y[k * H + h] = y[h];
        }
        const std::vector<float>& S = sw.S[p];
        batch.R.resize(n * W);
        batch.Lbar.assign(n * W, 0.f);
        for (size_t x = 0; x < n; ++x) {
            rowTimesMatrix(&S[x * M + 1], Yt, H, W, W, &batch.R[x * W], false);
        }
    }
    for (size_t j = 0; j < count; ++j) sweepDirection(t, g, dirs[j], 2 * j, batch, sw);
    if (M > 1) {
        // G[x, lm] += sum over columns of Lbar[x, k] Y_lm(k), l >= 1.
        std::vector<float>& G = sw.G[size_t(g)];
        const float* Y = batch.Yt.data() + H * W;
        for (size_t x = 0; x < n; ++x) {
            rowTimesMatrix(&batch.Lbar[x * W], Y, W, H, H, &G[x * M + 1], true);
        }
    }
}

// Direction d of group g, both senses, columns @a column and @a column + 1 of @a batch: the
// pass with the sources, then (periodic) the passes of the light wrapping around the period.
void
CloudTransfer::Impl::sweepDirection(const CloudTransfer& t, int g, size_t d, size_t column,
    Batch& batch, Sweep& sw) const
{
    const size_t p = SweepSchedule::patternOf(g), M = size_t(this->M);
    const SweepSchedule::Pattern& pattern = schedule->pattern(p);
    const std::vector<float>& S = sw.S[p];
    const std::vector<float>& B = sw.B[p];
    const float* E = sw.E[p].empty() ? nullptr : sw.E[p].data();
    const std::vector<float>& kappaP = kappaOrdered[p];
    std::vector<float>& G = sw.G[size_t(g)];
    std::array<double, 2>& escaped = sw.escaped[size_t(g)];
    const int up = t.mOptions.up;
    // The line swept (the direction's own, or its projection across flat axes), its step in
    // voxels and its tube's etendue (cross-section 1 / step voxel faces times the solid angle
    // of one orientation).
    const SweptLine line = sweptLine(schedule->directions().direction(d), flat);
    const Coord& sigma = line.sigma;
    const Vec3d& unit = line.unit;
    const float step = line.step;
    const float omega = float(kPi * schedule->directions().factor(d));
    const double etendue = double(omega) / double(step);
    // Periodic: power entering each side face per layer (what left the opposite face), and
    // what leaves this pass.
    const PeriodicBoundary* periodic = boundary.get();
    std::vector<double> entry, exits;
    // The lines' keys, centred on the box: used only to find the side faces they cross.
    const LinePartition part = periodic ? periodic->partition(sigma)
                                        : LinePartition(sigma, LineType::Naive);
    if (periodic) {
        entry.assign(leftFace.begin() + long(periodic->slice(d)),
            leftFace.begin() + long(periodic->slice(d) + periodic->sliceSize()));
        exits.assign(periodic->sliceSize(), 0.0);
    }
    const float beamT[2] = {phase.beam[2 * d], phase.beam[2 * d + 1]};
    const float* yAcc[2] = {&phase.harmonics[2 * d * M], &phase.harmonics[(2 * d + 1) * M]};
    LineSweep::Lanes<Ray>& work = lanes.local();
    const bool linear = t.mOptions.source == VoxelSource::Linear;
    const int major = part.majorAxis();
    // The ground (Ground.h): where light lands, and per unit of reflected power the radiance
    // the upward sense gains (the downward sense and horizontal lines gain nothing).
    const GroundLayer* layer = ground ? &*ground : nullptr;
    std::vector<double>* landed = layer ? &sw.landed[size_t(g)] : nullptr;
    const bool upward[2] = {unit[up] > 0.0, unit[up] < 0.0};
    const double gain = layer ? groundGain[d] : 0.0;
    // Light going down from voxel c along t onto the ground cell under it: wrapped around a
    // periodic box, missed (false) outside an open one's.
    auto land = [&](const Coord& c, const Vec3d& t, double power) {
        const int64_t cell = layer->cellBelow(c.asVec3d(), t, periodic != nullptr);
        if (cell < 0) return false;
        (*landed)[size_t(cell)] += power;
        return true;
    };
    // Surfaces (FogSurfaces.h): the rule at surface voxel v (passed over where the line runs
    // along it); a run of senders sends in the pass with the sources only.
    const std::vector<uint32_t>* surfaceP = surfaces ? &surfaceOrdered[p] : nullptr;
    std::vector<double>* onSurface = surfaces ? &sw.onSurface[size_t(g)] : nullptr;
    double& backs = sw.backs[size_t(g)];
    bool sending = true;
    auto sent = [&](uint32_t u) { return sending ? float(sw.surfaceEmits[u]) : 0.f; };
    // The line leaves surfaces: a run of senders sends; so does a receiver that the medium
    // voxel @a x (null: the line's end) follows right after (the mirror of a sender taking
    // what comes from the medium just before it).
    auto endRun = [&](Ray& ray, const uint32_t* x) {
        if (ray.run != FogSurfaces::kNone) {
            ray.radiance = sent(ray.run);
        } else if (ray.receiving && x && lineNeighbours(*pattern.sweep, major, *x, ray.last)) {
            ray.radiance = sent((*surfaceP)[ray.last]);
        }
        ray.run = FogSurfaces::kNone;
        ray.receiving = false;
    };
    auto visitSurface = [&](Ray& ray, uint32_t x, uint32_t v, bool forward) {
        const double c = senseCosine(unit, forward, surfaces->normal(v));
        if (c == 0.0) return;
        const bool adjacent = lineNeighbours(*pattern.sweep, major, x, ray.last);
        if (meetSurface(ray, v, c, adjacent, etendue, sent, backs)) {
            (*onSurface)[v] += double(ray.radiance) * etendue;
            ray.radiance = 0.f;
        }
        ray.last = x;
        ray.pending = false;
    };
    // The pending voxel of @a ray, its source rising by the slope from the one before it and
    // @a after (the next one's source, null at a gap or the line's end): its moments, and the
    // radiance that leaves it. Compiled apart for a constant source (Lin false), which is then
    // finished in place, at the constant scheme's cost.
    // The first pass's forward sense computes each voxel's exponential (every voxel is finished
    // once per sense and pass); the rest read it.
    std::vector<double>& absorbed = batch.absorbed;
    if (absorbed.size() < n) absorbed.resize(n);
    bool computing = true;
    auto finish = [&](auto lin, Ray& ray, float s, float r, float b, size_t sense,
                      const float* after) {
        const uint32_t x = ray.last;
        const float tau = kappaP[x] * step;
        float absorb, mean, perTau = 0.f, slope = 0.f, gain = 0.f;
        if constexpr (decltype(lin)::value) {
            slope = sourceSlope(s, ray.hasBefore ? &ray.before : nullptr, after);
        }
        double a = 0.0;
        if (tau > kExponentialDepth) {
            if (computing) absorbed[x] = absorbedFraction(tau);
            a = absorbed[x];
        }
        if (slope != 0.f) gain = linearSourceGain(tau, a, perTau, absorb, mean);
        else stepFactors(tau, a, absorb, mean);
        const float* y = yAcc[sense];
        const float L = ray.radiance;
        // Mean over the step: s + (L - s) f - slope h / tau. I_00 gathers only
        // b + (L - b - r) f - slope h / tau; iterate() adds the rest, s0 (1 - f) + r, summed
        // over the directions in closed form (the self-scattering elimination), so that an
        // opaque voxel's I_00 is not a small difference of floats.
        const float rest = omega * (b + (L - b - r) * mean - slope * perTau);
        G[size_t(x) * M] += rest * y[0];
        if (M > 1) {
            // The higher moments: sweepBatch() multiplies this out.
            batch.Lbar[size_t(x) * batch.width + column + sense]
                += omega * (s + (L - s) * mean - slope * perTau);
        }
        ray.radiance = L + (s - L) * absorb + slope * gain;
        ray.pending = false;
    };
    // A pass without sources (light wrapping a periodic box) has nothing to slope.
    auto pass = [&](bool sources, auto lin) {
        sending = sources;
        std::fill(exits.begin(), exits.end(), 0.0);
        pattern.sweep->walk(sigma, schedule->reversed(d), work,
            [&](uint32_t x, Ray& ray, bool forward) {
                if (!ray.started) {
                    ray.started = true;
                    if (periodic) {
                        const int at = periodic->entering(part, sigma, pattern.sweep->coord(x),
                            forward ? unit : -unit, forward);
                        if (at >= 0) {
                            const uint32_t c = periodic->enterCount(d, size_t(at));
                            ray.radiance = float(entry[size_t(at)] / c / etendue);
                        }
                    }
                }
                // An isolated line holds one voxel: nothing comes in from the one before.
                if (line.isolated) ray.radiance = 0.f;
                const size_t sense = forward ? 0 : 1;
                if (layer && layer->contains(pattern.sweep->coord(x))) {
                    // A ground cell: the voxel before it (going down) ends at a gap; light
                    // going up gathers what the cell reflects (once per sweep: not in the
                    // wrap passes), light going down stays.
                    if constexpr (decltype(lin)::value) {
                        if (ray.pending) finish(lin, ray, ray.s, ray.r, ray.b, sense, nullptr);
                        ray.hasBefore = false;
                    }
                    const size_t cell = layer->cell(pattern.sweep->coord(x));
                    if (upward[sense]) {
                        if (sources) ray.radiance += float(sw.groundEmits[cell] * gain);
                    } else {
                        (*landed)[cell] += double(ray.radiance) * etendue;
                        ray.radiance = 0.f;
                    }
                    ray.last = x;
                    ray.pending = false;
                    return;
                }
                if (surfaceP) {
                    const uint32_t v = (*surfaceP)[x];
                    if (v != FogSurfaces::kNone) {
                        if constexpr (decltype(lin)::value) {
                            if (ray.pending) {
                                finish(lin, ray, ray.s, ray.r, ray.b, sense, nullptr);
                            }
                            ray.hasBefore = false;
                        }
                        visitSurface(ray, x, v, forward);
                        return;
                    }
                    endRun(ray, &x);
                    ray.medium = true;
                }
                const float* y = yAcc[sense];
                // The source: its isotropic part s0, its higher moments' part r and the beam's
                // first scattering b.
                float s0 = 0.f, r = 0.f, b = 0.f;
                if (sources) {
                    s0 = S[size_t(x) * M] * y[0];
                    if (M > 1) r = batch.R[size_t(x) * batch.width + column + sense];
                    b = B[x] * beamT[sense];
                    if (E) b += E[x];   // isotropic, fixed: gathered whole, as the beam's
                }
                const float s = s0 + r + b;
                if constexpr (decltype(lin)::value) {
                    bool adjacent = false;
                    if (ray.pending) {
                        // Neighbours along the line: one step apart on its major axis (no gap).
                        adjacent = lineNeighbours(*pattern.sweep, major, x, ray.last);
                        finish(lin, ray, ray.s, ray.r, ray.b, sense, adjacent ? &s : nullptr);
                        ray.before = ray.s;
                    }
                    ray.hasBefore = adjacent;
                    ray.pending = true;
                    ray.s = s;
                    ray.r = r;
                    ray.b = b;
                }
                ray.last = x;
                if constexpr (!decltype(lin)::value) finish(lin, ray, s, r, b, sense, nullptr);
            },
            [&](const Ray* fronts, size_t lines, bool forward) {
                const Vec3d dir = forward ? unit : -unit;
                for (size_t l = 0; l < lines; ++l) {
                    Ray ray = fronts[l];
                    if constexpr (decltype(lin)::value) {
                        if (ray.pending) {
                            finish(lin, ray, ray.s, ray.r, ray.b, forward ? 0 : 1, nullptr);
                        }
                    }
                        if (surfaceP) {
                        // A run that ends the line sends out of the box, unless it faces a
                        // closed cavity (FogSurfaces.h).
                        if (ray.run != FogSurfaces::kNone && enclosed[ray.run]) {
                            ray.run = FogSurfaces::kNone;
                        }
                        endRun(ray, nullptr);
                    }
                    // (An isolated line's tube has no cross-section: nothing leaves it.)
                    if (!ray.started || ray.radiance == 0.f || line.isolated) continue;
                    const double power = double(ray.radiance) * etendue;
                    if (periodic) {
                        const int at = periodic->leaving(part, sigma,
                            pattern.sweep->coord(ray.last), dir, forward);
                        if (at >= 0) { exits[size_t(at)] += power; continue; }
                    }
                    if (dir[up] == 0.0) {
                        escaped[0] += 0.5 * power;
                        escaped[1] += 0.5 * power;
                    } else if (dir[up] < 0.0 && layer
                        && land(pattern.sweep->coord(ray.last), dir, power)) {
                        // A line that ends above the ground without crossing its layer (at
                        // the bound of a centred partition's central line): on the cell where
                        // it meets the layer.
                    } else {
                        escaped[dir[up] > 0.0 ? 1 : 0] += power;
                    }
                }
                if (forward) computing = false;
            });
    };
    if (linear) pass(true, std::true_type());
    else pass(true, std::false_type());
    if (periodic && !line.isolated) {
        periodic->followWraps(d, periodic->rise(schedule->directions(), d), unit[up], entry,
            exits, [&] { pass(false, std::false_type()); }, &sw.leftNow[periodic->slice(d)], escaped);
    }
}

std::vector<double>
CloudTransfer::Impl::surfaceAreas() const
{
    // Per group, then added in a fixed order: the same bits for any thread count.
    const size_t count = surfaces->size();
    std::array<std::vector<double>, kGroups> parts;
    const SweepProgress progress(nullptr, schedule->directions().size());
    schedule->forEachGroup(progress, "surface areas", [](int) { return true; }, [&](int g) {
        const size_t p = SweepSchedule::patternOf(g);
        const SweepSchedule::Pattern& pattern = schedule->pattern(p);
        const std::vector<uint32_t>& surfaceP = surfaceOrdered[p];
        std::vector<double>& area = parts[size_t(g)];
        area.assign(count, 0.0);
        LineSweep::Lanes<Ray>& work = lanes.local();
        double backs = 0.0;
        auto none = [](uint32_t) { return 0.f; };
        schedule->forDirections(g, [&](size_t d) {
            const SweptLine line = sweptLine(schedule->directions().direction(d), flat);
            const double etendue = double(float(kPi * schedule->directions().factor(d)))
                / double(line.step);
            const int major = LinePartition(line.sigma, LineType::Naive).majorAxis();
            pattern.sweep->walk(line.sigma, schedule->reversed(d), work,
                [&](uint32_t x, Ray& ray, bool forward) {
                    const uint32_t v = surfaceP[x];
                    if (v == FogSurfaces::kNone) {
                        ray.run = FogSurfaces::kNone;
                        ray.receiving = false;
                        ray.medium = true;
                    } else {
                        const double c = senseCosine(line.unit, forward, surfaces->normal(v));
                        if (c == 0.0) return;
                        const bool adjacent = ray.started
                            && lineNeighbours(*pattern.sweep, major, x, ray.last);
                        // A line's first voxel receives from outside the box: not where it
                        // faces a closed cavity (the mirror of the sweep's rule at line ends).
                        if (meetSurface(ray, v, c, adjacent, etendue, none, backs)
                            && (ray.started || !enclosed[v])) {
                            area[v] += etendue;
                        }
                    }
                    ray.started = true;
                    ray.last = x;
                },
                [](const Ray*, size_t, bool) {});
        });
    });
    std::vector<double> A(count, 0.0);
    for (const std::vector<double>& part : parts) {
        for (size_t v = 0; v < part.size(); ++v) A[v] += part[v];
    }
    for (size_t v = 0; v < count; ++v) A[v] = surfaceNorm[v] > 0.0 ? A[v] / surfaceNorm[v] : 0.0;
    return A;
}

double
CloudTransfer::iterate(openvdb::util::NullInterrupter* interrupt)
{
    return mIteration.iterate([&] { return sweep(interrupt); });
}

double
CloudTransfer::sweep(openvdb::util::NullInterrupter* interrupt)
{
    Impl& impl = *mImpl;
    const SweepSchedule& schedule = *impl.schedule;
    const size_t n = impl.n;

    // Source per voxel: omega0 chi_l times the moments of the diffuse radiance, so that
    // S(s) = sum_lm c_lm Y_lm(s), plus the beam's first scattering omega0 J_beam T(s).
    const size_t M = size_t(impl.M);
    const std::vector<double>& quadratureMean = impl.phase.quadratureMean;
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
                    total += c[size_t(lm)] * quadratureMean[size_t(lm)];
                }
            }
            // The direction set integrates this source to 4 pi x total, not exactly to its
            // isotropic part (the scattered power): scale it to that, keeping its angular shape.
            // (Subtracting each harmonic's quadrature mean instead would spread the error
            // evenly over all directions: a forward peak then leaks into backscatter, +30%
            // slab albedo at order 16.)
            const double target = c[0] * quadratureMean[0];
            const double alpha = total > 0.0 ? target / total : 1.0;
            for (size_t lm = 0; lm < M; ++lm) source[i * M + lm] = float(alpha * c[lm]);
            if (M > 1) isoExcess[i] = total > 0.0 ? (target - total) / total * c[0] : 0.0;
            beamSource[i] = impl.omega[i] * impl.beamJ[i];
        }
    });
    // The sources in each pattern's order, so that the sweeps read them sequentially.
    std::array<std::vector<float>, SweepSchedule::kPatterns> S, B, E;
    for (size_t p = 0; p < S.size(); ++p) {
        if (schedule.pattern(p).empty()) continue;
        schedule.toPatternOrder(p, source, S[p], M);
        schedule.toPatternOrder(p, beamSource, B[p]);
        if (!impl.emitSource.empty()) schedule.toPatternOrder(p, impl.emitSource, E[p]);
    }
    // What each ground cell reflects in this sweep: its albedo times what reached it.
    const size_t cells = impl.groundDiffuse.size();
    std::vector<double> emits(cells);
    for (size_t c = 0; c < cells; ++c) {
        emits[c] = impl.groundAlbedo * (impl.groundDirect[c] + impl.groundDiffuse[c]);
    }
    // What each surface voxel sends in this sweep, over Z_v: its emission and its albedo times
    // what reached its front.
    const size_t surfaceCount = impl.surfaceLanded.size();
    std::vector<double> surfaceEmits(surfaceCount);
    for (size_t v = 0; v < surfaceCount; ++v) surfaceEmits[v] = impl.surfaceSends(v);
    Impl::Sweep sw{S, B, E, emits, {}, {}, std::vector<double>(impl.leftFace.size(), 0.0), {},
        surfaceEmits, {}, {}};
    // Under MPI each rank sweeps its own groups (Distribution.h).
    const Distribution& ranks = Distribution::orAlone(mOptions.ranks, impl.alone);
    auto mine = [&](int g) { return ranks.owns(g); };
    SweepProgress progress(interrupt, schedule.directionsOf(mine));
    const size_t perBatch = Impl::batchSize(n, M);
    schedule.forEachGroup(progress, "cloud transfer", mine, [&](int g) {
        sw.G[size_t(g)].assign(n * M, 0.f);
        sw.landed[size_t(g)].assign(cells, 0.0);
        sw.onSurface[size_t(g)].assign(surfaceCount, 0.0);
        std::vector<size_t> dirs;
        schedule.forDirections(g, [&](size_t d) { dirs.push_back(d); });
        for (size_t b = 0; b < dirs.size() && !progress.cancelled(); b += perBatch) {
            const size_t count = std::min(perBatch, dirs.size() - b);
            impl.sweepBatch(*this, g, &dirs[b], count, sw);
            progress.finished(count);
        }
    });

    if (ranks.distributed()) {
        // Every group's results from its owner (the light wrapping a periodic box: one slice
        // per direction, written by its owner alone), then summed as one process does.
        for (int g = 0; g < SweepSchedule::kGroups; ++g) {
            if (schedule.patternOfGroup(g).empty()) continue;
            const int owner = ranks.ownerOf(g);
            ranks.share(sw.G[size_t(g)], n * M, owner);
            ranks.share(sw.landed[size_t(g)], cells, owner);
            ranks.share(sw.onSurface[size_t(g)], surfaceCount, owner);
            ranks.share(sw.escaped[size_t(g)].data(), sizeof(double) * 2, owner);
            ranks.share(&sw.backs[size_t(g)], sizeof(double), owner);
        }
        ranks.combine(sw.leftNow);
    }
    // Moments from the groups, in a fixed order (bit-identical for any thread count).
    std::vector<double> sum(n * M, 0.0);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, n), [&](const tbb::blocked_range<size_t>& r) {
        for (size_t i = r.begin(); i != r.end(); ++i) schedule.sum(sw.G, i, M, &sum[i * M]);
    });
    // The state this sweep started from, for the Anderson step below: the moments and, with
    // periodic boundaries, the light carried across the side faces (in a thin periodic slab
    // light wraps many times, and that carry-over is then the slowest mode).
    std::vector<float> x;
    if (impl.mixer) {
        x = impl.moments;
        x.insert(x.end(), impl.leftFace.begin(), impl.leftFace.end());
        x.insert(x.end(), impl.groundDiffuse.begin(), impl.groundDiffuse.end());
        x.insert(x.end(), impl.surfaceLanded.begin(), impl.surfaceLanded.end());
    }
    // Light that reached the ground, the groups added in a fixed order.
    std::vector<double> landed(cells, 0.0);
    for (const std::vector<double>& part : sw.landed) {
        for (size_t c = 0; c < cells; ++c) landed[c] += part[c];
    }
    // Self-scattering elimination. Of what a voxel scatters isotropically, the fraction
    // 1 - M_v is extinguished again in the voxel itself: the sweep maps I_00 to
    // swept = rest + alpha c_v I_00 + (1 - alpha) omega0 I_00 (the second term s0 (1 - f), the
    // third the quadrature of r: alpha makes the higher moments integrate to
    // (1 - alpha) times the isotropic source), with c_v = omega0 (1 - M_v). In an opaque
    // conservative voxel that local mode decays like c_v ~ 1 - 1 / tau per sweep. Solving the
    // local term exactly,
    //     I_00' = (swept - c_v I_00) / (1 - c_v)
    //           = (rest - (alpha - 1) omega0 M_v I_00) / (1 - c_v),
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
    // The ground's reflected radiance, rho E / pi, is an unknown as J is.
    double onGround = 0.0, directOnGround = 0.0;
    for (size_t c = 0; c < cells; ++c) {
        const double k = impl.groundAlbedo / kPi;
        maxChange = std::max(maxChange, k * std::abs(landed[c] - impl.groundDiffuse[c]));
        maxJ = std::max(maxJ, k * (impl.groundDirect[c] + landed[c]));
        onGround += impl.groundDirect[c] + landed[c];
        directOnGround += impl.groundDirect[c];
    }
    impl.groundDiffuse = landed;
    // The surfaces' radiosity, B / pi = (E A + rho (direct + landed)) / (A pi) at each voxel,
    // is an unknown too; their backs absorb what reaches them.
    double surfaceAbsorbed = impl.backDirect;
    {
        std::vector<double> onSurface(surfaceCount, 0.0);
        for (int g = 0; g < SweepSchedule::kGroups; ++g) {
            const std::vector<double>& part = sw.onSurface[size_t(g)];
            for (size_t v = 0; v < surfaceCount; ++v) onSurface[v] += part[v];
            surfaceAbsorbed += sw.backs[size_t(g)];
        }
        for (size_t v = 0; v < surfaceCount; ++v) {
            const double rho = impl.surfaces->albedo(v), reached = impl.surfaceDirect[v] + onSurface[v];
            surfaceAbsorbed += (1.0 - rho) * reached;
            if (!(impl.surfaceArea[v] > 0.0)) continue;
            const double perB = 1.0 / (kPi * impl.surfaceArea[v]);
            maxChange = std::max(maxChange, rho * perB * std::abs(onSurface[v] - impl.surfaceLanded[v]));
            maxJ = std::max(maxJ, double(impl.surfaces->emission(v)) / (kPi * impl.outputScale)
                + rho * perB * reached);
        }
        impl.surfaceLanded = std::move(onSurface);
    }

    if (impl.boundary) impl.leftFace.swap(sw.leftNow);
    if (impl.mixer) {
        // The next sweep starts from the mixed state; J follows it, so that the next residual
        // measures that sweep's change and the output is the mixed iterate. A mixed state with
        // negative mean radiance or carried power is refused (the plain step is kept).
        std::vector<float> gx = impl.moments;
        gx.insert(gx.end(), impl.leftFace.begin(), impl.leftFace.end());
        gx.insert(gx.end(), impl.groundDiffuse.begin(), impl.groundDiffuse.end());
        gx.insert(gx.end(), impl.surfaceLanded.begin(), impl.surfaceLanded.end());
        andersonStep(*impl.mixer, x.data(), gx.data(), [&](const float* v) {
            for (size_t i = 0; i < n; ++i) if (!(v[i * M] >= 0.f)) return false;
            for (size_t k = n * M; k < gx.size(); ++k) if (!(v[k] >= 0.f)) return false;
            return true;
        });
        const auto faces = gx.begin() + long(n * M), lands = faces + long(impl.leftFace.size());
        const auto onSurfaces = lands + long(cells);
        std::copy(gx.begin(), faces, impl.moments.begin());
        std::copy(faces, lands, impl.leftFace.begin());
        std::copy(lands, onSurfaces, impl.groundDiffuse.begin());
        std::copy(onSurfaces, gx.end(), impl.surfaceLanded.begin());
        for (size_t i = 0; i < n; ++i) impl.diffuseJ[i] = float(double(impl.moments[i * M]) * y00);
    }
    // Light leaving the box, added in a fixed order: pattern by pattern, then its two halves
    // (the order these double sums had before the groups were numbered as SweepSchedule
    // numbers them, so that the budget kept its bits).
    double up0 = 0.0, down0 = 0.0;
    for (int p = 0; p < SweepSchedule::kPatterns; ++p) {
        for (int half = 0; half < SweepSchedule::kGroups / SweepSchedule::kPatterns; ++half) {
            const size_t g = size_t(half * SweepSchedule::kPatterns + p);
            const std::array<double, 2>& e = sw.escaped[g];
            down0 += e[0];
            up0 += e[1];
        }
    }
    const double total = impl.incident + impl.emitted + impl.mediumEmitted;
    const double in = total > 0.0 ? total : 1.0;
    mBudget.incident = total * impl.outputScale;
    mBudget.emitted = (impl.emitted + impl.mediumEmitted) / in;
    mBudget.mediumEmitted = impl.mediumEmitted / in;
    mBudget.surfaceAbsorptance = surfaceAbsorbed / in;
    mBudget.albedo = up0 / in;
    mBudget.transmittance = (down0 + impl.directOut + onGround) / in;
    mBudget.directTransmittance = (impl.directOut + directOnGround) / in;
    mBudget.absorptance = absorbed / in;
    mBudget.groundReflected = impl.groundAlbedo * onGround / in;
    return maxJ > 0.0 ? maxChange / maxJ : 0.0;
}

void
CloudTransfer::solve(openvdb::util::NullInterrupter* interrupt)
{
    while (!finished()) iterate(interrupt);
}

size_t
CloudTransfer::memoryEstimate(const Cloud& cloud, const CloudTransferOptions& options,
    int threads)
{
    const Coord copies = periodicCopies(cloud, options);
    const size_t tiles = size_t(copies.x()) * size_t(copies.y()) * size_t(copies.z());
    // A ground adds a layer of voxels under the copies' footprint.
    size_t footprint = 0;
    if (options.groundAlbedo) {
        const Coord dim = cloud.voxels().bbox().dim();
        footprint = 1;
        for (int k = 0; k < 3; ++k) {
            if (k != options.up) footprint *= size_t(dim[k]) * size_t(copies[k]);
        }
    }
    const size_t surfaces = options.surfaces ? options.surfaces->size() : 0;
    const size_t n = cloud.size() * tiles + footprint + surfaces;
    const size_t t = size_t(std::max(threads, 1));
    const int order = phaseOrderFor(options);
    const size_t M = size_t(order + 1) * size_t(order + 1);
    const bool anderson = chooseAcceleration(cloud, options) == Acceleration::Anderson;
    size_t perVoxel = 4 + 4 + 4 + 8 + 4;            // kappa, omega, beam J, deposit, diffuse J
    perVoxel += 8 + (M > 1 ? 8 : 0);                // escape factor, alpha's excess of I_00
    perVoxel += SweepSchedule::bytesPerVoxel(true, false, false);   // orders, layouts
    perVoxel += 4 * 4;                              // kappa in each pattern's order
    perVoxel += 4 * M + 4 * M + 4;                  // moments, their source, the beam's source
    perVoxel += 4 * (4 * M + 4);                    // the sources in each pattern's order
    if (!cloud.emission().isZero()) perVoxel += 4 + 4 * 4;   // emission's source, and ordered
    perVoxel += size_t(Impl::kGroups) * 4 * M;      // gathered moments per group
    perVoxel += 8 * M;                              // their double sum
    perVoxel += t * (4 + 16 + 8);                   // per thread: slots, line state, 1 - e^-tau
    if (M > 1) perVoxel += t * 2 * 2 * 4 * Impl::batchSize(n, M);   // a batch's two matrices
    if (anderson) {
        perVoxel += 8 * M + AndersonMixer::bytes(M, options.andersonDepth);   // + x, G(x)
    }
    // The copies of a narrow periodic box, or the ground's layer added: coordinates,
    // extinction, the voxel copied, index.
    if (tiles > 1 || footprint > 0 || surfaces > 0) perVoxel += 12 + 4 + 4 + 8;
    size_t bytes = n * perVoxel;
    // Surfaces: the voxel each solved one is (in each pattern's order too), and per surface
    // voxel its normal, albedo, area, emission, Z, direct and landed power, per group what lands.
    if (surfaces > 0) {
        bytes += n * 4 * 5 + surfaces * (12 + 4 + 8 * 5 + 8 * size_t(Impl::kGroups)
            + (anderson ? 8 : 0));
        if (anderson) bytes += AndersonMixer::bytes(surfaces, options.andersonDepth);
    }
    if (options.periodic) {
        // Light carried across the side faces: per direction, sense, face and layer, twice.
        const openvdb::CoordBBox box = cloud.voxels().bbox();
        const size_t layers = size_t(box.dim()[options.up]);   // copies stack sideways only
        const size_t dirs = DirectionSet::fromCount(directionCount(options)).size();
        const size_t faces = dirs * 2 * 6 * layers;
        bytes += faces * (8 + 8 + PeriodicBoundary::kBytesPerSlot);
        if (anderson) {
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
    h = hashBytes(impl.phase.beam.data(), impl.phase.beam.size() * sizeof(float), h);
    const int64_t options[13] = {int64_t(directions().size()), mOptions.periodic ? 1 : 0,
        phaseOrderFor(mOptions), int64_t(*mOptions.accelerate), mOptions.andersonDepth, mOptions.up,
        impl.M, mCopies.x(), mCopies.y(), mCopies.z(), int64_t(mOptions.source),
        mQuadratureDegree, impl.flat[0] + 2 * impl.flat[1] + 4 * impl.flat[2]};
    h = hashBytes(options, sizeof options, h);
    if (impl.ground) h = hashBytes(&impl.groundAlbedo, sizeof(double), h);
    if (impl.surfaces) h = impl.surfaces->hash(h);
    h = hashBytes(impl.emitSource.data(), impl.emitSource.size() * sizeof(float), h);
    return h;
}

void
CloudTransfer::saveState(SolverState& state) const
{
    const Impl& impl = *mImpl;
    mIteration.save(state);
    const double budget[5] = {mBudget.incident, mBudget.albedo, mBudget.transmittance,
        mBudget.directTransmittance, mBudget.absorptance};
    state.put("budget", budget, 5);
    state.put("diffuseJ", impl.diffuseJ);
    state.put("moments", impl.moments);
    state.put("leftFace", impl.leftFace);
    if (impl.ground) {
        state.put("groundDiffuse", impl.groundDiffuse);
        state.put("groundReflected", &mBudget.groundReflected, 1);
    }
    if (impl.surfaces) {
        state.put("surfaceLanded", impl.surfaceLanded);
        state.put("surfaceAbsorptance", &mBudget.surfaceAbsorptance, 1);
    }
    if (impl.mixer) impl.mixer->save(state, "anderson.");
}

void
CloudTransfer::restoreState(const SolverState& state)
{
    Impl& impl = *mImpl;
    mIteration.restore(state);
    const std::vector<double> budget = state.get<double>("budget", 5);
    impl.diffuseJ = state.get<float>("diffuseJ", impl.diffuseJ.size());
    impl.moments = state.get<float>("moments", impl.moments.size());
    impl.leftFace = state.get<double>("leftFace", impl.leftFace.size());
    if (impl.ground) {
        impl.groundDiffuse = state.get<double>("groundDiffuse", impl.groundDiffuse.size());
        mBudget.groundReflected = state.get<double>("groundReflected", 1)[0];
    }
    if (impl.surfaces) {
        impl.surfaceLanded = state.get<double>("surfaceLanded", impl.surfaceLanded.size());
        mBudget.surfaceAbsorptance = state.get<double>("surfaceAbsorptance", 1)[0];
    }
    const double emitted = impl.emitted + impl.mediumEmitted;
    mBudget.emitted = emitted > 0.0 ? emitted / (impl.incident + emitted) : 0.0;
    mBudget.mediumEmitted = emitted > 0.0 ? impl.mediumEmitted / (impl.incident + emitted) : 0.0;
    if (impl.mixer) impl.mixer->restore(state, "anderson.");
    mBudget.incident = budget[0];
    mBudget.albedo = budget[1];
    mBudget.transmittance = budget[2];
    mBudget.directTransmittance = budget[3];
    mBudget.absorptance = budget[4];
}

std::vector<float>
CloudTransfer::meanIntensity() const
{
    const Impl& impl = *mImpl;
    const double scale = impl.outputScale;
    std::vector<float> J(mCloud.size());
    if (!impl.solved) {
        for (size_t i = 0; i < J.size(); ++i) {
            J[i] = float(double(impl.diffuseJ[i] + impl.beamJ[i]) * scale);
        }
        return J;
    }
    // The mean over a voxel's copies (every voxel has the same number of them).
    std::vector<double> sum(J.size(), 0.0);
    for (size_t i = 0; i < impl.n; ++i) {
        if (impl.copyOf[i] == GroundLayer::kGround) continue;
        sum[impl.copyOf[i]] += double(impl.diffuseJ[i] + impl.beamJ[i]);
    }
    const double per = scale / (double(mCopies.x()) * double(mCopies.y()) * double(mCopies.z()));
    for (size_t i = 0; i < J.size(); ++i) J[i] = float(sum[i] * per);
    return J;
}

std::vector<float>
CloudTransfer::surfaceRadiosity() const
{
    const Impl& impl = *mImpl;
    if (!impl.surfaces) return {};
    std::vector<float> B(impl.surfaces->size());
    for (size_t v = 0; v < B.size(); ++v) {
        // A voxel no line reaches (no area) shows its emission.
        B[v] = impl.surfaceArea[v] > 0.0
            ? float(impl.surfaceSends(v) * impl.surfaceNorm[v] * impl.outputScale)
            : impl.surfaces->emission(v);
    }
    return B;
}

const std::vector<double>&
CloudTransfer::surfaceArea() const
{
    return mImpl->surfaceArea;
}

std::vector<float>
CloudTransfer::groundIrradiance() const
{
    const Impl& impl = *mImpl;
    if (!impl.ground) return {};
    // The given box's ground; a cell of the copies' ground is the one a period away from it.
    const openvdb::CoordBBox box = mCloud.voxels().bbox();
    const GroundLayer given(box, mOptions.up);
    const Coord dim = box.dim();
    std::vector<double> sum(given.size(), 0.0);
    for (size_t c = 0; c < impl.ground->size(); ++c) {
        Coord ijk = impl.ground->coord(c);
        for (int k = 0; k < 3; ++k) {
            if (k != mOptions.up) ijk[k] = box.min()[k] + (ijk[k] - box.min()[k]) % dim[k];
        }
        sum[given.cell(ijk)] += impl.groundDirect[c] + impl.groundDiffuse[c];
    }
    const double per = impl.outputScale / double(impl.ground->size() / given.size());
    std::vector<float> E(given.size());
    for (size_t c = 0; c < E.size(); ++c) E[c] = float(sum[c] * per);
    return E;
}

openvdb::FloatGrid::Ptr
CloudTransfer::groundGrid(const std::string& name) const
{
    const std::vector<float> E = groundIrradiance();
    if (E.empty()) return nullptr;
    const GroundLayer layer(mCloud.voxels().bbox(), mOptions.up);
    openvdb::FloatGrid::Ptr g = openvdb::FloatGrid::create(0.f);
    g->setTransform(mCloud.transform().copy());
    g->setName(name);
    openvdb::FloatGrid::Accessor acc = g->getAccessor();
    for (size_t c = 0; c < E.size(); ++c) acc.setValueOn(layer.coord(c), E[c]);
    g->insertMeta("vdbrad:ground_albedo", openvdb::FloatMetadata(float(mImpl->groundAlbedo)));
    g->insertMeta("vdbrad:up", openvdb::Int32Metadata(mOptions.up));
    g->insertMeta(meta::kIterations, openvdb::Int32Metadata(iterationCount()));
    g->insertMeta(meta::kVersion, openvdb::StringMetadata(VDBRAD_VERSION_STRING));
    return g;
}

openvdb::GridBase::Ptr
CloudTransfer::grid(const std::string& name) const
{
    openvdb::FloatGrid::Ptr g = arrayToGrid(mCloud.voxels(), meanIntensity(), mCloud.transform(),
        name);
    g->insertMeta("vdbrad:albedo", openvdb::FloatMetadata(float(mBudget.albedo)));
    g->insertMeta("vdbrad:transmittance", openvdb::FloatMetadata(float(mBudget.transmittance)));
    g->insertMeta("vdbrad:absorptance", openvdb::FloatMetadata(float(mBudget.absorptance)));
    if (mImpl->ground) {
        g->insertMeta("vdbrad:ground_reflected",
            openvdb::FloatMetadata(float(mBudget.groundReflected)));
    }
    g->insertMeta(meta::kIterations, openvdb::Int32Metadata(iterationCount()));
    g->insertMeta(meta::kResidual, openvdb::FloatMetadata(float(mIteration.lastResidual())));
    g->insertMeta(meta::kDirections, openvdb::Int32Metadata(int(directions().size())));
    g->insertMeta(meta::kSeconds, openvdb::FloatMetadata(float(mIteration.seconds())));
    g->insertMeta(meta::kVersion, openvdb::StringMetadata(VDBRAD_VERSION_STRING));
    return g;
}

std::string
CloudTransfer::describe() const
{
    std::ostringstream os;
    os << "cloud: " << withCommas(mCloud.size()) << " voxels, " << directions().size()
       << " directions (nearest to " << mOptions.directions << "), "
       << (mOptions.periodic ? "periodic" : "open") << " boundaries";
    if (mCopies != Coord(1)) {
        os << " (solved as " << mCopies.x() << " x " << mCopies.y() << " x " << mCopies.z()
           << " copies of the box)";
    }
    const FlatAxes& flat = mImpl->flat;
    if (flat[0] || flat[1] || flat[2]) {
        const char* axis = "xyz";
        os << " (one voxel deep along";
        for (int k = 0; k < 3; ++k) if (flat[size_t(k)]) os << ' ' << axis[k];
        os << ": swept across it)";
    }
    if (mOptions.phaseOrder > 0) os << ", phase order " << mOptions.phaseOrder;
    if (mQuadratureDegree > 0) {
        os << ", weights exact for harmonics to degree " << mQuadratureDegree;
    }
    if (mOptions.accelerate == Acceleration::Anderson) os << ", Anderson acceleration";
    if (mOptions.source == VoxelSource::Constant) os << ", constant source per voxel";
    if (mImpl->ground) os << ", over a Lambertian ground of albedo " << mImpl->groundAlbedo;
    if (mImpl->surfaces) {
        os << ", with " << withCommas(mImpl->surfaces->size()) << " surface voxels";
    }
    if (isRgb(mCloud, mOptions)) os << " (channel " << mOptions.channel << ")";
    return os.str();
}

namespace {

std::string
budgetLine(const CloudBudget& b, const CloudTransferOptions& options)
{
    std::ostringstream os;
    os << "albedo " << b.albedo << ", transmittance " << b.transmittance << " (direct "
       << b.directTransmittance << "), absorptance " << b.absorptance;
    if (options.groundAlbedo) os << ", reflected by the ground " << b.groundReflected;
    if (options.surfaces) {
        os << " (left the box), emitted by the surfaces " << b.emitted - b.mediumEmitted
           << ", absorbed by them " << b.surfaceAbsorptance;
    }
    if (b.mediumEmitted > 0.0) os << ", emitted by the medium " << b.mediumEmitted;
    os << "; balance " << b.balance();
    return os.str();
}

// iterateSolve(), framed as one progress step unless @a control reports each iteration.
void
iterateFramed(CloudTransfer& transfer, const SolveControl& control,
    openvdb::util::NullInterrupter* interrupt)
{
    const bool framed = interrupt && !control.beforeIteration;
    if (framed) interrupt->start("cloud transfer");
    iterateSolve(transfer, control, interrupt);
    if (framed) interrupt->end();
}

SolveStats
statsOf(const CloudTransfer& transfer)
{
    SolveStats stats;
    stats.directions = int(transfer.directions().size());
    stats.iterations = transfer.iterationCount();
    stats.residual = transfer.residuals().empty() ? 0.0 : transfer.residuals().back();
    stats.seconds = transfer.seconds();
    return stats;
}

// Colours (an RGB albedo of the medium or of the surfaces, RGB lamps): light of each colour
// travels alone, so each channel is its own transfer (the medium's work three times over).
openvdb::GridBase::Ptr
solveCloudRgb(const Cloud& cloud, const CloudTransferOptions& options,
    openvdb::util::NullInterrupter* interrupt, const SolveControl& control,
    openvdb::GridBase::Ptr* radiosity)
{
    if (!control.checkpoint.empty() || !control.resume.empty()) {
        OPENVDB_THROW(openvdb::ValueError, "checkpoints are not supported for an RGB cloud or "
            "surface scene (three solves, one per channel)");
    }
    const Scene* scene = options.surfaces;
    std::vector<openvdb::Vec3f> J(cloud.size()), B(scene ? scene->size() : 0);
    openvdb::Vec3f albedo, transmittance, absorptance;
    SolveStats stats;
    double residual = 0.0;
    for (int c = 0; c < 3; ++c) {
        CloudTransferOptions o = options;
        o.channel = c;
        CloudTransfer transfer(cloud, o, interrupt);
        iterateFramed(transfer, control, interrupt);
        const CloudBudget& b = transfer.budget();
        if (control.note) control.note("channel " + std::string(1, "rgb"[c]) + ": " + budgetLine(b, o));
        const std::vector<float> j = transfer.meanIntensity();
        const std::vector<float> r = scene ? transfer.surfaceRadiosity() : std::vector<float>();
        for (size_t i = 0; i < J.size(); ++i) J[i][c] = j[i];
        for (size_t v = 0; v < B.size(); ++v) B[v][c] = r[v];
        albedo[c] = float(b.albedo);
        transmittance[c] = float(b.transmittance);
        absorptance[c] = float(b.absorptance);
        const SolveStats s = statsOf(transfer);
        stats.directions = s.directions;
        stats.iterations = std::max(stats.iterations, s.iterations);
        residual = std::max(residual, s.residual);
        stats.seconds += s.seconds;
    }
    stats.residual = residual;
    if (radiosity) {
        radiosity->reset();
        if (scene) *radiosity = makeRadiosityGrid(*scene, B, stats);
    }
    openvdb::Vec3SGrid::Ptr g = arrayToGrid(cloud.voxels(), J, cloud.transform(),
        "mean_intensity");
    g->insertMeta("vdbrad:albedo", openvdb::Vec3SMetadata(albedo));
    g->insertMeta("vdbrad:transmittance", openvdb::Vec3SMetadata(transmittance));
    g->insertMeta("vdbrad:absorptance", openvdb::Vec3SMetadata(absorptance));
    g->insertMeta(meta::kIterations, openvdb::Int32Metadata(stats.iterations));
    g->insertMeta(meta::kResidual, openvdb::FloatMetadata(float(stats.residual)));
    g->insertMeta(meta::kDirections, openvdb::Int32Metadata(stats.directions));
    g->insertMeta(meta::kSeconds, openvdb::FloatMetadata(float(stats.seconds)));
    g->insertMeta(meta::kVersion, openvdb::StringMetadata(VDBRAD_VERSION_STRING));
    return g;
}

} // namespace

openvdb::GridBase::Ptr
solveCloud(const Cloud& cloud, const CloudTransferOptions& options,
    openvdb::util::NullInterrupter* interrupt, const SolveControl& control,
    openvdb::FloatGrid::Ptr* ground, openvdb::GridBase::Ptr* radiosity)
{
    if (isRgb(cloud, options)) {
        if (ground) ground->reset();
        return solveCloudRgb(cloud, options, interrupt, control, radiosity);
    }
    CloudTransfer transfer(cloud, options, interrupt);
    iterateFramed(transfer, control, interrupt);
    if (control.note) control.note(budgetLine(transfer.budget(), options));
    if (ground) *ground = transfer.groundGrid();
    if (radiosity) {
        radiosity->reset();
        if (options.surfaces) {
            *radiosity = makeRadiosityGrid(*options.surfaces, transfer.surfaceRadiosity(),
                statsOf(transfer));
        }
    }
    return transfer.grid();
}

} // namespace vdbrad
