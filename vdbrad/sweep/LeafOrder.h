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
// extends the componentwise order: if q - p has sigma's signs, floor(q/8) - floor(p/8) has them
// too, so q's leaf is p's leaf or comes later.
//
// There are 8 sign patterns; a pattern and its negation give reverse orders, so 4 base orders
// serve every direction, each traversed forwards (sigma) or backwards (-sigma).
#pragma once

#include "vdbrad/core/VoxelIndex.h"

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

    /// The directions of a set dealt to the four base patterns, as every solver sweeps them.
    struct Patterns
    {
        std::array<Signs, 4> signs{};                     ///< pattern p's base signs
        std::array<std::vector<size_t>, 4> directions;    ///< direction indices of pattern p
        std::vector<char> reversed;                       ///< per direction: served backwards
    };
    /// @brief Deal @a directions (their count, and the k-th one) to patterns
    /// p = 2 (y sign < 0) + (z sign < 0).
    template<typename DirectionOf>
    static Patterns patterns(size_t count, DirectionOf&& directionOf)
    {
        Patterns out;
        out.reversed.resize(count);
        for (size_t k = 0; k < count; ++k) {
            bool rev = false;
            const Signs signs = baseSigns(directionOf(k), rev);
            const size_t p = size_t((signs[1] < 0 ? 2 : 0) + (signs[2] < 0 ? 1 : 0));
            out.signs[p] = signs;
            out.directions[p].push_back(k);
            out.reversed[k] = rev ? 1 : 0;
        }
        return out;
    }

private:
    Signs mSigns;
    std::vector<uint32_t> mOrder;
    std::vector<uint32_t> mLeaves;
};

} // namespace vdbrad
