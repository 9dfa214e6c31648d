// RayCastVisibility: V(x, sigma) by marching each receiver's digital line through the tree
// (thesis §4.2, the ray-casting approach the line sweeps replace). A reference for LineSweep
// that shares none of its visibility code: no visiting order, no frontier, no bubble repair.
//
// For a receiver x and light travelling along t = +-sigma, the march walks x's line (the same
// LinePartition, centred on the same box, so both methods use the same digital lines) against
// t, one slice of the major axis at a time, and applies the exchange rule of LineSweep.h to
// the chain it meets: x sees the first sender S (t . n > 0) behind it if every voxel between
// them lets light pass (t . n <= 0), none of them hides the next one (the next lies
// `depth` or more behind its plane), and all of them face S's air region. A slice's voxels are
// found from the line's defining inequalities and ordered by LinePartition::position (which
// orders the voxels of standard lines' 2x2 blocks); empty space is crossed by jumping over
// the empty tree nodes (tiles and missing children of the index tree) the line is known to stay
// in, the hierarchical empty-space skipping of OpenVDB's DDA-based ray intersectors.
#pragma once

#include "vdbrad/core/VoxelIndex.h"
#include "vdbrad/sweep/LinePartition.h"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <limits>
#include <vector>

namespace vdbrad {

class RayCastVisibility
{
public:
    static constexpr uint32_t kNone = std::numeric_limits<uint32_t>::max();
    using Accessor = VoxelIndex::Accessor;

    /// @param normals  index-space unit normals, one per voxel of @a index
    /// @param depth    occlusion depth in voxels, > 0 (LineSweep.h)
    /// @param regions  per voxel, the air region it faces (Enclosure.h); null: one region.
    ///                 @a normals and @a regions are kept by reference.
    RayCastVisibility(const VoxelIndex& index, const std::vector<openvdb::Vec3f>& normals,
        LineType lines, float depth = 1.f, const std::vector<uint32_t>* regions = nullptr);

    /// @brief For every voxel x facing sigma or -sigma: visit(x, y, sigmaDotN), x and y voxel
    /// indices of the VoxelIndex, y the voxel x sees (kNone: nothing) and sigmaDotN = sigma . n_x
    /// (< 0: x receives light travelling along +sigma). Thread-safe; one direction per call.
    template<typename VisitT>
    void cast(const openvdb::Coord& sigma, VisitT&& visit) const
    {
        const Line line = makeLine(sigma);
        Accessor acc(mIndex.tree());
        const openvdb::Vec3f s(float(sigma.x()), float(sigma.y()), float(sigma.z()));
        for (size_t x = 0; x < mIndex.size(); ++x) {
            const float dn = s.dot(mNormals[x]);
            if (dn < 0.f) visit(uint32_t(x), seen(line, acc, uint32_t(x), 1.f), dn);
            else if (dn > 0.f) visit(uint32_t(x), seen(line, acc, uint32_t(x), -1.f), dn);
        }
    }

private:
    // A direction's lines and what the march needs of them.
    struct Line
    {
        LinePartition partition;
        openvdb::Coord sigma;
        openvdb::Vec3f s;
        int64_t majorLo, majorHi;   // the box's range on the canonical major axis
    };
    Line makeLine(const openvdb::Coord& sigma) const;

    /// The voxel x sees, light travelling along travel * sigma (kNone: nothing).
    uint32_t seen(const Line& line, Accessor& acc, uint32_t x,
        float travel) const;

    const VoxelIndex& mIndex;
    const std::vector<openvdb::Vec3f>& mNormals;
    const std::vector<uint32_t>* mRegions;   // null: one region
    uint32_t region(uint32_t v) const { return mRegions ? (*mRegions)[v] : 0u; }
    LineType mLines;
    float mDepth;
    openvdb::CoordBBox mBox;
};

} // namespace vdbrad
