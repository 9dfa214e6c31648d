#include "vdbrad/core/GridContract.h"

#include "vdbrad/core/Attribute.h"

#include <algorithm>
#include <cmath>
#include <limits>
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

bool
GridRoles::uses(const openvdb::GridBase::ConstPtr& grid) const
{
    return std::find(sources.begin(), sources.end(), grid) != sources.end();
}

namespace {

bool isScalar(const openvdb::GridBase& g)
{
    return g.isType<openvdb::FloatGrid>() || g.isType<openvdb::DoubleGrid>();
}

bool isVector(const openvdb::GridBase& g)
{
    return g.isType<openvdb::Vec3SGrid>() || g.isType<openvdb::Vec3DGrid>();
}

bool isLevelSet(const openvdb::GridBase& g)
{
    return g.getGridClass() == openvdb::GRID_LEVEL_SET && isScalar(g);
}

double magnitude(double v) { return std::abs(v); }
double magnitude(const openvdb::Vec3d& v)
{
    return std::max({std::abs(v[0]), std::abs(v[1]), std::abs(v[2])});
}

template<typename ToGridT, typename FromGridT>
openvdb::GridBase::ConstPtr
converted(const FromGridT& from)
{
    // float's range, not its precision, is what a conversion can lose: an overflow would
    // become an infinity the samplers then report far from its cause.
    const double limit = double(std::numeric_limits<float>::max());
    auto check = [&](const auto& v, const openvdb::Coord& ijk) {
        const double m = magnitude(v);
        if (std::isfinite(m) && m > limit) {
            OPENVDB_THROW(openvdb::ValueError, "grid '" << from.getName() << "' holds " << m
                << " at " << formatCoord(ijk) << ", beyond single precision (vdbrad computes "
                "in float)");
        }
    };
    check(from.background(), openvdb::Coord());
    // Every value, active or not (samplers read inactive ones too; a level set's sign lives in
    // them): the same topology, then both trees' values in lock step.
    using ToT = typename ToGridT::ValueType;
    auto tree = std::make_shared<typename ToGridT::TreeType>(from.tree(),
        ToT(from.background()), openvdb::TopologyCopy());
    auto to = tree->beginValueAll();
    for (auto it = from.tree().cbeginValueAll(); it; ++it, ++to) {
        if (!to || to.getCoord() != it.getCoord()) {
            OPENVDB_THROW(openvdb::ValueError, "grid '" << from.getName() << "': its copy in "
                "single precision does not have its topology");
        }
        check(*it, it.getCoord());
        to.setValue(ToT(*it));
    }
    typename ToGridT::Ptr grid = ToGridT::create(tree);
    grid->insertMeta(from);   // name, class, vector type and the rest
    grid->setTransform(from.transform().copy());
    return grid;
}

} // namespace

openvdb::GridBase::ConstPtr
singlePrecision(const openvdb::GridBase::ConstPtr& grid, std::string* note)
{
    if (note) note->clear();
    if (!grid) return grid;
    auto say = [&](const std::string& what) {
        if (note) *note = "grid '" + grid->getName() + "': " + what;
    };
    if (auto d = openvdb::GridBase::constGrid<openvdb::DoubleGrid>(grid)) {
        say("double values read as float (the solvers' precision; relative rounding <= 6e-8)");
        return converted<openvdb::FloatGrid>(*d);
    }
    if (auto d = openvdb::GridBase::constGrid<openvdb::Vec3DGrid>(grid)) {
        say("vec3d values read as vec3s (the solvers' precision; relative rounding <= 6e-8)");
        return converted<openvdb::Vec3SGrid>(*d);
    }
    if (grid->saveFloatAsHalf()) say("stored as half floats (about 3 significant digits)");
    return grid;
}

namespace {

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
    // Each role's grid of the file, type-checked, in single precision.
    auto take = [&](openvdb::GridBase::ConstPtr& role, const openvdb::GridBase::ConstPtr& g,
                    const char* name, bool ok, const char* expected) {
        if (!g) return;
        requireType(g, ok, name, expected);
        roles.sources.push_back(g);
        std::string note;
        role = singlePrecision(g, &note);
        if (!note.empty()) roles.notes.push_back(note);
    };
    auto colour = [](const openvdb::GridBase::ConstPtr& g) {
        return isScalar(*g) || isVector(*g);
    };
    const char* colours = "float, double, vec3s or vec3d";
    const char* scalars = "float or double";
    openvdb::GridBase::ConstPtr albedo = findGrid(grids, names::kAlbedo);
    for (const char* alias : {names::kHoudiniColour, names::kBlenderColour}) {
        if (albedo) break;
        albedo = findGrid(grids, alias);
        if (albedo) {
            roles.notes.push_back(std::string("grid '") + alias + "' taken as the albedo (no "
                "'albedo' grid)");
        }
    }
    take(roles.albedo, albedo, "albedo", albedo && colour(albedo), colours);
    const auto emission = findGrid(grids, names::kEmission);
    take(roles.emission, emission, "emission", emission && colour(emission), colours);
    const auto density = findGrid(grids, densityName);
    take(roles.density, density, "density", density && isScalar(*density), scalars);
    const auto area = findGrid(grids, names::kEmissionArea);
    take(roles.emissionArea, area, "emission_area", area && isScalar(*area), scalars);
    const auto specular = findGrid(grids, names::kSpecular);
    take(roles.specular, specular, "specular", specular && colour(specular), colours);
    const auto roughness = findGrid(grids, names::kRoughness);
    take(roles.roughness, roughness, "roughness", roughness && isScalar(*roughness), scalars);

    if (!surfaceName.empty()) {
        const auto surface = findGrid(grids, surfaceName);
        if (!surface) {
            OPENVDB_THROW(openvdb::KeyError, "no grid named '" << surfaceName << "'");
        }
        // A named scalar grid is taken as a signed distance even if its class metadata is
        // missing (some exporters drop it); the user asked for it explicitly.
        take(roles.surface, surface, "surface", isScalar(*surface) || isVector(*surface),
            "float or double (level set), vec3s or vec3d (normals)");
        roles.surfaceKind = isVector(*surface) ? GridRoles::SurfaceKind::NormalGrid
                                               : GridRoles::SurfaceKind::LevelSet;
        return roles;
    }

    if (auto normal = findGrid(grids, names::kNormal)) {
        take(roles.surface, normal, "normal", isVector(*normal), "vec3s or vec3d");
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
        take(roles.surface, levelSets[0], "surface", true, "");
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
