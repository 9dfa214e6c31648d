// `vdbrad voxelize`: an OBJ or PLY mesh into a surface scene (vdbrad/mesh/Voxelizer.h).
#include "Commands.h"
#include "Progress.h"
#include "ToolSupport.h"

#include "vdbrad/vdbrad.h"

#include <iostream>
#include <sstream>

namespace vdbrad {
namespace cli {

int
runVoxelize(const Arguments& a)
{
    const std::string in = a.positional()[0], out = a.positional()[1];
    VoxelizeOptions o;
    if (a.has("voxel-size")) {
        if (a.has("res")) throw UsageError("give --voxel-size or --res, not both");
        o.voxelSize = a.getFloat("voxel-size");
    }
    o.resolution = a.getInt("res");
    o.separation = a.getInt("separation");
    o.defaultAlbedo = float(a.getFloat("albedo"));
    o.keepSdf = a.flag("keep-sdf");
    o.specular = !a.flag("no-specular");
    if (isStdin(in)) {
        throw UsageError("the mesh must be a file (its MTL files are found beside it)");
    }
    checkOutput(out, {in}, a.flag("overwrite"));

    ProgressInterrupter progress(a.flag("quiet"));
    progress.start(("reading " + in).c_str());
    // Mesh errors already start with the file name (and line): no label of our own.
    const TriangleMesh mesh = [&] {
        try {
            return readMesh(in);
        } catch (const std::exception& e) {
            throw UserError(errorMessage(e));
        }
    }();
    progress.end(std::to_string(mesh.triangles.size()) + " triangles");
    // The reader's warnings start with the file and line, as its errors do.
    for (const std::string& w : mesh.warnings) std::cerr << "vdbrad: warning: " << w << "\n";
    for (const Material& m : mesh.materials) {
        if (o.specular && m.reflectance() > 1.f) {
            std::ostringstream os;
            os.precision(4);
            os << "material '" << m.name << "': Kd + Ks = " << m.reflectance()
               << " > 1, both scaled by 1/" << m.reflectance() << " (a surface reflects no "
               << "more light than it receives; --no-specular: Kd alone)";
            warn(in, os.str());
        }
    }
    VdbFile file;
    std::vector<std::string> warnings;
    file.grids = forFile(in, [&] { return voxelizeMesh(mesh, o, &progress, &warnings); });
    for (const std::string& w : warnings) warn(in, w);
    const openvdb::GridBase::Ptr normal = file.grids.front();
    if (!a.flag("quiet")) {
        std::cerr << "voxelized " << in << ": " << withCommas(normal->activeVoxelCount())
                  << " surface voxels, voxel size " << normal->voxelSize()[0] << ", "
                  << o.separation << "-separating\n";
    }
    if (!findGrid(file.grids, names::kEmission)) {
        warn(in, "nothing emits (no MTL material with Ke > 0): the scene will be dark");
    }
    setCreator(file);
    writeOutput(file, out);
    return 0;
}

} // namespace cli
} // namespace vdbrad
