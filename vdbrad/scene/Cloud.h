// Cloud: the medium voxels of a fog volume, ready for the transfer sweeps (thesis §6.3).
//
// Every active voxel of the `density` FloatGrid is a medium voxel with extinction coefficient
// sigma_t = density * extinctionScale (per world unit) and single-scattering albedo omega0 from an
// `albedo` grid (float or RGB) or CloudOptions::defaultAlbedo. Arrays use the VoxelIndex numbering.
//
// Emission (fire): an optional grid (CloudOptions::emission; by default Blender's and Houdini's
// `flame`) read as the volume emission coefficient epsilon = value x emissionScale x
// emissionColour, radiance added per world unit of path and emitted the same in every
// direction, as a path tracer's volume emission. The medium emits through its extinction (the
// transfer's source is epsilon / sigma_t), so a voxel that emits where the density is 0 or that
// is not a density voxel emits nothing: Cloud::lostEmitters() counts them, for a warning.
#pragma once

#include "vdbrad/core/Attribute.h"
#include "vdbrad/core/GridContract.h"
#include "vdbrad/core/VoxelIndex.h"

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

#include <array>
#include <string>
#include <vector>

namespace vdbrad {

struct CloudOptions
{
    std::string density = names::kDensity;  ///< name of the density grid
    float extinctionScale = 1.f;            ///< multiplies density, > 0 and finite
    float defaultAlbedo = 1.f;              ///< omega0 where no `albedo` grid, in [0, 1]
    /// Read omega0 from the `albedo` grid if there is one; false where that grid is a surface
    /// scene's (a fog inside surfaces, CloudTransferOptions::surfaces): defaultAlbedo then.
    bool albedoGrid = true;
    /// The grid of emission strength (float or double); empty: `flame` if the file has one.
    std::string emission;
    float emissionScale = 1.f;                             ///< >= 0 and finite
    openvdb::Vec3f emissionColour = openvdb::Vec3f(1.f);   ///< each channel >= 0 and finite
};

class Cloud
{
public:
    Cloud() = default;
    Cloud(openvdb::math::Transform::Ptr transform, VoxelIndex voxels,
        std::vector<float> extinction, Attribute albedo, std::string densityName,
        Attribute emission = Attribute(0.f));

    size_t size() const { return mVoxels.size(); }
    const VoxelIndex& voxels() const { return mVoxels; }
    const openvdb::math::Transform& transform() const { return *mTransform; }
    double voxelSize() const { return mTransform->voxelSize()[0]; }

    /// Extinction coefficient of voxel @a i, per world unit.
    float extinction(size_t i) const { return mExtinction[i]; }
    const std::vector<float>& extinctionArray() const { return mExtinction; }
    /// Single-scattering albedo.
    const Attribute& albedo() const { return mAlbedo; }
    const std::string& densityName() const { return mDensityName; }
    /// Volume emission coefficient epsilon per voxel (radiance per world unit; zero where the
    /// extinction is), grey or RGB; uniform 0 without an emission grid.
    const Attribute& emission() const { return mEmission; }
    /// The emission grid's name ("" without one).
    const std::string& emissionName() const { return mEmissionName; }
    /// Emitting voxels of the emission grid that emit nothing here: outside the density's
    /// active voxels or where the extinction is 0.
    size_t lostEmitters() const { return mLostEmitters; }
    /// Set what emission() and the two above return (buildCloud: from the emission grid).
    void setEmission(Attribute emission, std::string name, size_t lost)
    {
        mEmission = std::move(emission);
        mEmissionName = std::move(name);
        mLostEmitters = lost;
    }

    size_t memUsage() const;

private:
    openvdb::math::Transform::Ptr mTransform;
    VoxelIndex mVoxels;
    std::vector<float> mExtinction;
    Attribute mAlbedo;
    std::string mDensityName;
    Attribute mEmission;
    std::string mEmissionName;
    size_t mLostEmitters = 0;
};

/// @brief Build the cloud of a file's grids (docs/scene-contract.md).
/// @throw openvdb::KeyError   no density grid
/// @throw openvdb::TypeError  density is not a float grid, albedo neither float nor vec3s
/// @throw openvdb::KeyError   a named emission grid missing
/// @throw openvdb::ValueError no active voxels, NaN/Inf or negative density or emission, albedo
///        outside [0, 1], bad options, mismatched or unsupported transforms
Cloud buildCloud(const openvdb::GridPtrVec& grids, const CloudOptions& options = CloudOptions(),
    openvdb::util::NullInterrupter* interrupt = nullptr);

/// @brief Record in @a result (a solve's mean radiance grid) how @a options read the emission,
/// so that a renderer of the solved file reads it alike (emissionAsSolved()).
void recordEmission(openvdb::GridBase& result, const Cloud& cloud, const CloudOptions& options);

/// @brief @a options with the emission settings recorded in @a result, if any.
CloudOptions emissionAsSolved(const openvdb::GridBase& result, CloudOptions options);

/// @brief @a cloud repeated copies[k] times along each index axis k, the copies side by side at
/// the period of its bounding box (so a periodic box and its tiling are the same medium).
/// @param source  if not null, set to the voxel of @a cloud that each voxel of the result copies
/// @throw openvdb::ValueError if the result has too many voxels (VoxelIndex)
Cloud tileCloud(const Cloud& cloud, const openvdb::Coord& copies,
    std::vector<uint32_t>* source = nullptr);

/// Marks a voxel that copies none of the cloud's (filledBox(); GroundLayer's cells likewise).
constexpr uint32_t kNoCloudVoxel = Attribute::kNone;

/// @brief @a cloud with every voxel of its bounding box, the added ones empty (no extinction,
/// albedo or emission). A periodic box's side faces pass light layer by layer between the
/// lines of a dense box (PeriodicBoundary.h); a sparse medium's lines would not match.
/// @param source  if not null, set to the voxel of @a cloud that each voxel of the result is,
///                kNoCloudVoxel for the added ones
/// @throw openvdb::ValueError if the box has too many voxels (VoxelIndex)
Cloud filledBox(const Cloud& cloud, std::vector<uint32_t>* source = nullptr);

/// @brief The axes other than @a up along which @a cloud does not vary over its bounding box:
/// every voxel's neighbour along the axis (the box's far layer wrapping to its first) is a
/// voxel too, of the same extinction, albedo and emission. A periodic box uniform along an axis
/// is the same medium one voxel deep along it (sliceCloud()), which the transfer sweeps in the
/// plane of the other axes, however many layers the file happened to have.
std::array<bool, 3> uniformAxes(const Cloud& cloud, int up);

/// @brief The first layer of @a cloud's bounding box along each axis of @a axes: one voxel
/// deep along them.
Cloud sliceCloud(const Cloud& cloud, const std::array<bool, 3>& axes);

} // namespace vdbrad
