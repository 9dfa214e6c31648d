// CloudTransferImpl: the cloud solver's state, shared by its translation units (internal, not
// installed): CloudTransfer.cc builds and reads it, CloudSweeps.cc sweeps it, SolveCloud.cc
// runs whole solves.
#pragma once

#include "vdbrad/cloud/CloudTransfer.h"

#include "vdbrad/cloud/DiffusionAcceleration.h"
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

// Channel @a c of voxel @a i: an RGB problem is solved one colour at a time.
inline float
channelOf(const Attribute& a, size_t i, int c)
{
    return a.isRgb() ? a.rgb(i)[c] : a.grey(i);
}

// Whether the problem has colours: an RGB albedo (medium or surfaces) or surface emission.
inline bool
isRgb(const Cloud& cloud, const CloudTransferOptions& o)
{
    const openvdb::Vec3d& sun = o.sunColour;
    return cloud.albedo().isRgb() || cloud.emission().isRgb()
        || (o.surfaces && o.surfaces->isRgb()) || o.sky.isRgb()
        || sun[0] != sun[1] || sun[1] != sun[2];
}

namespace detail {

// What a line carries: its radiance, whether it has met its first voxel yet (periodic boundaries
// give that voxel the light re-entering the box) and the last voxel it met (where it leaves).
// A voxel is finished only when the next one on its line is met (or the pass ends), which gives
// a linear source its slope: until then `radiance` is what enters the pending voxel `last`.
struct CloudRay
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

} // namespace detail

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
    // The sky (CloudTransferOptions::sky), at the internal irradiance: per direction the
    // radiance a line starts with, [2d] sweeping along +sigma (from the sky's -sigma cell),
    // [2d + 1] along -sigma (empty: no sky); the power it brought in the last sweep.
    std::vector<float> skyIn;
    double skyIncident = 0.0;
    void setSky(const CloudTransferOptions& options, const DirectionSet& directions,
        const openvdb::math::Transform& transform);
    double outputScale = 1.0;        // F0 / the internal irradiance: a power of two
    openvdb::Vec3d toSun{0.0, 1.0, 0.0};   // unit, index space
    // Per voxel of the given cloud, @a width numbers from the medium solved's (n x width): the
    // mean over the voxel's copies (each has the same number), times the output scale.
    std::vector<float> perGivenVoxel(const std::vector<double>& values, size_t width,
        size_t given, const openvdb::Coord& copies) const;
    std::vector<float> diffuseJ;     // diffuse mean radiance of the last sweep
    // Mean escape factor M_v per voxel: Y_00^2 sum_{directions, senses} Omega f(tau), from the
    // sweeps' own float factors; 1 - omega0 (1 - M_v) is what iterate() divides I_00 by.
    std::vector<double> escape;
    // 1 - c_v = (1 - omega0) + omega0 M_v: the fraction of what voxel v scatters that is not
    // extinguished again in it (absorbed or escaped), formed without cancellation.
    double escapes(size_t v) const
    {
        const double w = omega[v];
        return (1.0 - w) + w * escape[v];
    }
    // Anisotropic scattering: M = (K + 1)^2 radiance moments per voxel (M = 1: isotropic).
    int M = 1;
    std::vector<double> chi;         // delta-M scaled Legendre coefficients, l = 0..K
    std::vector<float> moments;      // diffuse I_lm per voxel (n x M), from the last sweep
    std::unique_ptr<AndersonMixer> mixer;   // Acceleration::Anderson only
    // Diffusion synthetic acceleration of I_00 (null: off).
    std::unique_ptr<DiffusionAcceleration> diffusion;
    void setDiffusion(const Cloud& cloud, const CloudTransferOptions& options);
    // The phase function on the directions: harmonics per direction and sense, their
    // quadrature means, the beam's first scattering (PhaseFunction::Tables).
    PhaseFunction::Tables phase;

    std::unique_ptr<SweepSchedule> schedule;
    std::array<std::vector<float>, SweepSchedule::kPatterns> kappaOrdered;   // per pattern
    mutable SweepSchedule::PerThread<LineSweep::Lanes<detail::CloudRay>> lanes;   // per thread, reused
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
        // Anisotropic: S's coefficient of Y_00 alone, n per pattern (the sweeps read it voxel
        // after voxel; empty where M = 1, S itself then).
        const std::array<std::vector<float>, SweepSchedule::kPatterns>& S0;
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
        std::array<double, SweepSchedule::kGroups> skyEntered{};   // the sky's power, per group
    };
    // Anisotropic scattering works on a batch of a group's directions at a time: the sources'
    // higher-moment part for every voxel and (direction, sense) of the batch by one product of
    // the voxels' coefficients with the harmonics, then the sweeps reading one float per voxel
    // and column, writing the mean radiance over the step to another, and the moments by a
    // second product (81 multiply-adds per voxel and column in a vectorised loop, instead of
    // inside the sweep's sequential step). Per thread: the two matrices and the harmonics.
    //
    // The sweeps visit voxels in the pattern's order, one column at a time, so the matrices are
    // stored column after column (R[k n + x]) and the moment I_00 they gather goes to its own
    // array: a sweep's reads and writes run along memory instead of striding a row (width or
    // (K + 1)^2 floats) per voxel, which left the order-8 step waiting on memory. The products
    // go through small row-major tiles, in the same arithmetic order: the same bits.
    struct Batch
    {
        size_t width = 0;            // columns: 2 x directions (both senses)
        std::vector<float> R;        // width x n: sum over l >= 1 of c_lm Y_lm(column)
        std::vector<float> Lbar;     // width x n: omega0 x the step's mean radiance
        std::vector<float> G0;       // n: the group's I_00 sum (G[x M]), during the batch
        std::vector<float> tile;     // kTile x width, row-major: a block of voxels' rows
        static constexpr size_t kTile = 16;
        std::vector<float> Yt;       // (M - 1) x width: the harmonics l >= 1, transposed
        // Per voxel, 1 - e^-tau of the direction swept: from the first pass's forward sense,
        // for its backward sense and the wrap passes (the exponential was a third of an
        // isotropic sweep).
        std::vector<double> absorbed;
    };
    mutable SweepSchedule::PerThread<Batch> batches;
    /// Directions per batch: as many as keep a thread's two matrices within kBatchBytes, a
    /// multiple of 8 where that is 8 or more (16 columns: whole vector blocks in the products;
    /// 10 directions left 4 columns to their scalar tail, as slow as the other 16).
    static constexpr size_t kBatchBytes = size_t(64) << 20;
    static constexpr size_t kMaxBatch = 32;
    static size_t batchSize(size_t n, size_t M)
    {
        if (M == 1) return 1;
        const size_t fit = std::clamp<size_t>(kBatchBytes / (std::max<size_t>(n, 1) * 2 * 2 * 4),
            1, kMaxBatch);
        return fit >= 8 ? fit / 8 * 8 : fit;
    }
    void sweepBatch(const CloudTransfer& t, int g, const size_t* dirs, size_t count,
        Sweep& sweep) const;
    void sweepDirection(const CloudTransfer& t, int g, size_t d, size_t column, Batch& batch,
        Sweep& sweep) const;
    // The constructor's steps (CloudTransfer.cc).
    void assemble(const Cloud& given, const CloudTransferOptions& options,
        const openvdb::Coord& copies);
    void setMedium(const Cloud& cloud, const CloudTransferOptions& options, int order);
    void traceBeam(const Cloud& cloud, const CloudTransferOptions& options,
        const openvdb::Vec3d& toSun, openvdb::util::NullInterrupter* interrupt);
    void setEmission(const Cloud& given, const CloudTransferOptions& options, double h);
    void layOut(const Cloud& cloud, const CloudTransferOptions& options, DirectionSet directions);
    void setEscapeFactors(int up);
    struct DirectionPass;   // CloudSweeps.cc
    // A sweep's steps around the groups' round (CloudSweeps.cc).
    struct Sources
    {
        std::vector<float> source;      // per voxel, M moments: omega0 chi_l c_lm, rescaled
        std::vector<float> beam;        // per voxel: the beam's first scattering
        std::vector<double> isoExcess;  // anisotropic: (alpha - 1) omega0 I_00 per voxel
    };
    Sources sources() const;
    // The largest change of an unknown in a sweep, and the largest unknown.
    struct Change
    {
        double max = 0.0, size = 0.0;
    };
    // @a before, if not null, gets I_00 as it was (the diffusion's residual needs it).
    void eliminateSelfScattering(std::vector<double>& sum, const std::vector<double>& isoExcess,
        std::vector<float>* before = nullptr);
    void accelerateDiffusion(std::vector<double>& sum, const std::vector<float>& before);
    double updateMeanRadiance(const std::vector<double>& sum, Change& change);
    std::pair<double, double> updateGround(const std::vector<double>& landed, Change& change);
    double updateSurfaces(const Sweep& sw, Change& change);
    std::vector<float> mixedState() const;
    // Anderson mixes the moments of order l <= 1 only (the mean radiance and the flux, where
    // the slow, diffusive modes live): higher moments decay at a rate independent of the
    // optical depth (see eliminateSelfScattering), and the plain step carries them; mixing
    // all (K + 1)^2 took the same sweeps (slab g 0.877, tau 100, order 8: 145 against 136;
    // step cloud 29-34 against 31-34) in (K + 1)^2 / 4 times the memory (order 13, a 416 k
    // voxel cloud, depth 16: 11 GB). l = 0 alone is not enough (tau 100 did not converge).
    static size_t mixedMoments(int M) { return std::min<size_t>(size_t(M), 4); }
    size_t mixedMoments() const { return mixedMoments(M); }
    void mix(const std::vector<float>& x);
};

} // namespace vdbrad
