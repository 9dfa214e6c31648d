// OutputGrids: per-voxel arrays written back as grids on the input's transform.
//
// The solver's result is the `radiosity` grid (float, or Vec3f when any input colour is RGB),
// active exactly on the surface voxels, with the solve's statistics as grid metadata:
//   vdbrad:voxels (int), vdbrad:directions (int, directions actually swept),
//   vdbrad:iterations (int), vdbrad:residual (float, last relative residual),
//   vdbrad:seconds (float, solve wall time), vdbrad:lines ("naive"/"standard"), vdbrad:version.
// The output file is the input's grids, untouched, plus the result grids (an older grid of the
// same name is replaced), with the input's file-level metadata.
#pragma once

#include "vdbrad/core/GridIO.h"
#include "vdbrad/scene/Scene.h"

#include <openvdb/openvdb.h>

#include <string>
#include <vector>

namespace vdbrad {

namespace meta {
constexpr const char* kVoxels = "vdbrad:voxels";
constexpr const char* kDirections = "vdbrad:directions";
constexpr const char* kIterations = "vdbrad:iterations";
constexpr const char* kResidual = "vdbrad:residual";
constexpr const char* kSeconds = "vdbrad:seconds";
constexpr const char* kLines = "vdbrad:lines";
constexpr const char* kVersion = "vdbrad:version";
constexpr const char* kBrdf = "vdbrad:brdf";
constexpr const char* kControlPoints = "vdbrad:control_points";
constexpr const char* kRanks = "vdbrad:ranks";
constexpr const char* kHarmonicOrder = "vdbrad:harmonic_order";
} // namespace meta

/// What a solve reports; written as metadata on its result grid.
struct SolveStats
{
    int directions = 0;
    int iterations = 0;
    double residual = 0.0;
    double seconds = 0.0;
    std::string lines = "naive";   ///< "naive" or "standard"
};

/// @brief A grid named @a name on @a transform, active exactly on the voxels of @a index, with
/// value values[i] at voxel i. @a values must have index.size() entries.
openvdb::FloatGrid::Ptr arrayToGrid(const VoxelIndex& index, const std::vector<float>& values,
    const openvdb::math::Transform& transform, const std::string& name);
openvdb::Vec3SGrid::Ptr arrayToGrid(const VoxelIndex& index,
    const std::vector<openvdb::Vec3f>& values, const openvdb::math::Transform& transform,
    const std::string& name);

/// @brief The `radiosity` grid of a grey solution (one value per scene voxel), with metadata.
openvdb::GridBase::Ptr makeRadiosityGrid(const Scene& scene, const std::vector<float>& radiosity,
    const SolveStats& stats);
/// @brief The `radiosity` grid of an RGB solution, with metadata.
openvdb::GridBase::Ptr makeRadiosityGrid(const Scene& scene,
    const std::vector<openvdb::Vec3f>& radiosity, const SolveStats& stats);

/// @brief The scene in explicit form: `normal` (world-space unit normals), `albedo` and, if the
/// scene emits, `emission` grids (and `emission_area` if it has one), as the contract's form (b)
/// reads them back.
openvdb::GridPtrVec sceneToGrids(const Scene& scene);

/// @brief @a input's grids and file metadata with @a results added; an input grid with the same
/// name as a result is replaced in place (so a re-solve does not pile up radiosity grids).
VdbFile withGrids(const VdbFile& input, const openvdb::GridPtrVec& results);

} // namespace vdbrad
