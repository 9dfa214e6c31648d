// `vdbrad voxelize`: an OBJ or PLY mesh into a surface scene (vdbrad/mesh/Voxelizer.h; its
// options: vdbrad/request/VoxelizeRequest.h).
#include "Commands.h"
#include "Progress.h"
#include "ToolSupport.h"

#include "vdbrad/request/VoxelizeRequest.h"
#include "vdbrad/vdbrad.h"

#include <iostream>
#include <sstream>

namespace vdbrad {
namespace cli {

int
runVoxelize(const Arguments& a)
{
    const std::string in = a.positional()[0], out = a.positional()[1];
    const VoxelizeOptions o = voxelizeOptions(a.request());
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
    // Each starts with the file (and line), as the reader's errors do.
    for (const std::string& w : meshWarnings(mesh, in, o, a.request())) {
        std::cerr << "vdbrad: warning: " << w << "\n";
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
    for (const std::string& w : sceneWarnings(file.grids, in)) {
        std::cerr << "vdbrad: warning: " << w << "\n";
    }
    setCreator(file);
    writeOutput(file, out);
    return 0;
}

} // namespace cli
} // namespace vdbrad
