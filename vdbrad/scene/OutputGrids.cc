#include "vdbrad/scene/OutputGrids.h"

#include "vdbrad/core/Version.h"

#include <openvdb/tree/LeafManager.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace vdbrad {

namespace {

template<typename GridT>
typename GridT::Ptr
fillGrid(const VoxelIndex& index, const std::vector<typename GridT::ValueType>& values,
    const openvdb::math::Transform& transform, const std::string& name)
{
    using ValueT = typename GridT::ValueType;
    if (values.size() != index.size()) {
        OPENVDB_THROW(openvdb::ValueError, "grid '" << name << "': " << values.size()
            << " values for " << index.size() << " voxels");
    }
    using TreeT = typename GridT::TreeType;
    auto tree = std::make_shared<TreeT>(index.tree(), openvdb::zeroVal<ValueT>(),
        openvdb::TopologyCopy());
    // The copied leaves come in the same order as the index's, so leaf n holds voxels
    // [leafBegin(n), leafBegin(n+1)) in the same within-leaf order.
    openvdb::tree::LeafManager<TreeT> leaves(*tree);
    tbb::parallel_for(tbb::blocked_range<size_t>(0, leaves.leafCount()),
        [&](const tbb::blocked_range<size_t>& r) {
            for (size_t n = r.begin(); n != r.end(); ++n) {
                size_t i = index.leafBegin(n);
                for (auto it = leaves.leaf(n).beginValueOn(); it; ++it, ++i) it.setValue(values[i]);
            }
        });
    auto grid = GridT::create(tree);
    grid->setTransform(transform.copy());
    grid->setName(name);
    return grid;
}

void
addStats(openvdb::GridBase& grid, const Scene& scene, const SolveStats& stats)
{
    grid.insertMeta(meta::kVoxels, openvdb::Int32Metadata(int32_t(scene.size())));
    grid.insertMeta(meta::kDirections, openvdb::Int32Metadata(stats.directions));
    grid.insertMeta(meta::kIterations, openvdb::Int32Metadata(stats.iterations));
    grid.insertMeta(meta::kResidual, openvdb::FloatMetadata(float(stats.residual)));
    grid.insertMeta(meta::kSeconds, openvdb::FloatMetadata(float(stats.seconds)));
    grid.insertMeta(meta::kLines, openvdb::StringMetadata(stats.lines));
    grid.insertMeta(meta::kVersion, openvdb::StringMetadata(VDBRAD_VERSION_STRING));
}

} // namespace

openvdb::FloatGrid::Ptr
arrayToGrid(const VoxelIndex& index, const std::vector<float>& values,
    const openvdb::math::Transform& transform, const std::string& name)
{
    return fillGrid<openvdb::FloatGrid>(index, values, transform, name);
}

openvdb::Vec3SGrid::Ptr
arrayToGrid(const VoxelIndex& index, const std::vector<openvdb::Vec3f>& values,
    const openvdb::math::Transform& transform, const std::string& name)
{
    return fillGrid<openvdb::Vec3SGrid>(index, values, transform, name);
}

openvdb::GridBase::Ptr
makeRadiosityGrid(const Scene& scene, const std::vector<float>& radiosity, const SolveStats& stats)
{
    auto grid = arrayToGrid(scene.voxels(), radiosity, scene.transform(), names::kRadiosity);
    addStats(*grid, scene, stats);
    return grid;
}

openvdb::GridBase::Ptr
makeRadiosityGrid(const Scene& scene, const std::vector<openvdb::Vec3f>& radiosity,
    const SolveStats& stats)
{
    auto grid = arrayToGrid(scene.voxels(), radiosity, scene.transform(), names::kRadiosity);
    grid->setVectorType(openvdb::VEC_INVARIANT);   // a colour, not a direction
    addStats(*grid, scene, stats);
    return grid;
}

openvdb::GridPtrVec
sceneToGrids(const Scene& scene)
{
    std::vector<openvdb::Vec3f> normals(scene.size());
    for (size_t i = 0; i < scene.size(); ++i) normals[i] = scene.worldNormal(i);
    auto normal = arrayToGrid(scene.voxels(), normals, scene.transform(), names::kNormal);
    normal->setVectorType(openvdb::VEC_COVARIANT_NORMALIZE);

    auto attributeGrid = [&](const Attribute& a, const char* name) -> openvdb::GridBase::Ptr {
        if (a.isRgb()) {
            auto g = arrayToGrid(scene.voxels(), a.rgbArray(), scene.transform(), name);
            g->setVectorType(openvdb::VEC_INVARIANT);
            return g;
        }
        std::vector<float> v = a.greyArray();
        if (a.isUniform()) v.assign(scene.size(), a.uniformValue());
        return arrayToGrid(scene.voxels(), v, scene.transform(), name);
    };
    openvdb::GridPtrVec out{normal, attributeGrid(scene.albedo(), names::kAlbedo)};
    if (scene.hasEmission()) out.push_back(attributeGrid(scene.emission(), names::kEmission));
    if (scene.hasEmissionArea()) {
        // Back to world units^2 (the scene holds voxel faces).
        const double face = scene.voxelSize() * scene.voxelSize();
        std::vector<float> area(scene.size());
        for (size_t i = 0; i < area.size(); ++i) {
            area[i] = float(scene.emissionArea().grey(i) * face);
        }
        out.push_back(arrayToGrid(scene.voxels(), area, scene.transform(), names::kEmissionArea));
    }
    if (scene.isGlossy()) {
        out.push_back(attributeGrid(scene.specular(), names::kSpecular));
        out.push_back(attributeGrid(scene.roughness(), names::kRoughness));
    }
    return out;
}

VdbFile
withGrids(const VdbFile& input, const openvdb::GridPtrVec& results)
{
    VdbFile out;
    out.metadata = input.metadata ? std::make_shared<openvdb::MetaMap>(*input.metadata)
                                  : std::make_shared<openvdb::MetaMap>();
    out.grids = input.grids;
    for (const auto& r : results) {
        bool replaced = false;
        for (auto& g : out.grids) {
            if (g && g->getName() == r->getName()) { g = r; replaced = true; break; }
        }
        if (!replaced) out.grids.push_back(r);
    }
    return out;
}

} // namespace vdbrad
