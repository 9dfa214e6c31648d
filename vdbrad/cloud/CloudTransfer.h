// CloudTransfer: radiative transfer in a cloud by sweeps along 3D digital lines (thesis §6.3).
//
// The medium voxels (Cloud.h: extinction sigma_t, single-scattering albedo omega0) are swept
// along the naive digital lines of every direction pair of a DirectionSet, both senses, with the
// same machinery as the surface solver (LinePartition, LeafOrder, LineSweep::walk): each line
// carries a radiance L from voxel to voxel. A naive line advances one voxel per step of its
// major axis, so a step is exactly l = |sigma| / max_k |sigma_k| voxels long, and the line is a
// tube of cross-section 1 / l voxel faces. Across a voxel of optical depth tau = sigma_t l with
// source S (constant over the voxel), the transfer equation dL/ds = sigma_t (S - L) gives
//
//     L_out = S + (L_in - S) e^-tau,      mean over the step: L_bar = S + (L_in - S) f(tau),
//     f(tau) = (1 - e^-tau) / tau,        evaluated with expm1 so thin voxels keep precision.
//
// A source constant over a voxel is only right where the voxel is thin: light leaving an opaque
// voxel then carries the voxel's mean source instead of the source at its exit face, so each
// layer of opaque voxels reflects like a slab of its own (20 opaque conservative layers transmit
// 1/21 whatever their depth), and a slab of 2.5 per voxel reflects 2 % too little. With
// VoxelSource::Linear (the default) the source rises linearly along
// each step, S + S1 (u - 1/2) for u from 0 at the entry to 1 at the exit, S1 from the sources
// of the voxels before and after it on the line (the previous iterate's, as S itself): L_out
// gains S1 h(tau) and the step's mean loses S1 h(tau) / tau (VoxelStep.h). The voxel's mean
// source, hence what it emits, is unchanged, and tau (L_bar - S) = L_in - L_out still holds step
// by step, so energy is conserved as before; a voxel is finished when the next one on its line
// is met.
//
// Light sources: the solar beam (SolarBeam.h), attenuated exactly along its own direction (the
// power D_v it loses in voxel v is the first-order source), and a sky (CloudTransferOptions::sky):
// the radiance a line starts with where it enters the box from outside (a periodic box: through
// the top and bottom, and the side layers a horizontal direction drifts in by). Diffuse light
// is iterated (source iteration): with J_v the mean radiance over directions,
// sum_sigma Omega_sigma L_bar / (4 pi), and isotropic scattering,
//
//     S_v = omega0_v (J_v + D_v / (4 pi sigma_t,v))     (per unit volume: extinguished power
//                                                         times omega0, re-emitted over 4 pi)
//
// Self-scattering elimination: of what a voxel scatters, the fraction 1 - M_v (M_v its mean
// escape factor, the direction-weighted mean of f over the steps the sweeps take through it) is
// extinguished again in the voxel itself, so plain source iteration's local mode decays like
// omega0 (1 - M_v) per sweep: ~1 - 1 / tau in an opaque conservative voxel. Each sweep solves that
// local term exactly, J' = (J_swept - c_v J) / (1 - c_v) with c_v = omega0 (1 - M_v): the same
// fixed point, no slow local mode (only voxel-to-voxel diffusion is left).
//
// Diffusion synthetic acceleration (DiffusionAcceleration.h, CloudTransferOptions::diffusion):
// the voxel-to-voxel diffusion modes of a cloud many optical depths across decay like
// 1 - O(1 / tau^2) per sweep; after the elimination, a diffusion equation over the voxels
// solves for the error they carry, from the sweep's change of I_00, and Anderson mixes what
// is left (the flux and the anisotropic modes).
//
// Energy is conserved by construction: in each voxel and direction, what a tube loses plus what
// the voxel emits into it is what the voxel extinguishes, and the solid angles add up to 4 pi
// exactly; so at convergence reflected + transmitted + absorbed = incident (a test holds this to
// 1e-4, and the solver reports it). The `mean_intensity` output is the total mean radiance,
// direct beam included (D / (4 pi sigma_t)): omega0 times it is the isotropic scattering source
// a volume renderer needs.
//
// Boundaries: open (light leaving the box is gone), or periodic across the two horizontal axes:
// light leaving a side face re-enters through the opposite one at the same height, lagged by one
// iteration, matched layer by layer (PeriodicBoundary.h) between the lines of the box filled
// (a sparse medium's empty voxels added: filledBox(); else lines through its gaps, and the sky
// they carry, would be missing from the match). Narrow periodic boxes are solved as
// several copies side by side (CloudTransferOptions::minPeriod): all lines of a direction
// entering one layer of a face have the same phase (a naive line's pattern repeats), so a
// near-horizontal direction rises by a whole number of layers per wrap instead of its true
// fraction, and light on directions that round to no rise is trapped until it interacts; the
// narrower the box, the more directions that catches (figures:
// docs/journal/2026-12-01-extremes.md). The copies are the same medium (a period of the box is
// one of the tiling), so the result is the mean over them. A periodic box one voxel deep along a
// horizontal axis is a medium that does not vary along it (a 2D cloud such as the I3RC step cloud),
// and neither does its radiance: each direction is swept as its projection on the plane of the
// other axes, with the 3D path per step (sweptLine(), VoxelStep.h) — exact along that axis, without
// copies, and what wraps crosses the other axis' faces only. One voxel deep along both horizontal
// axes is a plane-parallel medium, swept along the vertical alone: the discrete-ordinates slab.
// solveCloud() slices a periodic box uniform along a horizontal axis to one voxel deep first
// (uniformSlice()), so that how many layers a file has along it changes nothing.
//
// Ground (CloudTransferOptions::groundAlbedo, Ground.h): a Lambertian surface under the box, a
// layer of voxels swept with the medium: light going down lands on the ground cell it meets and
// is reflected up the next sweep, rho E split over the directions by the cosine law so that the
// ground reflects exactly what it does not absorb. Its irradiance comes out as its own grid.
//
// Anisotropic scattering (PhaseFunction.h): the sweeps accumulate the radiance's spherical-
// harmonic moments I_lm up to order K instead of J alone, and a voxel's source in direction s is
// S(s) = alpha omega0' sum_l chi_l' sum_m I_lm Y_lm(s), delta-M scaled; alpha rescales it so that
// the direction set's quadrature of it is exactly the scattered power, so the energy balance
// above still closes. The moments are quadratures too: with the cells' solid angles products of
// order-K harmonics integrate roughly and higher orders alias; harmonicWeights refits the
// weights to integrate them exactly (HarmonicQuadrature.h). Cost: (K + 1)^2 multiply-adds per
// voxel and direction, twice (source and moments), done for a batch of directions at a time as
// two small matrix products outside the sequential line steps; memory (K + 1)^2 floats per voxel
// per accumulator group, and per thread two matrices of voxels x the batch's columns.
#pragma once

