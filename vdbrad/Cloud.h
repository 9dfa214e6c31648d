// Cloud: the medium voxels of a fog volume, ready for the transfer sweeps (thesis §6.3).
//
// Every active voxel of the `density` FloatGrid is a medium voxel with extinction coefficient
// sigma_t = density * extinctionScale (per world unit) and single-scattering albedo omega0 from an
// `albedo` grid (float or RGB) or CloudOptions::defaultAlbedo. Arrays use the VoxelIndex numbering.
#pragma once

#include "vdbrad/Attribute.h"
#include "vdbrad/GridContract.h"
#include "vdbrad/VoxelIndex.h"

#include <openvdb/openvdb.h>
#include <openvdb/util/NullInterrupter.h>

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
};

class Cloud
{
public:
    Cloud() = default;
    Cloud(openvdb::math::Transform::Ptr transform, VoxelIndex voxels,
        std::vector<float> extinction, Attribute albedo, std::string densityName);

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

    size_t memUsage() const;

private:
    openvdb::math::Transform::Ptr mTransform;
    VoxelIndex mVoxels;
    std::vector<float> mExtinction;
    Attribute mAlbedo;
    std::string mDensityName;
};

/// @brief Build the cloud of a file's grids (README, "Scene contract").
/// @throw openvdb::KeyError   no density grid
/// @throw openvdb::TypeError  density is not a float grid, albedo neither float nor vec3s
/// @throw openvdb::ValueError no active voxels, NaN/Inf or negative density, albedo outside
///        [0, 1], bad options, mismatched or unsupported transforms
Cloud buildCloud(const openvdb::GridPtrVec& grids, const CloudOptions& options = CloudOptions(),
    openvdb::util::NullInterrupter* interrupt = nullptr);

/// @brief @a cloud repeated copies[k] times along each index axis k, the copies side by side at
/// the period of its bounding box (so a periodic box and its tiling are the same medium).
/// @param source  if not null, set to the voxel of @a cloud that each voxel of the result copies
/// @throw openvdb::ValueError if the result has too many voxels (VoxelIndex)
Cloud tileCloud(const Cloud& cloud, const openvdb::Coord& copies,
    std::vector<uint32_t>* source = nullptr);

} // namespace vdbrad
