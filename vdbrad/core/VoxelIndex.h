// VoxelIndex: a sparse voxel set stored as compact arrays in OpenVDB leaf order.
//
// Both the surface scene and the cloud are "some voxels of a tree, each with a few attributes".
// The solver visits them leaf by leaf in direction-dependent orders, so the natural layout is:
//
//   index tree (Int32Tree, background -1)     arrays, one entry per voxel, leaf after leaf
//   +-------- leaf A --------+                [ A0 A1 A2 ... | B0 B1 ... | ... ]
//   | voxel -> array index   |  ----------->   ^ leafBegin(A)  ^ leafBegin(B)
//   +------------------------+
//
// Leaves are numbered in the tree's own iteration order (tree::LeafManager order) and, within a
// leaf, voxels in increasing linear offset, i.e. x-major then y then z: a lexicographic order,
// which the sweep orders of the method extend (thesis §4.3.3.4). Attribute arrays (normals,
// albedo, ...) live beside the index in the owning class (Scene, Cloud) and use the same numbering.
#pragma once

#include <openvdb/openvdb.h>

#include <cstdint>
#include <vector>

namespace vdbrad {

class VoxelIndex
{
public:
    using IndexTree = openvdb::Int32Tree;
    using IndexGrid = openvdb::Int32Grid;

    VoxelIndex();

    /// @brief Index the active voxels of @a mask (any topology; its values are ignored).
    /// @throw openvdb::ValueError as checkVoxelCount(), before allocating anything.
    explicit VoxelIndex(const openvdb::MaskTree& mask);

    /// Number of voxels.
    size_t size() const { return mCoords.size(); }
    bool empty() const { return mCoords.empty(); }

    /// Index-space coordinate of voxel @a i.
    const openvdb::Coord& coord(size_t i) const { return mCoords[i]; }
    const std::vector<openvdb::Coord>& coords() const { return mCoords; }

    /// Number of leaf nodes, and the half-open voxel range [leafBegin(n), leafBegin(n + 1)).
    size_t leafCount() const { return mLeafBegin.empty() ? 0 : mLeafBegin.size() - 1; }
    size_t leafBegin(size_t n) const { return mLeafBegin[n]; }
    /// Origin (minimum corner) of leaf @a n.
    const openvdb::Coord& leafOrigin(size_t n) const { return mLeafOrigins[n]; }

    /// Array index of the voxel at @a ijk, or -1 if it is not in the set.
    int32_t find(const openvdb::Coord& ijk) const { return mTree->getValue(ijk); }

    /// The index tree: active exactly on the set, value = array index, background -1.
    const IndexTree& tree() const { return *mTree; }

    using Accessor = openvdb::tree::ValueAccessor<const IndexTree>;
    /// @brief Side of the empty node holding @a ijk (a tile or a missing child: 8, 128 or 4096,
    /// aligned on multiples of it), or 1 if @a ijk lies in a leaf. What ray marches jump over.
    static int64_t emptyNodeSide(Accessor& acc, const openvdb::Coord& ijk)
    {
        const int depth = acc.getValueDepth(ijk);   // -1: background, 0 root, 1, 2 internal, 3 leaf
        return depth <= 0 ? 4096 : depth == 1 ? 128 : depth == 2 ? 8 : 1;
    }

    /// Index-space bounding box of the set (empty box if the set is empty).
    openvdb::CoordBBox bbox() const;

    /// @brief Refuse a set of @a count voxels before allocating it.
    /// @throw openvdb::ValueError above 2^31 - 1 voxels, or if the index alone would not fit in
    ///        this machine's physical memory
    static void checkVoxelCount(uint64_t count);

private:
    IndexTree::Ptr mTree;
    std::vector<openvdb::Coord> mCoords;
    std::vector<size_t> mLeafBegin;
    std::vector<openvdb::Coord> mLeafOrigins;
};

} // namespace vdbrad