#include "vdbrad/cloud/PhaseFunction.h"
#include "vdbrad/cloud/ScatteredSource.h"
#include "vdbrad/core/Checkpoint.h"
#include "vdbrad/scene/Cloud.h"
#include "vdbrad/scene/Scene.h"
#include "vdbrad/scene/Sky.h"
#include "vdbrad/sweep/Acceleration.h"
#include "vdbrad/sweep/DirectionSet.h"
#include "vdbrad/sweep/FixedPointIteration.h"

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <memory>
#include <optional>
#include <vector>

namespace vdbrad {

/// How the source varies inside a voxel along a line step (see the file comment).
enum class VoxelSource
{
    /// Constant over the voxel (the thesis' scheme): second-order accurate only in thin voxels;
    /// a layer of opaque voxels reflects like a whole slab.
    Constant,
    /// Linear along the step, its slope from the sources of the voxels before and after it on
    /// the line (monotonized central difference, kept >= 0 across the step).
    Linear
};

class Distribution;

struct CloudTransferOptions
{
    /// Direction pairs swept per iteration (DirectionSet::fromCount: the nearest count); 0
    /// (auto): for a phase function of asymmetry |g| > 0.5, whose peak must be carried from
    /// voxel to voxel, 1000, else 300 (CloudTransfer::directionCount()).
    int directions = 0;
    /// Source-iteration cap, >= 1.
    int maxIterations = 1000;
    /// Stop when max |J' - J| / max J' falls below this, >= 0.
    double tolerance = 1e-6;
    /// Sun: zenith angle from the up axis and azimuth from the first horizontal axis towards the
    /// second (up y: x then z; up z: x then y; up x: y then z), degrees; zenith in [0, 89.9].
    double sunZenith = 0.0, sunAzimuth = 0.0;
    /// Beam irradiance on a plane normal to the beam, F0 >= 0.
    double irradiance = 1.0;
    /// The beam's colour: channel c's irradiance is irradiance x sunColour[c] (each >= 0); not
    /// grey: an RGB solve (solveCloud()).
    openvdb::Vec3d sunColour{1.0, 1.0, 1.0};
    /// Light from every direction outside the box (scene/Sky.h; empty: none): each sweep
    /// direction's lines start, in the pass with the sources, with the sky's mean radiance over
    /// that direction's cell where they enter the box from outside (not through a periodic
    /// side face, not up out of the ground's layer, not from a surface voxel facing a closed
    /// cavity): the boundary value of the transfer equation, so the sweeps carry it like any
    /// radiance. An RGB sky makes the solve RGB.
    Sky sky;
    /// The vertical axis: 0 x, 1 y (Houdini's and OpenVDB's default), 2 z (Blender's).
    int up = 1;
    /// Periodic across the two horizontal axes (see the file comment).
    bool periodic = false;
    /// Periodic boxes narrower than this many voxels along a horizontal axis are solved as
    /// copies side by side until they are at least this wide (see the file comment). -1 (auto):
    /// ceil(sqrt(directions) / 2), and no more copies than make one period 8 mean optical
    /// depths wide (light crossing it horizontally is then gone); 0: never.
    int minPeriod = -1;
    /// Solar-beam rays per voxel along each axis of the beam's cross-section.
    int beamRaysPerVoxel = 2;
    /// Scattering phase function (PhaseFunction.h); isotropic by default.
    PhaseFunction phase;
    /// Spherical-harmonic order K of the radiance moments kept for an anisotropic phase, with
    /// delta-M scaling beyond it: (K + 1)^2 numbers per voxel and per accumulator group. -1
    /// (auto): 8 (CloudTransfer::phaseOrderFor()).
    int phaseOrder = -1;
    /// Anderson acceleration (Acceleration.h) of the source iteration, over the radiance
    /// moments of order l <= 1 (n x 4 numbers; the plain step carries the higher ones) and
    /// the light a periodic box carries over to the next iteration across its side faces.
    /// Unset (auto): Anderson where plain sweeps would be slow
    /// (CloudTransfer::chooseAcceleration()).
    std::optional<Acceleration> accelerate;
    /// Anderson history length m: 2m + 2 copies of the mixed state are kept.
    int andersonDepth = 16;
    /// Diffusion synthetic acceleration of the mean radiance (DiffusionAcceleration.h): after
    /// each sweep a diffusion solve over the medium's voxels estimates the error its smooth
    /// modes carry (a thick slab, tau 100: 8 iterations instead of 161), before Anderson. Not
    /// for phase functions of asymmetry below DiffusionAcceleration::kMinAsymmetry (-0.7).
    bool diffusion = true;
    /// The source's shape inside a voxel along each step.
    VoxelSource source = VoxelSource::Linear;
    /// Anisotropic phase: direction weights refitted to integrate harmonics exactly up to
    /// degree 2K (HarmonicQuadrature.h), so that the error falls with the direction count;
    /// false keeps the cells' solid angles (docs/journal/2026-12-04-harmonic-weights.md).
    bool harmonicWeights = true;
    /// A Lambertian ground of this albedo (in [0, 1]) under the box, reflecting the light that
    /// reaches it back into the cloud (Ground.h); unset: none (light leaving downwards is gone).
    std::optional<double> groundAlbedo;
    /// Surfaces inside the medium (FogSurfaces.h): the voxels of a surface scene on the
    /// cloud's transform, swept with it; they stop light, reflect it (their albedo) and emit
    /// (their emission: lamps). Not owned: it must outlive the transfer. Not with periodic
    /// boundaries or a ground (model the ground as surface voxels).
    const Scene* surfaces = nullptr;
    /// The channel (0, 1, 2) solved of an RGB albedo (the medium's or the surfaces') and of the
    /// surfaces' emission: light of each colour travels alone, so solveCloud() solves an RGB
    /// problem channel by channel.
    int channel = 0;
    /// The MPI job the transfer is shared with (Distribution.h: each rank sweeps its groups of
    /// directions; the same bits); kept by the host, not owned; null: this process alone.
    const Distribution* ranks = nullptr;
};

/// Where the incident sunlight went, as fractions of the incident power (after the last sweep).
struct CloudBudget
{
    /// Beam power entering the box plus the sky's plus the power the surfaces and the medium
    /// emit (units of F0 x voxel face); the fractions below are of it.
    double incident = 0.0;
    /// The sky's share of `incident` (CloudTransferOptions::sky).
    double sky = 0.0;
    double albedo = 0.0;         ///< leaving upwards
    /// Leaving downwards, direct beam included: onto the ground where there is one (its
    /// irradiance, every arrival counted), so with a ground it includes light reflected back
    /// down by the cloud.
    double transmittance = 0.0;
    double directTransmittance = 0.0;
    double absorptance = 0.0;    ///< absorbed in the medium
    /// Reflected back up by the ground: its albedo times what reached it (0 without a ground);
    /// (1 - ground albedo) x what reached it is what the ground absorbed.
    double groundReflected = 0.0;
    /// Emitted by the surfaces (CloudTransferOptions::surfaces) and the medium (Cloud::emission),
    /// included in `incident`; mediumEmitted: the medium's part.
    double emitted = 0.0;
    double mediumEmitted = 0.0;
    /// Absorbed by the surfaces: (1 - their albedo) x what lands on their fronts, and all that
    /// reaches their backs.
    double surfaceAbsorptance = 0.0;
    /// albedo + transmittance - groundReflected + absorptance + surfaceAbsorptance - 1: the
    /// energy balance error (the ground reflects what it does not absorb).
    double balance() const
    {
        return albedo + transmittance - groundReflected + absorptance + surfaceAbsorptance - 1.0;
    }
};

class CloudTransfer : public IterativeSolver
{
public:
    /// @brief Prepare the sweeps and trace the solar beam.
    /// @throw openvdb::ValueError for invalid options
    /// @throw vdbrad::Cancelled if @a interrupt asks to stop
    CloudTransfer(const Cloud& cloud, const CloudTransferOptions& options,
        openvdb::util::NullInterrupter* interrupt = nullptr);
    ~CloudTransfer();

