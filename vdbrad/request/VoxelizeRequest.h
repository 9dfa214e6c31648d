// VoxelizeRequest: `vdbrad voxelize` and vdbrad.voxelize() described once: the options of a
// mesh's voxelization (voxelizeMeshOptions()), read into VoxelizeOptions, and what both hosts
// warn of.
#pragma once

#include "vdbrad/request/Request.h"

#include "vdbrad/mesh/Mesh.h"
#include "vdbrad/mesh/Voxelizer.h"

#include <string>
#include <vector>

namespace vdbrad {

const std::vector<OptionSpec>& voxelizeMeshOptions();

/// @throw OptionError for options that contradict each other
VoxelizeOptions voxelizeOptions(const Request& request);

/// @brief What a user should hear of @a mesh (read from @a path) voxelized with @a options:
/// the reader's warnings, materials whose Kd + Ks exceeds 1.
std::vector<std::string> meshWarnings(const TriangleMesh& mesh, const std::string& path,
    const VoxelizeOptions& options, const Request& request);

/// @brief What a user should hear of the voxelized @a grids of @a path: nothing emits.
std::vector<std::string> sceneWarnings(const openvdb::GridPtrVec& grids, const std::string& path);

} // namespace vdbrad
