// LeafOrder: the order in which a sweep visits the voxels of a VoxelIndex (thesis §4.3.3.4).
//
// Along a monotone digital line of direction sigma every step moves each coordinate by 0 or by
// the sign of sigma's component. So any lexicographic order of the coordinates multiplied by
// those signs visits the voxels of every line in their order along the line: visiting all voxels
// in that order and appending each to its line builds every line already sorted, with no sort.
//
// On an OpenVDB tree the order is built from the leaves: leaf origins sorted lexicographically
// (with the signs), then the voxels inside each leaf. Inside a leaf the linear offset is
// (x&7)<<6 | (y&7)<<3 | (z&7), so the voxels sorted by offset XOR mask, with mask flipping the
// bits of every axis whose sign is negative, are exactly the signed lexicographic order. This
// extends the componentwise order: if q - p has sigma's signs, floor(q/8) - floor(p/8) has them too,
// so q's leaf is p's leaf or comes later.
//
// There are 8 sign patterns; a pattern and its negation give reverse orders, so 4 base orders
// serve every direction, each traversed forwards (sigma) or backwards (-sigma).
#pragma once

#include "vdbrad/VoxelIndex.h"

#include <openvdb/openvdb.h>

#include <array>
#include <cstdint>
#include <vector>

namespace vdbrad {

class LeafOrder
{
public:
    /// Signs of the direction's components; a zero component may take either sign.
    using Signs = std::array<int, 3>;

    /// @brief The signed lexicographic visiting order of @a index's voxels.
    /// @param signs  +1 or -1 per axis
    LeafOrder(const VoxelIndex& index, const Signs& signs);

    const Signs& signs() const { return mSigns; }
    /// Voxel array indices in visiting order (size == index.size()).
    const std::vector<uint32_t>& voxels() const { return mOrder; }
    /// Leaf numbers (VoxelIndex::leafOrigin numbering) in visiting order.
    const std::vector<uint32_t>& leaves() const { return mLeaves; }

    /// @brief The base pattern serving direction @a sigma: signs with x >= 0 (the x sign fixed to
    /// +1, with y and z flipped to match), and whether sigma is served backwards.
    static Signs baseSigns(const openvdb::Coord& sigma, bool& reversed);

private:
    Signs mSigns;
    std::vector<uint32_t> mOrder;
    std::vector<uint32_t> mLeaves;
};

} // namespace vdbrad
