#include "vdbrad/GridContract.h"

#include <cmath>
#include <sstream>

namespace vdbrad {

openvdb::GridBase::ConstPtr
findGrid(const openvdb::GridPtrVec& grids, const std::string& name)
{
    for (const auto& g : grids) {
        if (g && g->getName() == name) return g;
    }
    return nullptr;
}

namespace {

bool isLevelSet(const openvdb::GridBase& g)
{
    return g.getGridClass() == openvdb::GRID_LEVEL_SET && g.isType<openvdb::FloatGrid>();
}

void
requireType(const openvdb::GridBase::ConstPtr& g, bool ok, const char* role, const char* expected)
{
    if (g && !ok) {
        OPENVDB_THROW(openvdb::TypeError, "grid '" << g->getName() << "' (" << role << ") has type "
            << g->valueType() << ", expected " << expected);
    }
}

} // namespace

GridRoles
identifyRoles(const openvdb::GridPtrVec& grids, const std::string& surfaceName,
    const std::string& densityName)
{
    GridRoles roles;
    roles.albedo = findGrid(grids, names::kAlbedo);
    roles.emission = findGrid(grids, names::kEmission);
    roles.density = findGrid(grids, densityName);
    auto colour = [](const openvdb::GridBase::ConstPtr& g) {
        return g->isType<openvdb::FloatGrid>() || g->isType<openvdb::Vec3SGrid>();
    };
    requireType(roles.albedo, roles.albedo && colour(roles.albedo), "albedo", "float or vec3s");
    requireType(roles.emission, roles.emission && colour(roles.emission), "emission",
        "float or vec3s");
    requireType(roles.density, roles.density && roles.density->isType<openvdb::FloatGrid>(),
        "density", "float");
    roles.emissionArea = findGrid(grids, names::kEmissionArea);
    requireType(roles.emissionArea,
        roles.emissionArea && roles.emissionArea->isType<openvdb::FloatGrid>(), "emission_area",
        "float");

    roles.specular = findGrid(grids, names::kSpecular);
    requireType(roles.specular, roles.specular && colour(roles.specular), "specular",
        "float or vec3s");
    roles.roughness = findGrid(grids, names::kRoughness);
    requireType(roles.roughness, roles.roughness && roles.roughness->isType<openvdb::FloatGrid>(),
        "roughness", "float");

    if (!surfaceName.empty()) {
        roles.surface = findGrid(grids, surfaceName);
        if (!roles.surface) {
            OPENVDB_THROW(openvdb::KeyError, "no grid named '" << surfaceName << "'");
        }
        if (roles.surface->isType<openvdb::Vec3SGrid>()) {
            roles.surfaceKind = GridRoles::SurfaceKind::NormalGrid;
        } else if (roles.surface->isType<openvdb::FloatGrid>()) {
            // A named float grid is taken as a signed distance even if its class metadata is
            // missing (some exporters drop it); the user asked for it explicitly.
            roles.surfaceKind = GridRoles::SurfaceKind::LevelSet;
        } else {
            requireType(roles.surface, false, "surface", "float (level set) or vec3s (normals)");
        }
        return roles;
    }

    if (auto normal = findGrid(grids, names::kNormal)) {
        requireType(normal, normal->isType<openvdb::Vec3SGrid>(), "normal", "vec3s");
        roles.surface = normal;
        roles.surfaceKind = GridRoles::SurfaceKind::NormalGrid;
        return roles;
    }
    std::vector<openvdb::GridBase::ConstPtr> levelSets;
    for (const auto& g : grids) {
        if (g && isLevelSet(*g)) levelSets.push_back(g);
    }
    if (levelSets.size() > 1) {
        std::ostringstream os;
        for (size_t i = 0; i < levelSets.size(); ++i) {
            os << (i ? ", " : "") << "'" << levelSets[i]->getName() << "'";
        }
        OPENVDB_THROW(openvdb::ValueError, "several level sets (" << os.str()
            << "): choose the surface with --surface NAME");
    }
    if (levelSets.size() == 1) {
        roles.surface = levelSets[0];
        roles.surfaceKind = GridRoles::SurfaceKind::LevelSet;
    }
    return roles;
}

void
checkTransform(const openvdb::GridBase& grid)
{
    const openvdb::math::Transform& xform = grid.transform();
    if (!xform.isLinear()) {
        OPENVDB_THROW(openvdb::ValueError, "grid '" << grid.getName()
            << "' has a non-linear (frustum) transform; vdbrad needs a linear one");
    }
    if (!xform.hasUniformScale()) {
        OPENVDB_THROW(openvdb::ValueError, "grid '" << grid.getName()
            << "' has non-cubic voxels (voxel size " << xform.voxelSize()
            << "); resample it to a uniform voxel size");
    }
    const double vs = xform.voxelSize()[0];
    if (!std::isfinite(vs) || !(vs > 0.0)) {
        OPENVDB_THROW(openvdb::ValueError, "grid '" << grid.getName() << "' has voxel size " << vs);
    }
    // A file can hold a scale OpenVDB's own maps refuse (|det| below its tolerance, e.g. a voxel
    // size of 1e-30); copying the transform, as every user of the grid does, would throw later.
    try {
        (void)xform.baseMap()->getAffineMap();
    } catch (const openvdb::ArithmeticError&) {
        OPENVDB_THROW(openvdb::ValueError, "grid '" << grid.getName() << "' has voxel size " << vs
            << ", too small for OpenVDB's transforms; rescale the scene");
    }
}

void
checkSameTransform(const openvdb::GridBase& grid, const openvdb::GridBase& reference)
{
    if (grid.transform() != reference.transform()) {
        OPENVDB_THROW(openvdb::ValueError, "grid '" << grid.getName()
            << "' is not on the same transform as '" << reference.getName() << "' (voxel size "
            << grid.transform().voxelSize()[0] << " vs " << reference.transform().voxelSize()[0]
            << "); resample it onto the surface's transform");
    }
}

} // namespace vdbrad
