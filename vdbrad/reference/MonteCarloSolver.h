// MonteCarloSolver: radiosity of the voxelised scene by cosine-weighted continuous rays, with a
// per-voxel standard error. The reference for the direction set's angular error: it shares
// neither directions nor digital lines with the line-partition solver.
//
// The voxelised surface: voxel v is its plane with normal n_v (SurfacePlanes.h: the plane of its
// wall, not of its centre, so that a tilted wall's staircase does not shadow itself), clipped to
// its cube and to the convex edges of its wall. A ray that crosses that plane inside the cube,
// or runs behind it there (it slipped through a digitisation crack between two tilted patches),
// hits v: v's front (d . n_v < 0) shows B(v), its back is black. A ray that crosses a surface
// voxel's cube in front of its plane passes (the neighbours of a flat wall, at grazing angles).
// A 26-connected shell stops every ray this way: rays traverse cubes 6-connectedly. Leaving the
// scene's box is the sky (0). The direct light's shadow rays follow the same rule. An emitting
// voxel shows its patch's exitance (Emitters::exitance: scaled to the mesh's power when the scene
// has an `emission_area`), the light the exact direct light integrates, so the two agree.
//
// Estimator: S rays per voxel from 0.01 voxel in front of its plane (the estimate is the
// irradiance where they start), cosine-distributed about n_x (stratified in cos^2 theta,
// golden-ratio sequence in phi, per-voxel random offsets from a counter-based hash, so results
// do not depend on the thread count). Their hits are found once; then Jacobi
// iterations B(x) = E(x) + rho(x) (1/S) sum_s B(hit_s) until the relative residual is below the
// tolerance. For fixed rays this is the radiosity of the sampled scene; as S grows it converges
// to the voxelised scene's radiosity. A voxel facing a closed cavity (Enclosure.h) averages over
// its rays that hit a voxel (one leaving through its own cube is a digitisation artefact), as
// the line-partition solver renormalises. The standard error reported per voxel is that of its
// last gather: rho times the sampling error of the mean of its own rays, estimated by pairing
// adjacent strata (conservative; the error its neighbours' values carry in is not included).
//
// Final gather (the second pass of a two-pass Monte Carlo, gather()): at chosen voxels, E + rho
// times the mean of the current B at the hits of G fresh rays that are not stored, drawn as
// kGatherBatches independent stratified batches whose spread is an unbiased estimate of the
// gather's sampling error. The stored pass's own noise enters the gather only averaged over the
// thousands of voxels its rays hit, so a few hundred stored rays per voxel and a few thousand
// gathered ones give a low-noise reference in a fraction of the memory. Where rays concentrate
// on few voxels (one tucked behind its neighbour on a staircase sees only that neighbour) the
// carried-in noise is added from the stored pass's own estimate; with >= 256 stored rays the
// reported error then matches the spread of independent solves (tests/test_montecarlo.cc).
//
// Empty space: the traversal (marchVoxels, VoxelMarch.h) jumps over empty tree nodes (tiles and
// missing children of the index tree) to where the ray leaves them. Memory: S hit indices per
// voxel (4 S bytes).
#pragma once

#include "vdbrad/scene/OutputGrids.h"
#include "vdbrad/scene/Scene.h"
#include "vdbrad/scene/SurfacePlanes.h"
#include "vdbrad/sweep/FixedPointIteration.h"

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <cstdint>
#include <string>
#include <vector>

namespace vdbrad {

struct MonteCarloOptions
{
    /// Rays per voxel, >= 1.
    int samples = 256;
    /// Iteration cap, >= 1.
    int maxIterations = 200;
    /// Stop when max|B' - B| / max|B'| falls below this, >= 0.
    double tolerance = 1e-5;
    /// Seed of the per-voxel ray sequences.
    uint64_t seed = 1;
    /// solveMonteCarlo(): rays per voxel of a final gather after iterating (gather()), >= 0;
    /// 0: none.
    int gather = 0;
};

/// Radiosity and standard error of gathered voxels (grey or RGB, as the scene).
struct MonteCarloGather
{
    std::vector<float> grey, greyError;
    std::vector<openvdb::Vec3f> rgb, rgbError;
};

class MonteCarloSolver : public IterativeSolver
{
public:
    static constexpr uint32_t kSky = 0xffffffffu;   ///< a ray that leaves the scene
    static constexpr uint32_t kBack = 0xfffffffeu;  ///< a ray that hits a voxel's back

