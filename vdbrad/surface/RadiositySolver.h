// RadiositySolver: diffuse radiosity on surface voxels with the line-partition sweeps
// (Chatelier & Malgouyres, thesis 2006, ch. 4, eq. 4.11).
//
//   B(x) = E(x) + rho(x) * sum over directions s of w_s(n_x) * B(V(x, s))
//
// where V(x, s) is the voxel x sees along s (LineSweep) and the weights are the energy-conserving
// direction factors of DirectionSet normalised per voxel:
//   w_s(n) = |s^ . n| A(s) / Z(n),   Z(n) = sum over pairs |s^ . n| A(s),
// so that they add up to exactly 1 for every normal: a closed furnace is exact, and a direction
// in which a voxel sees nothing (open sky, a back) loses exactly its share.
//
// Iteration: every iteration sweeps every direction (both senses). Jacobi gathers from the
// previous iterate and replaces B at the end; in-place (default) sweeps the directions in two
// halves and updates B after each, so the second half gathers light the first half just moved
// (block Gauss-Seidel over directions; fewer iterations, same cost per iteration); progressive
// shooting sweeps the unshot radiosity and adds what it delivers (one bounce per iteration).
// The relative residual max|B' - B| / max|B'| over a whole iteration is reported per iteration.
//
// Precision: float, or double for albedos near 1 (Precision.h).
//
// Threads: directions are dealt to a fixed number of groups (SweepSchedule.h, independent of the
// thread count); each group sweeps its directions one after the other into its own accumulator, and
// the accumulators are added in group order. So the result is bit-identical for any thread count.
// A grey scene (no RGB input) is solved in floats; an RGB one in Vec3f, with no cost to the other.
#pragma once

#include "vdbrad/core/Checkpoint.h"
#include "vdbrad/core/Precision.h"
#include "vdbrad/glossy/GlossyOptions.h"
#include "vdbrad/scene/OutputGrids.h"
#include "vdbrad/scene/Scene.h"
#include "vdbrad/scene/Sky.h"
#include "vdbrad/surface/DirectLight.h"
#include "vdbrad/sweep/Acceleration.h"
#include "vdbrad/sweep/DirectionSet.h"
#include "vdbrad/sweep/FixedPointIteration.h"
#include "vdbrad/sweep/LinePartition.h"

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <memory>
#include <string>
#include <vector>

