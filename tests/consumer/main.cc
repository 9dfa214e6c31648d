// A plugin author's program, built against the installed headers and libraries: the furnace
// box (closed, albedo 0.5, emission 1) solved with the one-call solveRadiosity() must give every
// voxel exactly E / (1 - rho) = 2 (the closed furnace is exact: RadiositySolver.h).
#include <grids/CanonicalGrids.h>
#include <vdbrad/vdbrad.h>

#include <algorithm>
#include <cmath>
#include <iostream>

int
main()
{
    openvdb::initialize();
    vdbrad::grids::BuildParams params;
    params.res = 12;
    const vdbrad::Scene scene = vdbrad::buildScene(vdbrad::grids::makeFurnaceBox(params));
    vdbrad::RadiosityOptions options;
    options.directions = 100;
    options.tolerance = 1e-7;
    const openvdb::FloatGrid::Ptr b =
        openvdb::gridPtrCast<openvdb::FloatGrid>(vdbrad::solveRadiosity(scene, options));
    double worst = 0.0;
    size_t voxels = 0;
    for (auto it = b->cbeginValueOn(); it; ++it, ++voxels) {
        worst = std::max(worst, std::abs(double(*it) - 2.0) / 2.0);
    }
    std::cout << "vdbrad " << VDBRAD_VERSION_STRING << ": furnace box, " << voxels
              << " voxels, largest relative error " << worst << "\n";
    // Tolerance: the iteration stops at a relative residual of 1e-7 (an error of ~1e-7 / (1 -
    // rho)); float storage adds ~1e-6.
    return voxels == scene.size() && voxels > 0 && worst < 1e-5 ? 0 : 1;
}