    /// @brief Cast every voxel's rays. @throw openvdb::ValueError for invalid options;
    /// vdbrad::Cancelled if @a interrupt asks to stop.
    MonteCarloSolver(const Scene& scene, const MonteCarloOptions& options = MonteCarloOptions(),
        openvdb::util::NullInterrupter* interrupt = nullptr);

    /// One Jacobi iteration; returns the relative residual.
    /// @throw vdbrad::Cancelled if @a interrupt asks to stop (B is then unchanged)
    double iterate(openvdb::util::NullInterrupter* interrupt = nullptr);
    /// Iterate until the tolerance or the cap. @throw vdbrad::Cancelled if interrupted.
    void solve(openvdb::util::NullInterrupter* interrupt = nullptr);
    /// One line saying what a solve of @a scene with @a options does.
    static std::string describe(const Scene& scene, const MonteCarloOptions& options);
    std::string describe() const { return describe(mScene, mOptions); }

    static constexpr int kGatherBatches = 8;   ///< independent batches of a final gather

    /// @brief Final gather at the voxels @a voxels (indices) from the current solution, with
    /// @a rays fresh rays each (rounded up to a multiple of kGatherBatches).
    /// @throw openvdb::ValueError if @a rays < 1 or an index is out of range;
    /// vdbrad::Cancelled if @a interrupt asks to stop.
    MonteCarloGather gather(const std::vector<size_t>& voxels, int rays,
        openvdb::util::NullInterrupter* interrupt = nullptr) const;

    /// @brief Replace every voxel's radiosity and standard error by a final gather of @a rays
    /// rays from the current solution (grids() then writes the gathered values).
    /// @throw as gather(); B is unchanged if cancelled.
    void finalGather(int rays, openvdb::util::NullInterrupter* interrupt = nullptr);

    /// What ray @a s of voxel @a i hit: a voxel index, kSky or kBack.
    uint32_t hit(size_t i, int s) const { return mHits[i * size_t(mOptions.samples) + size_t(s)]; }

    const std::vector<float>& grey() const { return mGrey; }
    const std::vector<openvdb::Vec3f>& rgb() const { return mRgb; }
    /// Standard error of each voxel's radiosity (per channel for RGB scenes).
    const std::vector<float>& greyError() const { return mGreyError; }
    const std::vector<openvdb::Vec3f>& rgbError() const { return mRgbError; }

    /// `radiosity` (with metadata; vdbrad:directions holds the rays per voxel of the last pass
    /// (stored or gathered) and
    /// vdbrad:lines "montecarlo") and `radiosity_stderr`.
    openvdb::GridPtrVec grids() const;

private:
    template<typename ValueT> double iterate(std::vector<ValueT>& B, std::vector<ValueT>& err);
    static size_t raysPerBatch(int rays);
    template<typename ValueT> void gather(const std::vector<ValueT>& B,
        const std::vector<ValueT>& storedError, const std::vector<size_t>& voxels,
        size_t perBatch, std::vector<ValueT>& value, std::vector<ValueT>& error,
        openvdb::util::NullInterrupter* interrupt) const;

    const Scene& mScene;
    MonteCarloOptions mOptions;
    SurfacePlanes mPlanes;
    // What a ray that meets an emitting voxel collects: its patch's exitance, so that the
    // voxelised light's power is the mesh's (emission_area), as in the exact direct light.
    Attribute mEmission;
    std::vector<uint32_t> mHits;
    std::vector<char> mClosed;   // per voxel: faces a closed cavity (Enclosure.h)
    std::vector<float> mGrey, mGreyError;
    std::vector<openvdb::Vec3f> mRgb, mRgbError;
    int mGathered = 0;   // rays of the final gather that made B, 0 if none
};

/// @brief Solve @a scene by Monte Carlo: returns the `radiosity` and `radiosity_stderr` grids.
/// Then, with MonteCarloOptions::gather, a final gather. @a control: reports (SolveControl; a
/// Monte Carlo solve keeps no checkpoints).
/// @throw openvdb::ValueError for invalid options; vdbrad::Cancelled if interrupted
openvdb::GridPtrVec solveMonteCarlo(const Scene& scene,
    const MonteCarloOptions& options = MonteCarloOptions(),
    openvdb::util::NullInterrupter* interrupt = nullptr,
    const SolveControl& control = SolveControl());

} // namespace vdbrad