namespace vdbrad {

/// How B is updated within an iteration.
enum class UpdateScheme
{
    /// Every direction gathers from the previous iterate (thesis eq. 4.11).
    Jacobi,
    /// Gauss-Seidel-like: the directions are swept in two halves and B is updated after each, so
    /// the second half already gathers the first half's light.
    InPlace,
    /// Progressive shooting: the sweeps carry the unshot radiosity U (initially E); what it
    /// delivers, rho * gathered, is added to B and becomes the next U. Iterate k holds the
    /// light of paths of up to k bounces (iteration 1 = direct light), the residual is the
    /// last bounce's share, and nothing is recomputed from E: the Neumann series summed term
    /// by term (the same iterates as Jacobi, up to rounding).
    Progressive
};

/// How V(x, sigma), the voxel x sees along sigma, is found.
enum class Visibility
{
    /// The line sweeps (LineSweep): O(N) per direction.
    Sweep,
    /// Marching each receiver's digital line through the tree (RayCastVisibility): the
    /// reference, same lines and exchange rule, none of the sweep's code.
    RayCast
};

class Distribution;
class GlossySurfaces;

/// How a solve under mpirun (Distribution.h) shares the work between the ranks.
enum class Spread
{
    /// Every rank holds the whole scene and sweeps its share of the directions (thesis
    /// §6.2.1.2); the ranks add their sums once per half-iteration.
    Directions,
    /// Every rank holds one slab of the scene along x and sweeps every direction over it,
    /// passing line fronts to its neighbours (SlabDistribution.h, thesis §6.2.2.3): the memory
    /// per rank falls with the ranks. Diffuse scenes, naive lines, no Anderson acceleration;
    /// the visibility cache is not used.
    Slabs
};

struct RadiosityOptions
{
    /// Number of direction pairs (one sweep serves s and -s); the nearest count a discrete
    /// sphere gives is used (DirectionSet::fromCount), reported in SolveStats::directions.
    int directions = 300;
    /// Iteration cap, >= 1.
    int maxIterations = 200;
    /// Stop when the relative residual max|B' - B| / max|B'| falls below this, >= 0.
    double tolerance = 1e-5;
    /// Naive (26-connected) or standard (6-connected) lines.
    LineType lines = LineType::Naive;
    /// Occlusion depth in voxels (LineSweep), > 0.
    float occlusionDepth = 1.f;
    /// Jacobi, in-place or progressive-shooting updates (an in-place solve's first iteration is
    /// a Jacobi one).
    UpdateScheme update = UpdateScheme::InPlace;
    /// Line sweeps, or the ray-casting reference.
    Visibility visibility = Visibility::Sweep;
    /// Anderson acceleration (Acceleration.h) of Jacobi sweeps: with it, an in-place update is
    /// replaced by Jacobi (an in-place iteration keeps half of the previous iteration's gathered
    /// light, so it is not a function of B alone), and progressive shooting is refused.
    Acceleration accelerate = Acceleration::None;
    /// Anderson history length m: 2m + 2 copies of B are kept.
    int andersonDepth = 16;
    /// Float or double state (Auto: double only for albedos above 0.999).
    Precision precision = Precision::Auto;
    /// Bytes the solver may keep to remember what each voxel sees along each direction
    /// (VisibilityCache.h, ~1.2 bytes per voxel and direction, ~0.8 where the budget is short):
    /// a kept direction is swept once, and later iterations gather along it instead of
    /// sweeping it (faster: docs/journal/2026-11-24-radiosity-solver-speed.md; the same
    /// results, bit for bit). Directions are kept while the budget lasts. 0, or a single
    /// iteration: every iteration sweeps every direction.
    size_t visibilityCache = 0;
    /// Direct light from the emitters: integrated exactly (DirectLight.h; the sweeps then carry
    /// B - E, the reflected light, and the output adds E back), sent through the sweeps like
    /// every bounce, or Auto (exact when the emitters are at most half of the surface).
    DirectMode direct = DirectMode::Auto;
    /// Shadow rays per voxel for exact direct light (DirectLightOptions::samples), >= 1.
    int directSamples = 16;
    /// Light from outside the scene (Sky.h: uniform, clear, or an environment map): a voxel
    /// facing the outside receives, along each direction whose line leaves the scene from it,
    /// the sky's mean radiance over that direction's cell (measured by the first sweep, beside
    /// Enclosure.h's hit weights), so a scene of albedo 1 under a uniform sky L has B = pi L
    /// everywhere, whatever its shape. Diffuse scenes; an RGB sky makes the solve RGB.
    Sky sky;
    /// A sun (Sun.h): its first collision is computed exactly with the emitters' (DirectLight.h;
    /// needs DirectMode Exact or Auto), its reflections carried by the sweeps.
    std::optional<Sun> sun;
    /// The MPI job the solve is shared with (Distribution::join(), kept by the host; not
    /// owned); null: this process alone.
    const Distribution* ranks = nullptr;
    /// With several ranks: directions or slabs per rank (the same bits either way and alone).
    Spread spread = Spread::Directions;
    /// Glossy voxels (a scene with a `specular` grid): their lobes' model and representation.
    /// They need Jacobi or in-place updates, no Anderson acceleration and the line sweeps; the
    /// visibility cache is not used for them.
    GlossyOptions glossy;
};

/// True if a solve of @a scene with @a options is RGB: the scene is, or the sky or sun is.
bool solvesRgb(const Scene& scene, const RadiosityOptions& options);

class RadiositySolver : public IterativeSolver
{
public:
    /// Accumulator groups: fixed, so that results do not depend on the thread count.
    static constexpr int kGroups = 8;   // SweepSchedule::kGroups
    /// Kept directions are replayed in blocks of this many voxels (VisibilityCache.h).
    static constexpr uint32_t kReplayBlock = 1024;