    /// @brief One source iteration over every direction; returns the relative change of J.
    /// @throw vdbrad::Cancelled if @a interrupt asks to stop
    double iterate(openvdb::util::NullInterrupter* interrupt = nullptr);
    /// Iterate until the tolerance or the cap.
    void solve(openvdb::util::NullInterrupter* interrupt = nullptr);

    const DirectionSet& directions() const;
    /// One line saying what is solved (what `vdbrad solve-cloud` prints before iterating).
    std::string describe() const;
    /// Copies of the box solved side by side along each index axis (1, 1, 1 unless periodic
    /// and narrow: see CloudTransferOptions::minPeriod).
    const openvdb::Coord& copies() const { return mCopies; }
    /// @brief The copies a transfer of @a cloud with @a options solves (see copies()).
    static openvdb::Coord periodicCopies(const Cloud& cloud, const CloudTransferOptions& options);
    /// @brief The direction pairs asked for: options.directions, or for 0 (auto) 1000 where
    /// the phase function's asymmetry |g| > 0.5, else 300 (measured:
    /// docs/journal/2026-12-07-production-clouds.md).
    static int directionCount(const CloudTransferOptions& options);
    /// @brief The phase order solved: 0 for an isotropic phase, else options.phaseOrder, or
    /// for -1 (auto) 8: delta-M moves the rest into the forward peak (31 % of a g = 0.877
    /// HG), the beam's first scattering keeps the whole phase function (Tables::beam), and
    /// slabs of g 0.85-0.9 stay within 0.25 % of adding-doubling, the I3RC step cloud within
    /// 0.2 % of Monte Carlo (docs/journal/2026-12-07-production-clouds.md; orders 10-16 and
    /// 2000-5000 directions cost 3-4 times the time, and 16 GiB on a 416 k voxel cloud).
    static int phaseOrderFor(const CloudTransferOptions& options);
    /// @brief options.accelerate, or where unset: Anderson where plain source iteration would
    /// take more than ~20 sweeps to 1e-6, that is where its slowest mode, estimated as
    /// omega0 tau / (tau + 2) (the fraction of scattered light that scatters again in a
    /// two-stream slab of the thickest column's optical thickness tau, after delta-M scaling,
    /// with the largest single-scattering albedo), decays slower than 1/2 per sweep; else none
    /// (Anderson keeps 2m + 2 copies of the moments of order <= 1).
    static Acceleration chooseAcceleration(const Cloud& cloud,
        const CloudTransferOptions& options);

