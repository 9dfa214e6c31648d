#include "vdbrad/SurfacePlanes.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <cmath>

namespace vdbrad {

namespace {
// The neighbourhood: a cube of 2 kReach + 1 voxels. One voxel each way is not enough: a voxel at
// the edge of a 45-degree wall's band (3 voxels deep) sees only its own side of the band.
constexpr int kReach = 2;
} // namespace

SurfacePlanes
surfacePlanes(const Scene& scene)
{
    const VoxelIndex& voxels = scene.voxels();
    SurfacePlanes planes;
    planes.offset.assign(scene.size(), 0.f);
    planes.spread.assign(scene.size(), openvdb::Vec3f(0.f));
    tbb::parallel_for(tbb::blocked_range<size_t>(0, voxels.leafCount()),
        [&](const tbb::blocked_range<size_t>& r) {
            VoxelIndex::Accessor acc(voxels.tree());
            for (size_t leaf = r.begin(); leaf != r.end(); ++leaf) {
                for (size_t i = voxels.leafBegin(leaf); i < voxels.leafBegin(leaf + 1); ++i) {
                    const openvdb::Coord c = voxels.coord(i);
                    const openvdb::Vec3f& n = scene.normal(i);
                    openvdb::Vec3d sum(0.0);   // of c_j - c over the wall's voxels around
                    int count = 1;             // the voxel itself, at 0
                    for (int dx = -kReach; dx <= kReach; ++dx) {
                        for (int dy = -kReach; dy <= kReach; ++dy) {
                            for (int dz = -kReach; dz <= kReach; ++dz) {
                                if (dx == 0 && dy == 0 && dz == 0) continue;
                                const int32_t j = acc.getValue(c.offsetBy(dx, dy, dz));
                                if (j < 0 || scene.normal(size_t(j)).dot(n) < kSameWall) continue;
                                sum += openvdb::Vec3d(dx, dy, dz);
                                ++count;
                            }
                        }
                    }
                    const double half = 0.5 * (std::abs(n[0]) + std::abs(n[1]) + std::abs(n[2]));
                    const openvdb::Vec3d mean = sum / double(count);
                    planes.offset[i] = float(std::clamp(openvdb::Vec3d(n).dot(mean), -half, half));
                    planes.spread[i] = openvdb::Vec3f(mean);
                }
            }
        });
    return planes;
}

} // namespace vdbrad
