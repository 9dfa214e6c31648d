#include "vdbrad/request/VoxelizeRequest.h"

#include "vdbrad/core/GridContract.h"

#include <sstream>

namespace vdbrad {

const std::vector<OptionSpec>&
voxelizeMeshOptions()
{
    static const std::vector<OptionSpec> table = {
        OptionSpec{"res", OptionType::Int, "128", "256",
            "voxels along the mesh's longest axis"}.within(1, 16384),
        OptionSpec{"voxel-size", OptionType::Float, "", "0.01",
            "voxel edge in world units, instead of --res"}.above(0),
        OptionSpec{"separation", OptionType::Int, "26", "6",
            "26: the surface blocks naive lines (solve's default); 6: thinner, blocks "
            "standard lines only (solve with --lines standard)"}.oneOf({"6", "26"}),
        OptionSpec{"albedo", OptionType::Float, "0.5", "0.7",
            "albedo of triangles without a material, in meshes that have materials"}
            .within(0, 1),
        {"keep-sdf", OptionType::Flag, "", "",
            "also write the mesh's level set `surface` (closed meshes only)"},
        {"no-specular", OptionType::Flag, "", "",
            "ignore MTL Ks/Ns/Pr: every surface diffuse (no `specular`, `roughness` grids)"},
    };
    return table;
}

VoxelizeOptions
voxelizeOptions(const Request& r)
{
    VoxelizeOptions o;
    if (r.has("voxel-size")) {
        if (r.has("res")) r.fail("give " + r.spell("voxel-size") + " or " + r.spell("res") + ", not both");
        o.voxelSize = r.getFloat("voxel-size");
    }
    o.resolution = r.getInt("res");
    o.separation = r.getInt("separation");
    o.defaultAlbedo = float(r.getFloat("albedo"));
    o.keepSdf = r.flag("keep-sdf");
    o.specular = !r.flag("no-specular");
    return o;
}

std::vector<std::string>
meshWarnings(const TriangleMesh& mesh, const std::string& path, const VoxelizeOptions& options,
    const Request& request)
{
    // The reader's warnings start with the file and line, as its errors do.
    std::vector<std::string> warnings = mesh.warnings;
    for (const Material& m : mesh.materials) {
        if (options.specular && m.reflectance() > 1.f) {
            std::ostringstream os;
            os.precision(4);
            os << path << ": material '" << m.name << "': Kd + Ks = " << m.reflectance()
               << " > 1, both scaled by 1/" << m.reflectance() << " (a surface reflects no "
               << "more light than it receives; " << request.spell("no-specular")
               << ": Kd alone)";
            warnings.push_back(os.str());
        }
    }
    return warnings;
}

std::vector<std::string>
sceneWarnings(const openvdb::GridPtrVec& grids, const std::string& path)
{
    if (findGrid(grids, names::kEmission)) return {};
    return {path + ": nothing emits (no MTL material with Ke > 0): light it with solve's --sun, "
        "--sky or --environment"};
}

} // namespace vdbrad
