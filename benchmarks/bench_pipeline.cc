// The mesh pipeline's two ends, each against a baseline in the same process, all cores:
//  - the voxelizer against the way an OpenVDB user would otherwise get a surface shell from a
//    mesh: tools::meshToUnsignedDistanceField (works on open meshes, like the Cornell box) with a
//    1-voxel band, keeping the voxels within half a voxel diagonal of a triangle (a shell close to
//    the 26-separating one, with no material per voxel and no topology guarantee);
//  - the renderer (640x480, 1 and 4 samples per pixel) against one in-place iteration of the
//    solver with 300 directions on the same voxels: what a picture costs next to the light.
//
//   build/benchmarks/bench_pipeline [mesh=samples/meshes/furnished_room.obj] [res...=128 256 512 1024]
#include "vdbrad/mesh/Mesh.h"
#include "vdbrad/mesh/Voxelizer.h"
#include "vdbrad/render/Renderer.h"
#include "vdbrad/scene/Scene.h"
#include "vdbrad/surface/RadiositySolver.h"

#include <openvdb/openvdb.h>
#include <openvdb/tools/MeshToVolume.h>

#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace {

template<typename F>
double
seconds(F&& f)
{
    const auto t0 = std::chrono::steady_clock::now();
    f();
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

} // namespace

int
main(int argc, char** argv)
{
    openvdb::initialize();
    const std::string path = argc > 1 ? argv[1]
                                      : std::string(VDBRAD_SOURCE_DIR) + "/samples/meshes/furnished_room.obj";
    std::vector<int> resolutions;
    for (int a = 2; a < argc; ++a) resolutions.push_back(std::atoi(argv[a]));
    if (resolutions.empty()) resolutions = {128, 256, 512, 1024};

    const vdbrad::TriangleMesh mesh = vdbrad::readMesh(path);
    std::printf("%s: %zu triangles\n", path.c_str(), mesh.triangles.size());
    std::printf("%6s %12s %9s %12s %9s %12s %9s %8s\n", "res", "voxels(26)", "26 s",
        "voxels(6)", "6 s", "voxels(udf)", "udf s", "udf/26");
    for (int res : resolutions) {
        vdbrad::VoxelizeOptions o;
        o.resolution = res;
        openvdb::GridPtrVec thick, star;
        const double t26 = seconds([&] { thick = vdbrad::voxelizeMesh(mesh, o); });
        o.separation = 6;
        const double t6 = seconds([&] { star = vdbrad::voxelizeMesh(mesh, o); });

        const double voxelSize = vdbrad::voxelizeVoxelSize(mesh, o);
        const auto xform = openvdb::math::Transform::createLinearTransform(voxelSize);
        std::vector<openvdb::Vec3I> triangles(mesh.triangles.begin(), mesh.triangles.end());
        std::vector<openvdb::Vec4I> quads;
        openvdb::Index64 udfVoxels = 0;
        const double tUdf = seconds([&] {
            openvdb::FloatGrid::Ptr udf = openvdb::tools::meshToUnsignedDistanceField<
                openvdb::FloatGrid>(*xform, mesh.points, triangles, quads, 1.f);
            // Keep the voxels within half a voxel diagonal (world units) of the surface.
            const float keep = float(0.8660254 * voxelSize);
            for (auto it = udf->tree().beginValueOn(); it; ++it) {
                if (*it > keep) it.setValueOff();
            }
            udfVoxels = udf->activeVoxelCount();
        });
        std::printf("%6d %12llu %9.3f %12llu %9.3f %12llu %9.3f %8.2f\n", res,
            (unsigned long long)thick.front()->activeVoxelCount(), t26,
            (unsigned long long)star.front()->activeVoxelCount(), t6,
            (unsigned long long)udfVoxels, tUdf, tUdf / t26);
    }

    // Rendering, at the second resolution given (default 256).
    vdbrad::VoxelizeOptions o;
    o.resolution = resolutions.size() > 1 ? resolutions[1] : resolutions[0];
    openvdb::GridPtrVec grids = vdbrad::voxelizeMesh(mesh, o);
    const vdbrad::Scene scene = vdbrad::buildScene(grids);
    vdbrad::RadiosityOptions ro;
    ro.directions = 300;
    ro.maxIterations = 1;
    vdbrad::RadiositySolver solver(scene, ro);
    const double tIteration = seconds([&] { solver.iterate(); });
    grids.push_back(solver.grid());
    std::printf("\nres %d, %zu voxels: one solver iteration (300 directions) %.3f s\n",
        o.resolution, scene.size(), tIteration);
    for (int aa : {1, 2}) {
        vdbrad::RenderOptions r;
        r.samplesPerPixel = aa;
        const double t = seconds([&] { vdbrad::renderImage(grids, r); });
        std::printf("render 640x480, %d sample%s per pixel: %.3f s (%.0f ns per ray), %.3f of an "
            "iteration\n", aa * aa, aa > 1 ? "s" : "", t, 1e9 * t / (640.0 * 480 * aa * aa),
            t / tIteration);
    }
    return 0;
}
