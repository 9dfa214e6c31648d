// Surfaces inside a medium (FogSurfaces.h, CloudTransferOptions::surfaces).
#include "vdbrad/CloudTransfer.h"
#include "vdbrad/FogSurfaces.h"
#include "vdbrad/Scene.h"
#include "grids/CanonicalGrids.h"

#include <gtest/gtest.h>
#include <openvdb/openvdb.h>

#include <cmath>
#include <iostream>

using namespace vdbrad;
using openvdb::Coord;

namespace {

constexpr double kPi = 3.14159265358979323846;

class FogSurfacesTest : public ::testing::Test
{
protected:
    static void SetUpTestSuite() { openvdb::initialize(); }
};

// A uniform fog of extinction @a sigma (per world unit) and albedo @a omega over @a box (index
// space of @a transform).
Cloud
fog(const openvdb::math::Transform& transform, const openvdb::CoordBBox& box, double sigma,
    float omega)
{
    openvdb::FloatGrid::Ptr density = openvdb::FloatGrid::create(0.f);
    density->setName("density");
    density->setTransform(transform.copy());
    density->setGridClass(openvdb::GRID_FOG_VOLUME);
    density->tree().fill(box, float(sigma), true);
    density->tree().voxelizeActiveTiles();
    CloudOptions o;
    o.defaultAlbedo = omega;
    return buildCloud({density}, o);
}

const openvdb::math::Transform&
transformOf(const openvdb::GridPtrVec& grids)
{
    return grids.front()->transform();
}

} // namespace

TEST_F(FogSurfacesTest, Explore)
{
    grids::BuildParams p;
    p.res = 24;
    p.albedo = 0.5f;
    p.emission = 1.f;
    const openvdb::GridPtrVec g = grids::makeFurnaceBox(p);
    const Scene scene = buildScene(g);
    const openvdb::CoordBBox shell = scene.voxels().bbox();
    const openvdb::CoordBBox inside(shell.min() + Coord(1), shell.max() - Coord(1));
    for (double sigma : {1e-6, 1.0, 10.0}) {
        for (float omega : {1.f, 0.5f}) {
            const Cloud cloud = fog(scene.transform(), inside, sigma, omega);
            CloudTransferOptions o;
            o.surfaces = &scene;
            o.irradiance = 0.0;
            CloudTransfer t(cloud, o);
            t.solve();
            const std::vector<float> B = t.surfaceRadiosity();
            double sum = 0, area = 0, lo = 1e9, hi = 0;
            double fl = 1e9, fh = 0, fs = 0; int fn = 0;
            for (size_t v = 0; v < B.size(); ++v) {
                const openvdb::Vec3f n = scene.normal(v);
                if (std::abs(n[0]) + std::abs(n[1]) + std::abs(n[2]) < 1.01f) { fl = std::min(fl, double(B[v])); fh = std::max(fh, double(B[v])); fs += B[v]; ++fn; }
            }
            std::cout << "faces " << fs / fn << " [" << fl << ", " << fh << "]\n";
            for (size_t v = 0; v < B.size(); ++v) {
                const double a = t.surfaceArea()[v];
                sum += B[v] * a; area += a; lo = std::min(lo, double(B[v])); hi = std::max(hi, double(B[v]));
            }
            const std::vector<float> J = t.meanIntensity();
            double jl = 1e9, jh = 0, js = 0;
            for (float j : J) { jl = std::min(jl, double(j)); jh = std::max(jh, double(j)); js += j; }
            const CloudBudget& b = t.budget();
            std::cout << "sigma " << sigma << " omega " << omega << " its " << t.iterationCount()
                      << " Bmean " << sum / area << " [" << lo << ", " << hi << "] J*pi mean "
                      << js / J.size() * kPi << " [" << jl * kPi << ", " << jh * kPi << "] balance " << b.balance()
                      << " A " << b.absorptance << " surfA " << b.surfaceAbsorptance << " esc " << b.albedo + b.transmittance << "\n";
        }
    }
}