    /// @brief Peak bytes a transfer of @a cloud with @a options allocates (not counting the
    /// cloud), from the sizes of its arrays; @a threads: the worker threads that will run it.
    static size_t memoryEstimate(const Cloud& cloud, const CloudTransferOptions& options,
        int threads);

    /// @brief Everything the next iterate() reads, for a checkpoint (Checkpoint.h); see
    /// RadiositySolver::saveState.
    void saveState(SolverState& state) const;
    /// @throw openvdb::ValueError if @a state does not fit this transfer
    void restoreState(const SolverState& state);
    /// Hash of the medium, the beam and the options that change the iterates.
    uint64_t fingerprint() const;

    /// Total mean radiance per medium voxel (VoxelIndex numbering), direct beam included.
    std::vector<float> meanIntensity() const;
    /// @brief The multiple-scattered source per medium voxel: its real spherical-harmonic
    /// coefficients c_lm, l <= min(@a order, the phase order solved), (l + 1)^2 numbers per
    /// voxel (VoxelIndex numbering, then l^2 + l + m), so that the diffuse light a voxel
    /// scatters towards index-space direction of travel s is sum_lm c_lm Y_lm(s) per unit of
    /// delta-M scaled extinction; the beam's first scattering is not in it (a renderer adds it
    /// with the full phase function: ScatteredSource.h).
    std::vector<float> scatteredSource(int order) const;
    /// @brief What a renderer needs beside the source's moments (ScatteredSource.h): the sun,
    /// the phase function and its delta-M fraction, the boundaries, as metadata on @a grid.
    void recordScattering(openvdb::GridBase& grid, int order) const;
    /// The budget of the last sweep (zero before the first).
    const CloudBudget& budget() const { return mBudget; }