    /// @brief Prepare the solve: directions, sweep orders, per-voxel normalisation, emitter
    /// patches. B starts at E. With exact direct light the first iterate() computes it (its
    /// time counts in stats().seconds) and starts the reflected part at rho D.
    /// @throw openvdb::ValueError for invalid options
    RadiositySolver(const Scene& scene, const RadiosityOptions& options = RadiosityOptions());
    ~RadiositySolver();

    /// @brief One iteration over every direction (followed by an Anderson step when accelerated);
    /// returns the relative residual max|G(B) - B| / max|G(B)| of the iterate it swept.
    /// @throw vdbrad::Cancelled if @a interrupt asks to stop (B may then hold a partly updated
    ///        iterate: discard the solver or keep iterating)
    double iterate(openvdb::util::NullInterrupter* interrupt = nullptr);

    /// @brief Iterate until the tolerance or the iteration cap.
    void solve(openvdb::util::NullInterrupter* interrupt = nullptr);

    const DirectionSet& directions() const;
    /// One line saying what is solved: voxels, directions, lines, colour, acceleration,
    /// precision (what `vdbrad solve` prints before iterating).
    std::string describe() const;

    /// True if direct light is integrated exactly (RadiosityOptions::direct).
    bool exactDirect() const;
    /// The emitters' patches (empty if nothing emits) and the direct light's cost so far.
    const Emitters& emitters() const;
    const DirectIrradiance& directLight() const;

    /// True if the solution is RGB: the scene's colours are (Scene::isRgb()) or the light
    /// from outside is (an RGB sky or sun; solvesRgb()).
    bool isRgb() const;
    /// The current radiosity: grey() for a grey solve, rgb() for an RGB one (isRgb()).
    /// In double precision, these are B rounded to float.
    const std::vector<float>& grey() const;
    const std::vector<openvdb::Vec3f>& rgb() const;
    /// The glossy voxels' lobes (null for a diffuse scene).
    const GlossySurfaces* glossy() const;
    /// @brief What voxel @a i sends along the unit index-space direction @a toward (pi times
    /// its radiance that way, in radiosity units): its radiosity for a diffuse voxel, its
    /// diffuse part plus its lobe's light interpolated at @a toward for a glossy one (per
    /// channel; grey scenes: three equal channels).
    openvdb::Vec3d sent(size_t i, const openvdb::Vec3d& toward) const;
    /// The glossy voxels' lobes' exitance (zero elsewhere; empty for a diffuse scene): the
    /// part of grey() / rgb() that depends on the direction it is seen from.
    std::vector<openvdb::Vec3f> specularRadiosity() const;
    /// True if the state is double (RadiosityOptions::precision).
    bool doublePrecision() const;
    /// Directions the visibility cache holds, and its bytes (RadiosityOptions::visibilityCache;
    /// filled by the first iteration).
    size_t cachedDirections() const;
    size_t cacheBytes() const;

    /// @brief Make @a b (one value per voxel, in Scene order; B, emission included) the iterate
    /// the next iterate() sweeps: a restart from a known state. The next step is a Jacobi one
    /// and an Anderson history starts again.
    /// @throw openvdb::ValueError if its size or kind (grey, RGB) does not match the scene, or
    ///        for progressive shooting (whose state is not B alone)
    void setRadiosity(const std::vector<float>& b);
    void setRadiosity(const std::vector<openvdb::Vec3f>& b);

    /// @brief Peak bytes a solver of @a scene with @a options allocates (not counting the
    /// scene), from the sizes of its arrays: for refusing a solve before it allocates.
    /// @a threads: the worker threads that will run it.
    static size_t memoryEstimate(const Scene& scene, const RadiosityOptions& options,
        int threads);
    /// @brief A visibility cache budget for a solve that may use @a available more bytes (not
    /// counting the scene): half of what is left once the solve has what it needs without a
    /// cache (memoryEstimate()), so that the cache never crowds out the solve.
    static size_t visibilityCacheFor(const Scene& scene, const RadiosityOptions& options,
        int threads, double available);

