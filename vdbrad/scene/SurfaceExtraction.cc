#include "vdbrad/scene/SurfaceExtraction.h"

#include "vdbrad/core/Attribute.h"
#include "vdbrad/core/Errors.h"
#include "vdbrad/core/VoxelIndex.h"

#include <openvdb/tools/Prune.h>
#include <openvdb/tree/LeafManager.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <cmath>

namespace vdbrad {

namespace {

// Neighbour offsets: the first 6 are the faces, all 26 the full neighbourhood.
std::vector<openvdb::Coord>
neighbourOffsets(int separation)
{
    std::vector<openvdb::Coord> faces = {{1, 0, 0}, {-1, 0, 0}, {0, 1, 0}, {0, -1, 0},
        {0, 0, 1}, {0, 0, -1}};
    if (separation == 6) return faces;
    for (int i = -1; i <= 1; ++i) for (int j = -1; j <= 1; ++j) for (int k = -1; k <= 1; ++k) {
        if (std::abs(i) + std::abs(j) + std::abs(k) >= 2) faces.emplace_back(i, j, k);
    }
    return faces;
}

} // namespace

openvdb::MaskTree::Ptr
extractSurfaceVoxels(const openvdb::FloatGrid& levelSet, int separation,
    openvdb::util::NullInterrupter* interrupt)
{
    if (separation != 6 && separation != 26) {
        OPENVDB_THROW(openvdb::ValueError, "separation must be 6 or 26, got " << separation);
    }
    const std::vector<openvdb::Coord> offsets = neighbourOffsets(separation);

    // Active tiles are densified below: a corrupt or hostile level set (a 4096^3 active tile is a
    // few bytes on disk) must be refused before that allocates.
    VoxelIndex::checkVoxelCount(levelSet.activeVoxelCount());
    // Start from the level set's active topology and switch off what is not on the boundary;
    // leaves are independent, so this is a plain parallel loop with no locking.
    auto mask = std::make_shared<openvdb::MaskTree>(levelSet.tree(), false, openvdb::TopologyCopy());
    mask->voxelizeActiveTiles();
    openvdb::tree::LeafManager<openvdb::MaskTree> leaves(*mask);
    if (interrupt) interrupt->start("extracting surface voxels");
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leaves.leafCount()),
        [&](const tbb::blocked_range<size_t>& r) {
            if (openvdb::util::wasInterrupted(interrupt)) return;
            auto acc = levelSet.getConstAccessor();
            for (size_t n = r.begin(); n != r.end(); ++n) {
                auto& leaf = leaves.leaf(n);
                // Iterate a copy of the mask: bits are switched off as we go.
                const auto active = leaf.getValueMask();
                for (auto it = active.beginOn(); it; ++it) {
                    const openvdb::Coord ijk = leaf.offsetToGlobalCoord(it.pos());
                    const float phi = acc.getValue(ijk);
                    if (!std::isfinite(phi)) {
                        OPENVDB_THROW(openvdb::ValueError, "level set '" << levelSet.getName()
                            << "' has value " << phi << " at voxel " << formatCoord(ijk));
                    }
                    bool boundary = false;
                    if (phi <= 0.f) {
                        for (const auto& o : offsets) {
                            if (acc.getValue(ijk + o) > 0.f) { boundary = true; break; }
                        }
                    }
                    if (!boundary) leaf.setValueOff(it.pos());
                }
            }
        });
    if (interrupt) interrupt->end();
    if (openvdb::util::wasInterrupted(interrupt)) throw Cancelled("surface extraction");
    openvdb::tools::pruneInactive(*mask);
    return mask;
}

std::vector<openvdb::Vec3f>
levelSetNormals(const openvdb::FloatGrid& levelSet, const VoxelIndex& index)
{
    const std::vector<openvdb::Coord> all = neighbourOffsets(26);
    std::vector<openvdb::Vec3f> normals(index.size());
    tbb::parallel_for(tbb::blocked_range<size_t>(0, index.leafCount()),
        [&](const tbb::blocked_range<size_t>& r) {
            auto acc = levelSet.getConstAccessor();
            for (size_t n = r.begin(); n != r.end(); ++n) {
                for (size_t i = index.leafBegin(n); i < index.leafBegin(n + 1); ++i) {
                    const openvdb::Coord& c = index.coord(i);
                    openvdb::Vec3f g(
                        acc.getValue(c.offsetBy(1, 0, 0)) - acc.getValue(c.offsetBy(-1, 0, 0)),
                        acc.getValue(c.offsetBy(0, 1, 0)) - acc.getValue(c.offsetBy(0, -1, 0)),
                        acc.getValue(c.offsetBy(0, 0, 1)) - acc.getValue(c.offsetBy(0, 0, -1)));
                    if (!(g.length() > 1e-6f) || !std::isfinite(g.length())) {
                        g = openvdb::Vec3f(0.f);
                        for (const auto& o : all) {
                            if (acc.getValue(c + o) > 0.f) g += openvdb::Vec3f(o.asVec3s()).unit();
                        }
                    }
                    // A voxel with an outside neighbour always gets a non-zero fallback, except
                    // for perfectly symmetric configurations (an isolated voxel): pick +y there
                    // rather than emit NaN.
                    normals[i] = g.length() > 1e-6f ? g.unit() : openvdb::Vec3f(0.f, 1.f, 0.f);
                }
            }
        });
    return normals;
}

} // namespace vdbrad
