// What the tool does with an input's grids once they are parsed, for the fuzz targets: describe
// them (`vdbrad info`), find their roles, build the Scene and the Cloud, and solve, render and
// write small ones (`solve`, `render`, `solve-cloud`, `surface`). Expected failures are the
// library's exceptions for bad input (openvdb::Exception); anything else escaping, a crash or a
// sanitizer report is a finding.
#pragma once

#include "vdbrad/cloud/CloudTransfer.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/vdbrad.h"

#include <cstddef>

namespace vdbrad {
namespace fuzz {

// Inputs small enough to solve and render on every execution; larger ones stop after building.
constexpr size_t kMaxSolvedVoxels = 4096;

// One sweep over 3 direction pairs: every stage of a solve, at the least cost.
inline openvdb::GridBase::Ptr
tinySolve(const Scene& scene)
{
    RadiosityOptions o;
    o.directions = 3;
    o.maxIterations = 1;
    RadiositySolver solver(scene, o);
    solver.solve();
    return solver.grid();
}

inline openvdb::GridBase::Ptr
tinySolve(const Cloud& cloud)
{
    CloudTransferOptions o;
    o.directions = 3;
    o.maxIterations = 1;
    CloudTransfer transfer(cloud, o);
    transfer.solve();
    return transfer.grid();
}

inline void
useFile(const VdbFile& file)
{
    // `vdbrad info`: the description of every grid, whatever its type.
    for (const auto& g : file.grids) {
        (void)g->evalActiveVoxelBoundingBox();
        (void)g->activeVoxelCount();
        (void)g->transform().voxelSize();
    }
    const GridRoles roles = identifyRoles(file.grids);
    if (roles.surface) {
        try {
            const Scene scene = buildScene(file.grids, SceneOptions());
            // `vdbrad surface`: the scene's grids plus the input's, serialised.
            (void)serializeVdb(withGrids(file, sceneToGrids(scene)));
            if (scene.size() <= kMaxSolvedVoxels) {
                RenderOptions r;
                r.width = r.height = 4;
                (void)renderImage(withGrids(file, {tinySolve(scene)}).grids, r);
            }
        } catch (const openvdb::Exception&) {
        }
    }
    if (roles.density) {
        try {
            const Cloud cloud = buildCloud(file.grids);
            if (cloud.size() <= kMaxSolvedVoxels) {
                (void)serializeVdb(withGrids(file, {tinySolve(cloud)}));
            }
        } catch (const openvdb::Exception&) {
        }
    }
}

} // namespace fuzz
} // namespace vdbrad
