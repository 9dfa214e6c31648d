// MeshTracer: first hits of rays on a triangle mesh, so that a picture of a voxel solve can show
// the surface the scene was voxelised from (exact outlines) while its shading still comes from
// the voxels.
//
// A voxelised wall is drawn as voxel cubes (or planes within them) that stick out up to a voxel
// beyond the mesh: at the main job's settings that outline error is two thirds of the picture's
// error against a path tracer of the same mesh (docs/journal/2026-12-03-against-blender-cycles.md).
// The tracer bins the triangles into a sparse grid of cubic cells (a VoxelIndex over the cells any
// triangle meets, exactly, by the voxelizer's separating-axis test) and walks a ray through the
// cells with the renderer's own hierarchical march, testing the triangles of each cell
// (Moller-Trumbore, two-sided) until a hit lies within the cells already crossed.
#pragma once

#include "vdbrad/core/VoxelIndex.h"
#include "vdbrad/mesh/Mesh.h"

#include <openvdb/openvdb.h>

#include <cstdint>
#include <vector>

namespace vdbrad {

class MeshTracer
{
public:
    using Accessor = VoxelIndex::Accessor;

    struct Hit
    {
        double t = 0.0;            ///< world distance along the ray's unit direction
        openvdb::Vec3d normal;     ///< unit geometric normal, facing the ray's origin
        uint32_t triangle = 0;     ///< index into the mesh's triangles
    };

    /// @brief Bin @a mesh's triangles (world space) into cells of edge @a cellSize (world units).
    /// Triangles of zero area are left out (a ray cannot see them).
    /// @throw openvdb::ValueError a non-positive or non-finite cell size, non-finite points, or a
    ///        mesh that would need more than 2^31 - 1 cells
    MeshTracer(const TriangleMesh& mesh, double cellSize);

    /// World-space bounds of the triangles (empty if none has an area).
    const openvdb::BBoxd& bounds() const { return mBounds; }
    size_t triangleCount() const { return mTriangles.size(); }

    /// An accessor for intersect(), one per thread.
    Accessor accessor() const { return Accessor(mCells.tree()); }

    /// @brief The nearest hit of the ray @a eye + t @a dir (@a dir a unit vector, world space)
    /// with t in [@a t0, @a t1], if any.
    bool intersect(const openvdb::Vec3d& eye, const openvdb::Vec3d& dir, double t0, double t1,
        Hit& hit, Accessor& acc) const;

private:
    struct Triangle
    {
        openvdb::Vec3d a, ab, ac;   // a vertex and the two edges from it
        uint32_t id;
    };
    double mCell;
    std::vector<Triangle> mTriangles;
    VoxelIndex mCells;
    std::vector<uint32_t> mBegin;   // per cell (VoxelIndex numbering): its range in mList
    std::vector<uint32_t> mList;    // indices into mTriangles, cell after cell
    openvdb::CoordBBox mCellBox;
    openvdb::BBoxd mBounds;
};

} // namespace vdbrad