    /// @brief Everything the next iterate() reads, for a checkpoint (Checkpoint.h): a solver
    /// set up from the same scene and options and given it by restoreState() computes the
    /// same bits from there on as this one.
    void saveState(SolverState& state) const;
    /// @throw openvdb::ValueError if @a state does not fit this solver (sizes, update scheme)
    void restoreState(const SolverState& state);
    /// Hash of the scene and of the options that change the iterates (not the iteration cap
    /// or the tolerance): a checkpoint's fingerprint.
    uint64_t fingerprint() const;

    /// Statistics of the solve so far (directions, iterations, residual, seconds, lines).
    SolveStats stats() const;
    /// The `radiosity` grid of the current solution, with the contract's metadata (glossy
    /// scenes: also vdbrad:brdf, the lobe model, and vdbrad:control_points or, on harmonics,
    /// vdbrad:harmonic_order).
    openvdb::GridBase::Ptr grid() const;
    /// The `specular_radiosity` grid of a glossy scene (specularRadiosity() on its glossy
    /// voxels, float or Vec3f as `radiosity`): the part of `radiosity` a renderer shows
    /// view-dependent (Renderer.h); null for a diffuse scene.
    openvdb::GridBase::Ptr specularGrid() const;

    /// What the solver of one slab of a data-distributed solve takes from the whole scene
    /// (solveRadiosity() with Spread::Slabs builds it).
    struct SlabContext;
    /// @brief The solver of the slab @a slab of a whole scene, in a data-distributed solve
    /// whose ranks each build one (SlabDistribution.h); iterate() exchanges line fronts with
    /// the neighbouring ranks.
    RadiositySolver(const Scene& slab, const RadiosityOptions& options,
        std::shared_ptr<const SlabContext> context);

private:
    struct Impl;
    template<typename ValueT> struct Engine;
    template<typename ValueT> void replaceIterate(const std::vector<ValueT>& b);
    void prepareDirect(openvdb::util::NullInterrupter* interrupt);
    const Scene& mScene;
    RadiosityOptions mOptions;
    std::unique_ptr<Impl> mImpl;
};

/// @brief Solve the radiosity of @a scene and return the `radiosity` grid (float, or Vec3f for
/// an RGB scene) on the scene's transform, active exactly on the surface voxels, with the
/// metadata vdbrad:voxels, directions, iterations, residual, seconds, lines, version.
/// @a control: checkpoints (saved every K iterations, resumed from), and reports of each
/// iteration and of the solve (SolveControl).
/// @throw openvdb::ValueError for invalid options; vdbrad::Cancelled if interrupted; as
///        readCheckpoint() and writeCheckpoint() for @a control's files
///
/// @code
/// vdbrad::Scene scene = vdbrad::buildScene(vdbrad::readVdbFile("cornell.vdb").grids);
/// vdbrad::RadiosityOptions options;
/// options.directions = 1000;
/// openvdb::GridBase::Ptr radiosity = vdbrad::solveRadiosity(scene, options);
/// @endcode
/// @param specular  if not null and the scene is glossy, receives specularGrid() (else null)
/// Under mpirun with Spread::Slabs, rank 0 alone returns the grid (the others null).
openvdb::GridBase::Ptr solveRadiosity(const Scene& scene,
    const RadiosityOptions& options = RadiosityOptions(),
    openvdb::util::NullInterrupter* interrupt = nullptr,
    const SolveControl& control = SolveControl(), openvdb::GridBase::Ptr* specular = nullptr);

/// @brief solveRadiosity() of a scene it takes over: under mpirun with Spread::Slabs the ranks
/// other than 0 free it once their slab is set up, so that what they hold while solving is
/// their slab's share (rank 0 keeps it for the output grid). Otherwise as above; @a scene is
/// left as it was.
openvdb::GridBase::Ptr solveRadiosity(Scene&& scene, const RadiosityOptions& options,
    openvdb::util::NullInterrupter* interrupt = nullptr,
    const SolveControl& control = SolveControl(), openvdb::GridBase::Ptr* specular = nullptr);

} // namespace vdbrad