    /// @brief Irradiance of the ground (CloudTransferOptions::groundAlbedo), direct beam
    /// included, per cell of its layer (GroundLayer order), in units of the beam irradiance's;
    /// empty without a ground.
    std::vector<float> groundIrradiance() const;
    /// @brief The ground's irradiance as a float grid on the cloud's transform, active on the
    /// layer of voxels one below the box over its footprint (null without a ground).
    openvdb::FloatGrid::Ptr groundGrid(const std::string& name = "ground_irradiance") const;

    /// @brief Radiosity B = P / A per surface voxel (CloudTransferOptions::surfaces, the
    /// scene's numbering; FogSurfaces.h), in units of the beam irradiance's and the emission's;
    /// empty without surfaces.
    std::vector<float> surfaceRadiosity() const;
    /// @brief Area A_v of each surface voxel as the lines see it, voxel faces (FogSurfaces.h);
    /// empty without surfaces.
    const std::vector<double>& surfaceArea() const;

    /// @brief The `mean_intensity` float grid on the cloud's transform, active on its voxels,
    /// with metadata vdbrad:albedo, vdbrad:transmittance, vdbrad:absorptance, vdbrad:iterations,
    /// vdbrad:residual, vdbrad:directions, vdbrad:seconds.
    openvdb::GridBase::Ptr grid(const std::string& name = "mean_intensity") const;

private:
    struct Impl;
    /// One iteration's sweeps and update (iterate() times and records it).
    double sweep(openvdb::util::NullInterrupter* interrupt);
    /// periodicCopies() for a direction set of @a directions pairs.
    static openvdb::Coord copiesFor(const Cloud& cloud, const CloudTransferOptions& options,
        size_t directions);
    const Cloud& mCloud;
    CloudTransferOptions mOptions;
    openvdb::Coord mCopies{1, 1, 1};
    /// Degree to which the direction weights integrate harmonics exactly (0: the cells' own).
    int mQuadratureDegree = 0;
    std::unique_ptr<Impl> mImpl;
    CloudBudget mBudget;
};

/// @brief The medium a periodic transfer of @a cloud (options.periodic) solves in its place: one
/// voxel deep along each horizontal axis along which @a cloud does not vary (uniformAxes(),
/// sliceCloud()), so that the file's layers along it change nothing (the I3RC step cloud
/// written four deep took 229 s, one deep 25 s). Null where that is @a cloud itself (open
/// boxes, surfaces inside, no uniform axis).
std::unique_ptr<Cloud> uniformSlice(const Cloud& cloud, const CloudTransferOptions& options);

/// @brief Solve the transfer in @a cloud and return its `mean_intensity` grid (see grid()).
/// A periodic box uniform along a horizontal axis is solved as its uniformSlice(), the results
/// extended along the axis.
/// @a control: checkpoints and reports (SolveControl); @a ground, if not null, gets the
/// ground's irradiance (groundGrid(); null without a ground); @a radiosity, if not null, the
/// surfaces' `radiosity` grid (CloudTransferOptions::surfaces; null without). An RGB albedo
/// (medium or surfaces) or RGB surface emission is solved channel by channel: `mean_intensity`
/// and `radiosity` are then vec3s grids (checkpoints refused, no ground grid).
/// @throw as CloudTransfer's constructor and iterate(); as readCheckpoint(), writeCheckpoint()
/// @a sources, if not null, gets the scatteredSource() grids up to @a sourceOrder
/// (ScatteredSource.h: named after `mean_intensity`, which carries the metadata).
openvdb::GridBase::Ptr solveCloud(const Cloud& cloud, const CloudTransferOptions& options,
    openvdb::util::NullInterrupter* interrupt = nullptr,
    const SolveControl& control = SolveControl(), openvdb::FloatGrid::Ptr* ground = nullptr,
    openvdb::GridBase::Ptr* radiosity = nullptr, openvdb::GridPtrVec* sources = nullptr,
    int sourceOrder = ScatteredSource::kDefaultOrder);

/// @brief solveCloud() given the uniformSlice() of @a cloud already built (null where there is
/// none), for callers that planned on the slice: the neighbour scan and the copy run once.
openvdb::GridBase::Ptr solveCloud(const Cloud& cloud, const Cloud* slice,
    const CloudTransferOptions& options, openvdb::util::NullInterrupter* interrupt,
    const SolveControl& control, openvdb::FloatGrid::Ptr* ground,
    openvdb::GridBase::Ptr* radiosity, openvdb::GridPtrVec* sources = nullptr,
    int sourceOrder = ScatteredSource::kDefaultOrder);

} // namespace vdbrad
