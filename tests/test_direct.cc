// Exact direct light (DirectLight.h, Emitters.h): form factors against closed forms and brute
// force, shadows against analytic visibility, no leaks, thread-count independence, and the
// solver's split of B into E plus swept reflected light.
#include "CanonicalScene.h"
#include "vdbrad/core/Constants.h"

#include "grids/CanonicalGrids.h"
#include "vdbrad/core/GridContract.h"
#include "vdbrad/mesh/MeshTracer.h"
#include "vdbrad/mesh/Voxelizer.h"
#include "vdbrad/reference/MonteCarloSolver.h"
#include "vdbrad/scene/Emitters.h"
#include "vdbrad/scene/OutputGrids.h"
#include "vdbrad/scene/SurfacePlanes.h"
#include "vdbrad/surface/DirectLight.h"
#include "vdbrad/surface/RadiositySolver.h"

#include <gtest/gtest.h>
#include <openvdb/openvdb.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iostream>
#include <map>
#include <tuple>
#include <utility>
#include <vector>

using namespace vdbrad;
using namespace vdbrad::names;
using openvdb::Coord;
using openvdb::Vec3d;
using openvdb::Vec3f;

namespace {


class DirectTest : public ::testing::Test
{
protected:
    void SetUp() override { openvdb::initialize(); }
};

// A hand-made surface scene in index units (voxel size 1).
struct SceneBuilder
{
    struct Voxel { Vec3d normal; float albedo, emission; };
    std::map<std::tuple<int, int, int>, Voxel> voxels;

    void set(const Coord& c, const Vec3d& n, float albedo, float emission)
    {
        voxels[{c.x(), c.y(), c.z()}] = {n, albedo, emission};
    }
    Scene build() const { return buildScene(grids()); }
    openvdb::GridPtrVec grids() const
    {
        auto normal = openvdb::Vec3SGrid::create(openvdb::Vec3s(0.f));
        auto albedo = openvdb::FloatGrid::create(0.f);
        auto emission = openvdb::FloatGrid::create(0.f);
        normal->setName(kNormal);
        albedo->setName(kAlbedo);
        emission->setName(kEmission);
        for (const auto& [key, v] : voxels) {
            const Coord c(std::get<0>(key), std::get<1>(key), std::get<2>(key));
            normal->tree().setValue(c, openvdb::Vec3s(v.normal.unitSafe()));
            albedo->tree().setValue(c, v.albedo);
            emission->tree().setValue(c, v.emission);
        }
        return openvdb::GridPtrVec{normal, albedo, emission};
    }
};

// Brute force: (1 / pi) integral of cos+ cos / r^2 over the parallelogram o + s e1 + t e2,
// s, t in [0, 1], emitting along @a ne, by an m x m midpoint rule.
double
bruteFactor(const Vec3d& p, const Vec3d& n, const Vec3d& o, const Vec3d& e1, const Vec3d& e2,
    const Vec3d& ne, int m)
{
    const double dA = e1.cross(e2).length() / (double(m) * m);
    double sum = 0.0;
    for (int a = 0; a < m; ++a) {
        for (int b = 0; b < m; ++b) {
            const Vec3d q = o + e1 * ((a + 0.5) / m) + e2 * ((b + 0.5) / m);
            const Vec3d d = q - p;
            const double r2 = d.lengthSqr();
            sum += std::max(0.0, n.dot(d)) * std::max(0.0, -ne.dot(d)) / (r2 * r2) * dA;
        }
    }
    return sum / kPi;
}

} // namespace

// Lambert's contour formula against Howell's closed form (B-3) and against brute force where
// the polygon crosses the receiver's horizon (the clipped part), for a convex and a concave
// (L-shaped) polygon.
TEST_F(DirectTest, PolygonFormFactorMatchesClosedFormsAndBruteForce)
{
    // A 2 x 3 rectangle at height 1.5 over a point offset from its corner, facing it.
    const Vec3d p(0.3, 0.0, -0.4), up(0, 1, 0);
    const std::vector<std::vector<Vec3d>> rect{{Vec3d(0, 1.5, 0), Vec3d(2, 1.5, 0),
        Vec3d(2, 1.5, 3), Vec3d(0, 1.5, 3)}};
    const double exact = grids::rectangleFactor(-0.3, 1.7, 0.4, 3.4, 1.5);
    EXPECT_NEAR(polygonFormFactor(p, up, rect), exact, 1e-12 * exact);
    // Either orientation of the loop gives the same non-negative factor.
    std::vector<std::vector<Vec3d>> reversed{{rect[0].rbegin(), rect[0].rend()}};
    EXPECT_NEAR(polygonFormFactor(p, up, reversed), exact, 1e-12 * exact);

    // A tilted receiver whose horizon cuts the rectangle: brute force over the whole
    // rectangle counts only what is in front (cos+), which is what clipping must give.
    const Vec3d tilted = Vec3d(1.0, 0.35, 0.2).unitSafe();
    const Vec3d q(1.1, 0.2, 1.0);
    const double brute = bruteFactor(q, tilted, Vec3d(0, 1.5, 0), Vec3d(2, 0, 0),
        Vec3d(0, 0, 3), Vec3d(0, -1, 0), 1500);
    const double clipped = polygonFormFactor(q, tilted, rect);
    EXPECT_GT(clipped, 0.02);
    EXPECT_NEAR(clipped, brute, 2e-4 * brute);

    // An L (concave) straddling the horizon = the sum of its two rectangles.
    const std::vector<std::vector<Vec3d>> ell{{Vec3d(0, 1.5, 0), Vec3d(2, 1.5, 0),
        Vec3d(2, 1.5, 1), Vec3d(1, 1.5, 1), Vec3d(1, 1.5, 3), Vec3d(0, 1.5, 3)}};
    const std::vector<std::vector<Vec3d>> partA{{Vec3d(0, 1.5, 0), Vec3d(2, 1.5, 0),
        Vec3d(2, 1.5, 1), Vec3d(0, 1.5, 1)}};
    const std::vector<std::vector<Vec3d>> partB{{Vec3d(0, 1.5, 1), Vec3d(1, 1.5, 1),
        Vec3d(1, 1.5, 3), Vec3d(0, 1.5, 3)}};
    const Vec3d cut = Vec3d(-1.0, 0.3, 0.4).unitSafe();
    const Vec3d at(0.9, 0.4, 1.3);
    const double sum = polygonFormFactor(at, cut, partA) + polygonFormFactor(at, cut, partB);
    EXPECT_GT(sum, 0.01);
    EXPECT_NEAR(polygonFormFactor(at, cut, ell), sum, 1e-12);
    // Wholly behind the receiver: nothing.
    EXPECT_EQ(polygonFormFactor(p, -up, rect), 0.0);
}

// Patches: one per connected, flat, equally emitting set; outlines merged to their corners;
// holes kept; area per column.
TEST_F(DirectTest, EmittersGroupIntoPatchesWithMergedOutlines)
{
    SceneBuilder b;
    // A 5 x 5 ring (hole in the middle) facing down at y = 10, emission 2.
    for (int i = 0; i < 5; ++i) {
        for (int k = 0; k < 5; ++k) {
            if (i == 2 && k == 2) continue;
            b.set(Coord(i, 10, k), Vec3d(0, -1, 0), 0.f, 2.f);
        }
    }
    // An L of 4 voxels elsewhere, emission 1, facing +x.
    for (const Coord& c : {Coord(20, 0, 0), Coord(20, 1, 0), Coord(20, 2, 0), Coord(20, 0, 1)}) {
        b.set(c, Vec3d(1, 0, 0), 0.f, 1.f);
    }
    // A receiver that does not emit.
    b.set(Coord(2, 0, 2), Vec3d(0, 1, 0), 0.5f, 0.f);
    const Scene scene = b.build();
    const Emitters emitters(scene);
    ASSERT_EQ(emitters.patches().size(), 2u);
    EXPECT_EQ(emitters.voxels(), 28u);
    const EmitterPatch* ring = nullptr;
    const EmitterPatch* ell = nullptr;
    for (const EmitterPatch& p : emitters.patches()) (p.exitance[0] == 2.0 ? ring : ell) = &p;
    ASSERT_TRUE(ring && ell);
    EXPECT_EQ(ring->loops.size(), 2u);          // outside and hole
    size_t corners = 0;
    for (const auto& loop : ring->loops) corners += loop.size();
    EXPECT_EQ(corners, 8u);                      // 4 + 4 after merging
    EXPECT_DOUBLE_EQ(ring->area, 24.0);
    EXPECT_DOUBLE_EQ(ring->offset, -10.0);       // n . q = -10 on y = 10
    EXPECT_EQ(ell->loops.size(), 1u);
    EXPECT_EQ(ell->loops[0].size(), 6u);
    EXPECT_DOUBLE_EQ(ell->area, 4.0);
    EXPECT_DOUBLE_EQ(emitters.power(), 2.0 * 24 + 4.0);
    // The receiver under the ring's hole sees the ring: 1 - F(hole) of the whole square... as
    // the difference of two B-3 rectangles (index units: cells [-0.5, 4.5] and the hole).
    const double whole = grids::rectangleFactor(-2.5, 2.5, -2.5, 2.5, 10.0);
    const double hole = grids::rectangleFactor(-0.5, 0.5, -0.5, 0.5, 10.0);
    EXPECT_NEAR(patchFormFactor(Vec3d(2, 0, 2), Vec3d(0, 1, 0), *ring), whole - hole, 1e-12);
    for (size_t i = 0; i < scene.size(); ++i) {
        const bool emitting = scene.emission().grey(i) > 0.f;
        EXPECT_EQ(emitters.patchOf(i) != Emitters::kNone, emitting);
    }
}

// The lamp scene's floor: exact to float rounding at the default settings, for several lamp
// sizes and heights (the sweeps' own direct light is 10-60 % off here:
// docs/journal/2026-12-03-exact-direct-light.md).
TEST_F(DirectTest, LampOverFloorIsExactAtDefaultSettings)
{
    struct Case { float r, h; };
    for (const Case& c : {Case{0.05f, 0.25f}, Case{0.02f, 0.1f}, Case{0.15f, 0.5f},
             Case{0.1f, 0.05f}}) {
        grids::BuildParams p;
        p.res = 64;
        p.radius = c.r;
        p.height = c.h;
        const Scene scene = buildScene(grids::makeLamp(p));
        RadiositySolver solver(scene, RadiosityOptions());
        solver.solve();
        ASSERT_TRUE(solver.exactDirect());
        double top = 0.0, worst = 0.0;
        std::vector<double> exact(scene.size(), 0.0);
        for (size_t i = 0; i < scene.size(); ++i) {
            const Coord v = scene.voxels().coord(i);
            if (v.y() != 0) continue;
            exact[i] = grids::lampFloorRadiosity(p, v.x(), v.z());
            top = std::max(top, exact[i]);
        }
        for (size_t i = 0; i < scene.size(); ++i) {
            const Coord v = scene.voxels().coord(i);
            if (v.y() != 0) {
                EXPECT_EQ(solver.grey()[i], scene.emission().grey(i));   // black lamp: B = E
                continue;
            }
            if (exact[i] < 1e-3 * top) continue;
            worst = std::max(worst, std::abs(solver.grey()[i] - exact[i]) / exact[i]);
        }
        EXPECT_LT(worst, 2e-5) << "r " << c.r << " h " << c.h;
    }
}

TEST_F(DirectTest, IncidentDirectionsAddUpToTheIrradianceAndDoNotCarryOver)
{
    // Glossy voxels take their direct light with its directions: the pairs add up to the
    // irradiance, point at the lamp, and a voxel no lamp reaches (the lamp's own voxels) gets
    // none, even right after a lit one in the same workspace.
    grids::BuildParams p;
    p.res = 32;
    const Scene scene = buildScene(grids::makeLamp(p));
    const Emitters emitters(scene);
    const DirectLightSampler sampler(scene, emitters, DirectLightOptions());
    DirectLightSampler::Workspace ws(sampler);
    std::vector<std::pair<openvdb::Vec3d, openvdb::Vec3d>> incident;
    ws.incident = &incident;
    size_t lit = 0, dark = 0;
    for (size_t i = 0; i < scene.size(); ++i) {
        const openvdb::Vec3d e = sampler.at(scene.voxels().coord(i).asVec3d(),
            openvdb::Vec3d(scene.normal(i)), i, 7 + i, ws);
        openvdb::Vec3d sum(0.0);
        for (const auto& [dir, light] : incident) {
            sum += light;
            EXPECT_GT(dir.y(), 0.0);   // the lamp is above everything it lights
            EXPECT_NEAR(dir.length(), 1.0, 1e-12);
        }
        EXPECT_NEAR(sum[0], e[0], 1e-12 * (1.0 + e[0]));
        if (e[0] > 0.0) ++lit;
        if (e[0] == 0.0) { EXPECT_TRUE(incident.empty()); ++dark; }
    }
    EXPECT_GT(lit, 0u);
    EXPECT_GT(dark, 0u);
}

// A lamp narrower than a voxel keeps the columns nearest the axis (found by fuzz_load, which
// builds every scene at res 4 and 8), and its floor answer still holds.
TEST_F(DirectTest, LampNarrowerThanAVoxelKeepsItsAxisColumns)
{
    for (const int res : {4, 5, 8}) {
        grids::BuildParams p;
        p.res = res;
        const Scene scene = buildScene(grids::makeLamp(p));
        const Emitters emitters(scene);
        ASSERT_EQ(emitters.patches().size(), 1u);
        EXPECT_EQ(emitters.voxels(), size_t(res % 2 ? 1 : 4)) << res;
        RadiositySolver solver(scene, RadiosityOptions());
        solver.solve();
        for (size_t i = 0; i < scene.size(); ++i) {
            const Coord v = scene.voxels().coord(i);
            if (v.y() != 0) continue;
            const double exact = grids::lampFloorRadiosity(p, v.x(), v.z());
            EXPECT_NEAR(solver.grey()[i], exact, 2e-5 * exact) << res << " " << v;
        }
    }
}

// A black plate between the lamp and an albedo-1 floor. The repository's ray rule (shadow rays
// from half a voxel above the receiver's centre) stops a ray
// in a plate voxel's cube wherever it is behind that voxel's plane (what keeps rays out of the
// cracks of tilted walls), so from below the plate blocks exactly the rays through the box
// [cells] x [y - 1/2, y]: the reference integrates over the lamp with that visibility (midpoint
// rule, 160 x 160). Where the floor sees all of the lamp the answer is exact (B-3); where it
// sees none, zero; in the penumbra the shadow rays' ratio estimate is within a few per cent.
TEST_F(DirectTest, ShadowsMatchTheRayRulesVisibility)
{
    const int n = 48, lamp = 24, plate = 12;
    const int lo = 21, hi = 26, b0 = 16, b1 = 20;
    SceneBuilder b;
    for (int i = 0; i < n; ++i) {
        for (int k = 0; k < n; ++k) b.set(Coord(i, 0, k), Vec3d(0, 1, 0), 1.f, 0.f);
    }
    for (int i = lo; i <= hi; ++i) {
        for (int k = lo; k <= hi; ++k) b.set(Coord(i, lamp, k), Vec3d(0, -1, 0), 0.f, 1.f);
    }
    for (int i = b0; i <= b1; ++i) {
        for (int k = b0; k <= b1 + 8; ++k) b.set(Coord(i, plate, k), Vec3d(0, 1, 0), 0.f, 0.f);
    }
    const Scene scene = b.build();
    const double a0 = lo - 0.5, a1 = hi + 0.5;                               // lamp cells
    const double c0 = b0 - 0.5, c1 = b1 + 0.5, d0 = b0 - 0.5, d1 = b1 + 8.5;   // plate cells
    const double y0 = plate - 0.5, y1 = plate;   // the cubes' part behind the plate's plane
    // Is the ray from (x, lift, z) to (u, lamp, v) blocked? (Shadow rays start half a voxel
    // in front of the receiver's centre.) The plate is a lone sheet (SurfacePlanes::stops): a
    // ray meets it where it crosses its plane y1 over the plate's cells, or where, behind the
    // plane (y0 to y1), it passes from one plate cube into another (a crack); one that enters a
    // cube from below and leaves by the plate's outer side before the plane passes its edge.
    const double lift = 0.5;
    auto at = [&](double p0, double p1, double y) {
        return p0 + (p1 - p0) * (y - lift) / (lamp - lift);
    };
    auto blocked = [&](double x, double z, double u, double v) {
        const double x1 = at(x, u, y1), z1 = at(z, v, y1);
        if (x1 >= c0 && x1 <= c1 && z1 >= d0 && z1 <= d1) return true;
        // The part behind the plane, (x0, z0) -> (x1, z1), clipped to the plate's cells.
        const double x0 = at(x, u, y0), z0 = at(z, v, y0);
        double sa = 0.0, sb = 1.0;
        auto clip = [&](double p0, double p1, double e0, double e1) {
            if (p1 == p0) {
                if (p0 < e0 || p0 > e1) sb = -1.0;
                return;
            }
            double ta = (e0 - p0) / (p1 - p0), tb = (e1 - p0) / (p1 - p0);
            if (ta > tb) std::swap(ta, tb);
            sa = std::max(sa, ta);
            sb = std::min(sb, tb);
        };
        clip(x0, x1, c0, c1);
        clip(z0, z1, d0, d1);
        if (!(sa < sb)) return false;
        // Within one cell it passes; across a cell boundary it slipped from cube to cube.
        const double e = 1e-9 * (sb - sa);
        auto cell = [](double q) { return std::floor(q + 0.5); };
        const double xa = x0 + (x1 - x0) * (sa + e), xb = x0 + (x1 - x0) * (sb - e);
        const double za = z0 + (z1 - z0) * (sa + e), zb = z0 + (z1 - z0) * (sb - e);
        return cell(xa) != cell(xb) || cell(za) != cell(zb);
    };
    // The reference's seen share per floor voxel.
    const int m = 160;
    std::vector<double> full(scene.size(), 0.0), share(scene.size(), -1.0);
    for (size_t i = 0; i < scene.size(); ++i) {
        const Coord v = scene.voxels().coord(i);
        if (v.y() != 0) continue;
        const double x = v.x(), z = v.z();
        full[i] = grids::rectangleFactor(a0 - x, a1 - x, a0 - z, a1 - z, lamp);
        double seen = 0.0, all = 0.0;
        size_t hits = 0;
        for (int p = 0; p < m; ++p) {
            for (int q = 0; q < m; ++q) {
                const double u = a0 + (a1 - a0) * (p + 0.5) / m;
                const double w = a0 + (a1 - a0) * (q + 0.5) / m;
                const double r2 = (u - x) * (u - x) + (w - z) * (w - z) + double(lamp) * lamp;
                const double f = 1.0 / (r2 * r2);   // cos cos / r^2, up to a constant
                all += f;
                if (!blocked(x, z, u, w)) {
                    seen += f;
                    ++hits;
                }
            }
        }
        share[i] = hits == size_t(m) * m ? 1.0 : hits == 0 ? 0.0 : seen / all;
    }
    // Mean penumbra error, relative to the unshadowed value, for 4, 16 (default) and 64 rays.
    for (const auto& [samples, bound] : {std::pair<int, double>{4, 0.08}, {16, 0.03},
             {64, 0.007}}) {
        RadiosityOptions o;
        o.directSamples = samples;
        RadiositySolver solver(scene, o);
        solver.solve();
        ASSERT_TRUE(solver.exactDirect());
        double sumPen = 0.0;
        size_t lit = 0, penumbra = 0, umbra = 0;
        for (size_t i = 0; i < scene.size(); ++i) {
            if (share[i] < 0.0) continue;
            const double got = solver.grey()[i];
            if (share[i] == 1.0) {
                EXPECT_NEAR(got, full[i], 2e-5 * full[i]) << scene.voxels().coord(i);
                ++lit;
            } else if (share[i] == 0.0) {
                EXPECT_EQ(got, 0.f) << scene.voxels().coord(i);
                ++umbra;
            } else {
                sumPen += std::abs(got - full[i] * share[i]) / full[i];
                ++penumbra;
            }
        }
        ASSERT_GT(lit, 1000u);
        ASSERT_GT(umbra, 10u);
        ASSERT_GT(penumbra, 50u);
        std::printf("%d shadow rays: %zu penumbra voxels, mean error %.4f of the unshadowed "
            "value\n", samples, penumbra, sumPen / double(penumbra));
        EXPECT_LT(sumPen / double(penumbra), bound) << samples << " rays";
    }
}

// A tilted wall does not shadow itself: its voxels' centres form a staircase, but shadow rays
// leave from and stop at each voxel's plane (SurfacePlanes.h), the same plane for the whole
// wall. Nothing stands between the wall and the lamp, so every voxel facing it gets the exact
// unoccluded value (the ratio estimate is exact where every ray arrives). With planes through
// the centres, 23 %, 38 % and 67 % of the wall's voxels were in their own shadow at 17, 31 and
// 45 degrees of tilt.
TEST_F(DirectTest, TiltedWallDoesNotShadowItself)
{
    for (const double degrees : {17.0, 31.0, 45.0}) {
        const double a = degrees * kPi / 180.0;
        const Vec3d n(-std::sin(a), std::cos(a), 0.0);   // the wall's normal, up and to -x
        const double half = 0.5 * (std::abs(n[0]) + std::abs(n[1]));
        const int size = 40, lamp = 40;
        SceneBuilder b;
        for (int i = 0; i < size; ++i) {
            for (int j = -size; j <= size; ++j) {
                // The supercover of the plane n . x = 0: every voxel whose cube it meets.
                if (std::abs(n.dot(Vec3d(i, j, 0))) > half + 1e-9) continue;
                for (int k = 0; k < size; ++k) b.set(Coord(i, j, k), n, 0.5f, 0.f);
            }
        }
        for (int i = 14; i <= 22; ++i) {
            for (int k = 16; k <= 24; ++k) b.set(Coord(i, lamp, k), Vec3d(0, -1, 0), 0.f, 1.f);
        }
        const Scene scene = b.build();
        const Emitters emitters(scene);
        ASSERT_EQ(emitters.patches().size(), 1u);
        const EmitterPatch& patch = emitters.patches()[0];

        // The planes: all on the wall's own plane, to a fraction of a voxel.
        const SurfacePlanes planes(scene);
        double worstPlane = 0.0, meanPlane = 0.0, meanCentre = 0.0;
        size_t inner = 0;
        for (size_t i = 0; i < scene.size(); ++i) {
            const Coord c = scene.voxels().coord(i);
            // Away from the wall's rim, where a voxel has all its neighbours.
            if (c.y() == lamp || c.x() < 2 || c.x() > size - 3 || c.z() < 2 || c.z() > size - 3) {
                continue;
            }
            const double off = std::abs(n.dot(c.asVec3d()) + planes.offset(i));
            worstPlane = std::max(worstPlane, off);
            meanPlane += off;
            meanCentre += std::abs(n.dot(c.asVec3d()));
            ++inner;
        }
        meanPlane /= double(inner);
        meanCentre /= double(inner);
        std::printf("%.0f degrees: planes off the wall by %.3f voxel on average (centres: %.3f), "
            "at most %.3f (centres: %.3f)\n", degrees, meanPlane, meanCentre, worstPlane, half);
        EXPECT_LT(meanPlane, 0.25 * meanCentre) << degrees << " degrees";
        EXPECT_LT(worstPlane, 0.3 * half) << degrees << " degrees";

        const DirectIrradiance d = directIrradiance(scene, emitters);
        size_t checked = 0, shadowed = 0;
        for (size_t i = 0; i < scene.size(); ++i) {
            const Coord c = scene.voxels().coord(i);
            if (c.y() == lamp) continue;
            const double full = patchFormFactor(c.asVec3d(), n, patch) * patch.exitance[0];
            if (!(full > 1e-4)) continue;
            ++checked;
            if (std::abs(d.irradiance[i][0] - full) > 1e-5 * full) ++shadowed;
        }
        ASSERT_GT(checked, 1000u);
        EXPECT_EQ(shadowed, 0u) << degrees << " degrees: " << shadowed << " of " << checked
                                << " voxels shadow themselves";
    }
}

// A rotated block on a floor, voxelised from its mesh, under a lamp in front of it: the block's
// front face sees the whole lamp (nothing stands in front of it), so it must get the unoccluded
// value to the last row under its top edge, whose voxels overhang the face (convex edges cut
// the planes; without, 33 of its voxels lose light). The floor is checked against the mesh's
// own visibility (MeshTracer), away from the shadow's edges: lit where the mesh sees the lamp,
// dark where the block hides it all.
TEST_F(DirectTest, RotatedBlockIsNotShadowedByItsOwnEdges)
{
    const double a = 17.0 * kPi / 180.0;
    auto place = [&](double x, double y, double z) {   // rotate about y, stand at (0.5, 0, 0.55)
        return Vec3f(float(0.5 + std::cos(a) * x + std::sin(a) * z), float(y),
            float(0.55 - std::sin(a) * x + std::cos(a) * z));
    };
    TriangleMesh mesh;
    mesh.materials = {Material{"white", Vec3f(0.5f), Vec3f(0.f)},
        Material{"lamp", Vec3f(0.f), Vec3f(1.f)}};
    auto quad = [&](const Vec3f& p0, const Vec3f& p1, const Vec3f& p2, const Vec3f& p3, int m) {
        const uint32_t b = uint32_t(mesh.points.size());
        mesh.points.insert(mesh.points.end(), {p0, p1, p2, p3});
        mesh.triangles.emplace_back(b, b + 1, b + 2);
        mesh.triangles.emplace_back(b, b + 2, b + 3);
        mesh.triangleMaterials.insert(mesh.triangleMaterials.end(), {m, m});
    };
    quad(Vec3f(0, 0, 0), Vec3f(0, 0, 1), Vec3f(1, 0, 1), Vec3f(1, 0, 0), 0);   // floor, up
    quad(Vec3f(0.4f, 0.9f, 0.05f), Vec3f(0.6f, 0.9f, 0.05f), Vec3f(0.6f, 0.9f, 0.2f),
        Vec3f(0.4f, 0.9f, 0.2f), 1);                                            // lamp, down
    const double h = 0.15, top = 0.3;
    const Vec3f c[8] = {place(-h, 0, -h), place(h, 0, -h), place(h, 0, h), place(-h, 0, h),
        place(-h, top, -h), place(h, top, -h), place(h, top, h), place(-h, top, h)};
    quad(c[4], c[7], c[6], c[5], 0);   // top (counter-clockwise from above)
    quad(c[0], c[4], c[5], c[1], 0);   // front, towards -z
    quad(c[1], c[5], c[6], c[2], 0);
    quad(c[2], c[6], c[7], c[3], 0);
    quad(c[3], c[7], c[4], c[0], 0);
    VoxelizeOptions vo;
    vo.resolution = 96;
    const Scene scene = buildScene(voxelizeMesh(mesh, vo));
    const Emitters emitters(scene);
    const DirectIrradiance d = directIrradiance(scene, emitters);
    const double vs = scene.transform().voxelSize()[0];
    const Vec3d nFront = Vec3d(place(0, 0, -1)) - Vec3d(place(0, 0, 0));

    const MeshTracer tracer(mesh, 4.0 * vs);
    MeshTracer::Accessor acc = tracer.accessor();
    // The share of the lamp the mesh lets a world point see, by an 8 x 8 grid on the lamp.
    auto share = [&](const Vec3d& p) {
        int seen = 0;
        for (int i = 0; i < 8; ++i) {
            for (int k = 0; k < 8; ++k) {
                const Vec3d y(0.4 + 0.2 * (i + 0.5) / 8, 0.9, 0.05 + 0.15 * (k + 0.5) / 8);
                const double r = (y - p).length();
                MeshTracer::Hit hit;
                if (!tracer.intersect(p, (y - p) / r, 1e-9, r - 1e-6, hit, acc)) ++seen;
            }
        }
        return seen / 64.0;
    };
    size_t faces = 0, lit = 0, dark = 0;
    for (size_t i = 0; i < scene.size(); ++i) {
        if (emitters.patchOf(i) != Emitters::kNone) continue;
        const Coord v = scene.voxels().coord(i);
        const Vec3d n(scene.normal(i));
        double full = 0.0;
        for (const EmitterPatch& patch : emitters.patches()) {
            full += patchFormFactor(v.asVec3d(), n, patch) * patch.exitance[0];
        }
        const double got = d.irradiance[i][0];
        if (n.dot(nFront) > 0.99) {
            ++faces;
            EXPECT_NEAR(got, full, 1e-5 * full) << "front face voxel " << v;
            continue;
        }
        if (v.y() != 0 || !(full > 0.0)) continue;
        // The floor: decided where the mesh's answer is the same 2 voxels each way.
        const Vec3d p = v.asVec3d() * vs + Vec3d(0, 1e-7, 0);
        const double s = share(p);
        if (s != 0.0 && s != 1.0) continue;
        bool same = true;
        for (const Vec3d& step : {Vec3d(2, 0, 0), Vec3d(-2, 0, 0), Vec3d(0, 0, 2),
                 Vec3d(0, 0, -2)}) {
            same = same && share(p + step * vs) == s;
        }
        if (!same) continue;
        if (s == 1.0) {
            ++lit;
            EXPECT_NEAR(got, full, 1e-5 * full) << "lit floor voxel " << v;
        } else {
            ++dark;
            EXPECT_EQ(got, 0.f) << "shadowed floor voxel " << v;
        }
    }
    EXPECT_GT(faces, 500u);
    EXPECT_GT(lit, 1000u);
    EXPECT_GT(dark, 200u);
}

// A light outside a closed box lights none of the inside: shadow rays never cross a shell.
TEST_F(DirectTest, ClosedBoxLeaksNothing)
{
    grids::BuildParams p;
    p.res = 16;
    p.emission = 0.f;
    openvdb::GridPtrVec grids = grids::makeFurnaceBox(p);
    // A lamp over the box's top, facing down, outside it.
    openvdb::Vec3SGrid::Ptr normal;
    openvdb::FloatGrid::Ptr emission, albedo;
    for (auto& g : grids) {
        if (g->getName() == kNormal) normal = openvdb::gridPtrCast<openvdb::Vec3SGrid>(g);
        if (g->getName() == kEmission) emission = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
        if (g->getName() == kAlbedo) albedo = openvdb::gridPtrCast<openvdb::FloatGrid>(g);
    }
    ASSERT_TRUE(normal && emission);
    if (!albedo) {
        albedo = openvdb::FloatGrid::create(0.5f);
        albedo->setName(kAlbedo);
        albedo->setTransform(normal->transform().copy());
        grids.push_back(albedo);
    }
    for (int i = 4; i < 12; ++i) {
        for (int k = 4; k < 12; ++k) {
            normal->tree().setValue(Coord(i, 20, k), openvdb::Vec3s(0, -1, 0));
            emission->tree().setValue(Coord(i, 20, k), 1.f);
            albedo->tree().setValue(Coord(i, 20, k), 0.f);
        }
    }
    const Scene scene = buildScene(grids);
    RadiositySolver solver(scene, RadiosityOptions());
    solver.solve();
    ASSERT_TRUE(solver.exactDirect());
    size_t inside = 0, lit = 0;
    for (size_t i = 0; i < scene.size(); ++i) {
        const Coord v = scene.voxels().coord(i);
        if (v.y() == 20) continue;
        ++inside;
        EXPECT_EQ(solver.grey()[i], 0.f) << v;
        // The box's own top face looks down, away from the lamp; the lamp is in front of the
        // floor's voxels, so without the shadow rays they would be lit.
        if (patchFormFactor(v.asVec3d(), Vec3d(scene.normal(i)), solver.emitters().patches()[0])
            > 0.0) {
            ++lit;
        }
    }
    EXPECT_GT(inside, 1000u);
    EXPECT_GT(lit, 100u);
}

// Auto: exact for a small light, sweeps for a furnace (every voxel emits), whose answer stays
// E / (1 - rho) to rounding.
TEST_F(DirectTest, AutoKeepsFurnacesExact)
{
    const Scene furnace = test::canonicalScene("furnace-box", 12);
    RadiositySolver solver(furnace, RadiosityOptions());
    solver.solve();
    EXPECT_FALSE(solver.exactDirect());
    for (float b : solver.grey()) EXPECT_NEAR(b, 2.f, 1e-4f);
    const Scene cornell = test::canonicalScene("cornell", 16);
    RadiositySolver lit(cornell, RadiosityOptions());
    EXPECT_TRUE(lit.exactDirect());
    RadiosityOptions sweep;
    sweep.direct = DirectMode::Sweep;
    EXPECT_FALSE(RadiositySolver(cornell, sweep).exactDirect());
}

// Bit-identical for any thread count; all update schemes reach the same answer; a restart from
// B (emission included) continues where it was.
TEST_F(DirectTest, ThreadsSchemesAndRestartsAgree)
{
    const Scene scene = test::canonicalScene("cornell", 24);
    RadiosityOptions o;
    o.directions = 200;
    o.tolerance = 1e-6;
    std::vector<openvdb::Vec3f> one, two;
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 1);
        RadiositySolver s(scene, o);
        s.solve();
        one = s.rgb();
    }
    {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, 2);
        RadiositySolver s(scene, o);
        s.solve();
        two = s.rgb();
    }
    ASSERT_EQ(one.size(), two.size());
    EXPECT_EQ(0, std::memcmp(one.data(), two.data(), one.size() * sizeof(openvdb::Vec3f)));

    for (UpdateScheme u : {UpdateScheme::Jacobi, UpdateScheme::Progressive}) {
        RadiosityOptions other = o;
        other.update = u;
        other.maxIterations = 400;
        RadiositySolver s(scene, other);
        s.solve();
        double worst = 0.0, top = 0.0;
        for (size_t i = 0; i < one.size(); ++i) {
            for (int c = 0; c < 3; ++c) {
                worst = std::max(worst, double(std::abs(s.rgb()[i][c] - one[i][c])));
                top = std::max(top, double(one[i][c]));
            }
        }
        EXPECT_LT(worst, 1e-4 * top) << int(u);
    }

    // Restart from the converged B: one more iteration changes (almost) nothing.
    RadiositySolver again(scene, o);
    again.setRadiosity(one);
    const double residual = again.iterate();
    EXPECT_LT(residual, 1e-5);
    double worst = 0.0;
    for (size_t i = 0; i < one.size(); ++i) {
        worst = std::max(worst, double((again.rgb()[i] - one[i]).length()));
    }
    EXPECT_LT(worst, 1e-5);
}

// The `emission_area` grid: float, finite, >= 0, or the scene is refused naming it; with it a
// patch's power is emission x area whatever its voxel count.
TEST_F(DirectTest, EmissionAreaScalesPatchPowerAndIsChecked)
{
    SceneBuilder b;
    for (int i = 0; i < 4; ++i) {
        for (int k = 0; k < 4; ++k) b.set(Coord(i, 8, k), Vec3d(0, -1, 0), 0.f, 2.f);
    }
    b.set(Coord(0, 0, 0), Vec3d(0, 1, 0), 0.5f, 0.f);
    const Scene plain = b.build();
    EXPECT_FALSE(plain.hasEmissionArea());
    EXPECT_DOUBLE_EQ(Emitters(plain).power(), 2.0 * 16);

    auto withArea = [&](openvdb::GridBase::Ptr area) {
        openvdb::GridPtrVec grids = b.grids();
        area->setName(kEmissionArea);
        grids.push_back(area);
        return buildScene(grids);
    };
    // Each emitting voxel carries half a face: the patch keeps its outline, at half the power.
    auto half = openvdb::FloatGrid::create(0.f);
    for (int i = 0; i < 4; ++i) {
        for (int k = 0; k < 4; ++k) half->tree().setValue(Coord(i, 8, k), 0.5f);
    }
    const Scene scaled = withArea(half);
    ASSERT_TRUE(scaled.hasEmissionArea());
    const Emitters e(scaled);
    ASSERT_EQ(e.patches().size(), 1u);
    EXPECT_DOUBLE_EQ(e.patches()[0].area, 16.0);
    EXPECT_DOUBLE_EQ(e.power(), 2.0 * 16 * 0.5);
    // `vdbrad surface` writes it back: the same power from the explicit scene.
    const Scene again = buildScene(sceneToGrids(scaled));
    ASSERT_TRUE(again.hasEmissionArea());
    EXPECT_DOUBLE_EQ(Emitters(again).power(), e.power());

    auto negative = openvdb::FloatGrid::create(0.f);
    negative->tree().setValue(Coord(1, 8, 1), -1.f);
    try {
        withArea(negative);
        FAIL() << "a negative emission_area was accepted";
    } catch (const openvdb::ValueError& e) {
        EXPECT_NE(std::string(e.what()).find("emission_area"), std::string::npos) << e.what();
    }
    EXPECT_THROW(withArea(openvdb::Vec3SGrid::create(openvdb::Vec3s(0.f))), openvdb::TypeError);
}

// The Monte Carlo reference meets the emitting voxels themselves, so it must see the light the
// exact direct light integrates: with an `emission_area` of half a face per voxel the patch
// emits half of E x its voxels' area (Emitters::exitance), and the floor under it agrees with
// the exact direct light within the rays' reported error. Before, Monte Carlo collected the
// whole E (2x here; the Cornell light's rim 8 % at res 128). Hung alone, and in a black ceiling
// as the Cornell light is: rays that reach the lone lamp's open side from below its edge pass
// behind it (SurfacePlanes::stops), as they pass the patch's outline (before that rule its
// floor was 8.8 % bright).
TEST_F(DirectTest, MonteCarloSeesTheLightsMeshPower)
{
    for (const bool ceiling : {false, true}) {
        SceneBuilder b;
        for (int i = 0; i < 16; ++i) {
            for (int k = 0; k < 16; ++k) {
                const bool lamp = i >= 6 && i < 10 && k >= 6 && k < 10;
                if (lamp || ceiling) {
                    b.set(Coord(i, 6, k), Vec3d(0, -1, 0), 0.f, lamp ? 2.f : 0.f);
                }
                b.set(Coord(i, 0, k), Vec3d(0, 1, 0), 0.5f, 0.f);
            }
        }
        openvdb::GridPtrVec grids = b.grids();
        auto half = openvdb::FloatGrid::create(0.f);
        half->setName(kEmissionArea);
        for (int i = 6; i < 10; ++i) {
            for (int k = 6; k < 10; ++k) half->tree().setValue(Coord(i, 6, k), 0.5f);
        }
        grids.push_back(half);
        const Scene scene = buildScene(grids);
        const Attribute shown = Emitters(scene).exitance(scene);
        for (size_t i = 0; i < scene.size(); ++i) {
            EXPECT_EQ(shown.grey(i), scene.emission().grey(i) > 0.f ? 1.f : 0.f);
        }

        RadiositySolver exact(scene, RadiosityOptions());
        exact.solve();
        ASSERT_TRUE(exact.exactDirect());
        MonteCarloOptions o;
        o.samples = 4096;
        o.maxIterations = 2;   // nothing the floor sends comes back: two iterations are exact
        o.tolerance = 0.0;
        MonteCarloSolver mc(scene, o);
        mc.solve();
        double sumExact = 0.0, sumMc = 0.0, z2 = 0.0;
        size_t count = 0;
        for (size_t i = 0; i < scene.size(); ++i) {
            if (scene.voxels().coord(i).y() != 0) continue;
            const double se = mc.greyError()[i];
            ASSERT_GT(se, 0.0);
            const double diff = mc.grey()[i] - exact.grey()[i];
            EXPECT_LE(std::abs(diff), 5.0 * se + 1e-3 * exact.grey()[i])
                << scene.voxels().coord(i);
            z2 += diff * diff / (se * se);
            sumExact += exact.grey()[i];
            sumMc += mc.grey()[i];
            ++count;
        }
        ASSERT_EQ(count, 256u);
        std::cout << "floor under a half-covered lamp" << (ceiling ? " in a ceiling" : "")
                  << ": Monte Carlo / exact direct " << sumMc / sumExact
                  << ", rms (MC - exact) / stderr " << std::sqrt(z2 / double(count)) << "\n";
        // Measured: 1.0085 alone, 1.0004 in the ceiling.
        EXPECT_NEAR(sumMc / sumExact, 1.0, 0.015);
        EXPECT_LT(std::sqrt(z2 / double(count)), 1.5);
    }
}

// The sun on an open floor (issue 45): every voxel's radiosity is rho E cos(zenith), whatever
// the directions, since nothing else is lit and the floor does not see itself.
TEST_F(DirectTest, SunOnAnOpenFloorGivesRhoECosZenith)
{
    SceneBuilder b;
    for (int x = 0; x < 40; ++x) {
        for (int z = 0; z < 40; ++z) b.set(Coord(x, 0, z), Vec3d(0, 1, 0), 0.5f, 0.f);
    }
    const Scene scene = b.build();
    for (const double zenith : {0.0, 30.0, 75.0}) {
        RadiosityOptions o;
        o.directions = 100;
        Sun sun;
        sun.zenith = zenith;
        sun.azimuth = 20.0;
        sun.irradiance = Vec3d(2.0);
        o.sun = sun;
        const auto B = openvdb::gridPtrCast<openvdb::FloatGrid>(solveRadiosity(scene, o));
        ASSERT_TRUE(B);
        const double expected = 0.5 * 2.0 * std::cos(zenith * kPi / 180.0);
        size_t n = 0;
        for (auto it = B->cbeginValueOn(); it; ++it, ++n) {
            ASSERT_NEAR(*it, expected, 1e-5 * expected) << "zenith " << zenith << " at "
                                                         << it.getCoord();
        }
        EXPECT_EQ(n, 1600u);
    }
}

// A black box on a floor under the sun at 45 degrees: the floor is rho E cos(zenith) where
// lit, exactly 0 in the umbra, and the shadow's area is the box's geometric shadow within its
// outline's row of voxels. The box is black, so nothing is reflected: B = rho D exactly.
TEST_F(DirectTest, SunCastsTheBoxsGeometricShadow)
{
    SceneBuilder b;
    const int x0 = 30, z0 = 25, a = 10;   // the box: [x0, x0 + a) x [1, a] x [z0, z0 + a)
    for (int x = 0; x < 60; ++x) {
        for (int z = 0; z < 60; ++z) {
            const bool under = x >= x0 && x < x0 + a && z >= z0 && z < z0 + a;
            if (!under) b.set(Coord(x, 0, z), Vec3d(0, 1, 0), 0.5f, 0.f);
        }
    }
    for (int x = x0; x < x0 + a; ++x) {
        for (int y = 1; y <= a; ++y) {
            for (int z = z0; z < z0 + a; ++z) {
                const Vec3d n(x == x0 ? -1 : x == x0 + a - 1 ? 1 : 0, y == a ? 1 : 0,
                    z == z0 ? -1 : z == z0 + a - 1 ? 1 : 0);
                if (n != Vec3d(0.0)) b.set(Coord(x, y, z), n, 0.f, 0.f);
            }
        }
    }
    const Scene scene = b.build();
    RadiosityOptions o;
    o.directions = 100;
    Sun sun;
    sun.zenith = 45.0;   // azimuth 0, up y: towards +x and up, so the shadow falls towards -x
    sun.irradiance = Vec3d(2.0);
    o.sun = sun;
    const auto B = openvdb::gridPtrCast<openvdb::FloatGrid>(solveRadiosity(scene, o));
    ASSERT_TRUE(B);
    const double lit = 0.5 * 2.0 * std::cos(kPi / 4);
    size_t shadowed = 0;
    for (auto it = B->cbeginValueOn(); it; ++it) {
        const Coord c = it.getCoord();
        if (c.y() != 0) continue;
        if (*it < 0.5 * lit) ++shadowed;
        // Lit for sure: beside the shadow (one row off its outline), or on the sun's side.
        if (c.z() < z0 - 1 || c.z() > z0 + a || c.x() >= x0 + a) {
            EXPECT_NEAR(*it, lit, 1e-5 * lit) << c;
        }
        // Umbra for sure: a row inside the outline.
        if (c.z() > z0 && c.z() < z0 + a - 1 && c.x() > x0 - a + 1 && c.x() < x0) {
            EXPECT_EQ(*it, 0.f) << c;
        }
    }
    // The geometric shadow beyond the footprint: each plane through its voxels' centres, the
    // box's top a over the floor's, so a wide and a tan(45) = a long; within one row (a voxels)
    // along its far edge, where a floor voxel's centre lies on the shadow's edge.
    const double area = double(a) * double(a);
    std::cout << "  shadow: " << shadowed << " floor voxels, geometric " << area << "\n";
    EXPECT_NEAR(double(shadowed), area, double(a));
}

// ---- a uniform sky (issue 45) ------------------------------------------------------------------

namespace {

// The surface voxels of a solid (cells where @a inside holds, in [lo, hi]^3): those with an
// empty 6-neighbour, each facing the sum of its empty neighbours' directions.
template<typename InsideT>
SceneBuilder
solidSurface(int lo, int hi, InsideT inside, float albedo)
{
    SceneBuilder b;
    for (int x = lo; x <= hi; ++x) {
        for (int y = lo; y <= hi; ++y) {
            for (int z = lo; z <= hi; ++z) {
                if (!inside(x, y, z)) continue;
                Vec3d n(0.0);
                for (int axis = 0; axis < 3; ++axis) {
                    for (int sign : {-1, 1}) {
                        Coord c(x, y, z);
                        c[axis] += sign;
                        if (!inside(c.x(), c.y(), c.z())) n[axis] += sign;
                    }
                }
                if (n != Vec3d(0.0)) b.set(Coord(x, y, z), n, albedo, 0.f);
            }
        }
    }
    return b;
}

std::vector<double>
solvedValues(const Scene& scene, const RadiosityOptions& o)
{
    const auto B = openvdb::gridPtrCast<openvdb::FloatGrid>(solveRadiosity(scene, o));
    std::vector<double> v;
    for (auto it = B->cbeginValueOn(); it; ++it) v.push_back(*it);
    return v;
}

} // namespace

// A convex body under a uniform sky of radiance L: nothing it sees but sky, so every voxel's
// radiosity is rho pi L.
TEST_F(DirectTest, ConvexBodyUnderAUniformSkyIsRhoPiL)
{
    const Scene scene = solidSurface(0, 15, [](int x, int y, int z) {
        return x >= 2 && x <= 13 && y >= 2 && y <= 13 && z >= 2 && z <= 13;
    }, 0.6f).build();
    RadiosityOptions o;
    o.sky = Sky::uniform(Vec3d(0.5));
    const std::vector<double> B = solvedValues(scene, o);
    const double expected = 0.6 * kPi * 0.5;
    double worst = 0.0, mean = 0.0;
    for (const double b : B) {
        worst = std::max(worst, std::abs(b - expected));
        mean += b / double(B.size());
    }
    std::cout << "  convex body: mean " << mean / expected << " of rho pi L, worst "
              << worst / expected << "\n";
    EXPECT_LT(worst, 0.01 * expected);
    EXPECT_NEAR(mean, expected, 1e-3 * expected);
}

// The environment furnace: albedo 1 under a uniform sky L, a cup (a cavity open to the sky):
// B = pi L everywhere at convergence, since every direction brings pi L, from the sky or from
// a voxel at pi L. A closed box lets no sky in; a checkpointed solve resumes to the same bits.
TEST_F(DirectTest, EnvironmentFurnaceIsPiLEverywhere)
{
    const Scene cup = solidSurface(-1, 17, [](int x, int y, int z) {
        const bool block = x >= 0 && x < 16 && y >= 0 && y < 8 && z >= 0 && z < 16;
        const bool hollow = x >= 2 && x < 14 && y >= 2 && z >= 2 && z < 14;
        return block && !hollow;
    }, 1.f).build();
    RadiosityOptions o;
    o.sky = Sky::uniform(Vec3d(1.0));
    o.tolerance = 1e-9;
    o.maxIterations = 5000;
    o.accelerate = Acceleration::Anderson;
    const std::vector<double> B = solvedValues(cup, o);
    double worst = 0.0;
    for (const double b : B) worst = std::max(worst, std::abs(b - kPi));
    std::cout << "  environment furnace: " << B.size() << " voxels, worst |B - pi L| / pi L "
              << worst / kPi << "\n";
    EXPECT_LT(worst, 1e-4 * kPi);

    RadiosityOptions closed;
    closed.sky = Sky::uniform(Vec3d(1.0));
    for (const double b : solvedValues(test::canonicalScene("furnace-box", 12, 0.5f, 0.f), closed)) {
        ASSERT_EQ(b, 0.0);
    }

    // Saved after 3 iterations and restored: the uninterrupted run's bits.
    RadiosityOptions few = o;
    few.accelerate = Acceleration::None;
    few.tolerance = 0.0;
    few.maxIterations = 6;
    RadiositySolver whole(cup, few);
    whole.solve();
    RadiositySolver first(cup, few);
    for (int k = 0; k < 3; ++k) first.iterate();
    SolverState state;
    first.saveState(state);
    RadiositySolver resumed(cup, few);
    resumed.restoreState(state);
    while (resumed.iterationCount() < 6) resumed.iterate();
    ASSERT_EQ(whole.grey().size(), resumed.grey().size());
    EXPECT_EQ(0, std::memcmp(whole.grey().data(), resumed.grey().data(),
        whole.grey().size() * sizeof(float)));
}

// ---- skies by direction: clear sky, environment maps (issue 45) -------------------------------

namespace {

// A latitude-longitude map of @a width x width / 2 pixels, @a f(column, row) each.
template<typename F>
std::vector<Vec3f>
latLong(int width, F f)
{
    std::vector<Vec3f> pixels;
    for (int row = 0; row < width / 2; ++row) {
        for (int col = 0; col < width; ++col) pixels.push_back(f(col, row));
    }
    return pixels;
}

// The cup of EnvironmentFurnaceIsPiLEverywhere (a cavity open to the sky), of albedo @a rho.
SceneBuilder
cupOf(float rho)
{
    return solidSurface(-1, 17, [](int x, int y, int z) {
        const bool block = x >= 0 && x < 16 && y >= 0 && y < 8 && z >= 0 && z < 16;
        const bool hollow = x >= 2 && x < 14 && y >= 2 && z >= 2 && z < 14;
        return block && !hollow;
    }, rho);
}

std::vector<Vec3f>
solvedColours(const Scene& scene, const RadiosityOptions& o)
{
    const auto grid = solveRadiosity(scene, o);
    std::vector<Vec3f> v;
    if (const auto rgb = openvdb::gridPtrCast<openvdb::Vec3SGrid>(grid)) {
        for (auto it = rgb->cbeginValueOn(); it; ++it) v.push_back(*it);
    } else {
        const auto grey = openvdb::gridPtrCast<openvdb::FloatGrid>(grid);
        for (auto it = grey->cbeginValueOn(); it; ++it) v.push_back(Vec3f(*it));
    }
    return v;
}

// Largest |a - b| over all channels, relative to the largest |b|.
double
relativeGap(const std::vector<Vec3f>& a, const std::vector<Vec3f>& b)
{
    EXPECT_EQ(a.size(), b.size());
    double gap = 0.0, size = 0.0;
    for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) {
        for (int c = 0; c < 3; ++c) {
            gap = std::max(gap, double(std::abs(a[i][c] - b[i][c])));
            size = std::max(size, double(std::abs(b[i][c])));
        }
    }
    return size > 0.0 ? gap / size : gap;
}

} // namespace

// An RGB sky makes a grey scene's solve RGB: a convex body gets rho pi L in each channel.
TEST_F(DirectTest, RgbSkyOnAGreyConvexBodyIsRhoPiLPerChannel)
{
    const Scene scene = solidSurface(0, 15, [](int x, int y, int z) {
        return x >= 2 && x <= 13 && y >= 2 && y <= 13 && z >= 2 && z <= 13;
    }, 0.6f).build();
    RadiosityOptions o;
    o.sky = Sky::uniform(Vec3d(0.2, 0.5, 1.0));
    const std::vector<Vec3f> B = solvedColours(scene, o);
    ASSERT_FALSE(B.empty());
    for (const Vec3f& b : B) {
        for (int c = 0; c < 3; ++c) {
            const double expected = 0.6 * kPi * o.sky.radiance(Vec3d(0, 1, 0))[c];
            ASSERT_NEAR(b[c], expected, 0.01 * expected) << "channel " << c;
        }
    }
}

// A constant map is the uniform sky of its value (its cells' means are that value), here in a
// cup that also sees itself.
TEST_F(DirectTest, ConstantMapEqualsTheUniformSky)
{
    const Scene cup = cupOf(0.7f).build();
    RadiosityOptions o;
    o.tolerance = 0.0;
    o.maxIterations = 6;
    o.sky = Sky::uniform(Vec3d(0.8));
    const std::vector<Vec3f> uniform = solvedColours(cup, o);
    o.sky = Sky::fromMap(64, 32, latLong(64, [](int, int) { return Vec3f(0.8f); }), 1);
    EXPECT_FALSE(o.sky.sun());
    EXPECT_FALSE(o.sky.isRgb());
    const double gap = relativeGap(solvedColours(cup, o), uniform);
    std::cout << "  constant map vs uniform sky: " << gap << "\n";
    EXPECT_LT(gap, 1e-6);
}

// A map holding one bright pixel over a uniform background is that background plus a sun of
// the pixel's excess power, in its centre's direction, as wide as its solid angle.
TEST_F(DirectTest, MapWithOneBrightPixelEqualsASun)
{
    SceneBuilder b;
    for (int x = 0; x < 40; ++x) {
        for (int z = 0; z < 40; ++z) {
            const bool under = x >= 20 && x < 28 && z >= 15 && z < 23;
            if (!under) b.set(Coord(x, 0, z), Vec3d(0, 1, 0), 0.5f, 0.f);
        }
    }
    for (int x = 20; x < 28; ++x) {
        for (int y = 1; y <= 8; ++y) {
            for (int z = 15; z < 23; ++z) {
                const Vec3d n(x == 20 ? -1 : x == 27 ? 1 : 0, y == 8 ? 1 : 0,
                    z == 15 ? -1 : z == 22 ? 1 : 0);
                if (n != Vec3d(0.0)) b.set(Coord(x, y, z), n, 0.5f, 0.f);
            }
        }
    }
    const Scene scene = b.build();
    const int W = 256, H = 128, col = 100, row = 30;
    const float background = 0.1f, peak = 5000.f;
    const Sky map = Sky::fromMap(W, H, latLong(W, [&](int c, int r) {
        return Vec3f(c == col && r == row ? peak : background);
    }), 1);
    ASSERT_TRUE(map.sun());
    // The pixel's centre (Sky.h's layout), its solid angle, and a disk of that solid angle.
    const double theta = kPi * (row + 0.5) / H, phi = 2.0 * kPi * (0.5 - (col + 0.5) / W);
    const double omega = (std::cos(kPi * row / H) - std::cos(kPi * (row + 1) / H)) * 2.0 * kPi / W;
    Sun sun;
    sun.zenith = theta * 180.0 / kPi;
    sun.azimuth = phi * 180.0 / kPi;
    sun.irradiance = Vec3d((peak - background) * omega);
    sun.diameter = 2.0 * std::acos(1.0 - omega / (2.0 * kPi)) * 180.0 / kPi;
    EXPECT_NEAR(map.sun()->zenith, sun.zenith, 1e-9);
    EXPECT_NEAR(map.sun()->azimuth, sun.azimuth, 1e-9);
    EXPECT_NEAR(map.sun()->irradiance[0], sun.irradiance[0], 1e-6 * sun.irradiance[0]);
    EXPECT_NEAR(map.sun()->diameter, sun.diameter, 1e-9);

    RadiosityOptions o;
    o.directions = 100;
    o.tolerance = 0.0;
    o.maxIterations = 4;
    o.sky = map;
    o.sun = *map.sun();
    const std::vector<Vec3f> fromMap = solvedColours(scene, o);
    o.sky = Sky::uniform(Vec3d(background));
    o.sun = sun;
    const std::vector<Vec3f> explicitSun = solvedColours(scene, o);
    const double gap = relativeGap(fromMap, explicitSun);
    std::cout << "  one-pixel map vs uniform sky + sun: " << gap << "\n";
    EXPECT_LT(gap, 1e-5);
    // Not trivially equal: the sun dominates, and the box shades part of the floor.
    size_t shaded = 0;
    for (const Vec3f& v : explicitSun) shaded += v[0] < 0.5 * explicitSun[0][0];
    EXPECT_GT(shaded, 20u);
}

// Turning the scene's transform and the map together about the up axis changes nothing: the
// index-space directions see the same cells of the map.
TEST_F(DirectTest, TurningTheMapWithTheSceneChangesNothing)
{
    const SceneBuilder cup = cupOf(0.6f);
    // A coloured map with detail in azimuth and elevation (no sun).
    const int W = 128;
    const std::vector<Vec3f> pixels = latLong(W, [&](int c, int r) {
        const double a = 2.0 * kPi * (c + 0.5) / W, e = kPi * (r + 0.5) / (W / 2);
        return Vec3f(float(0.3 + 0.25 * std::sin(a) * std::cos(e)),
            float(0.4 + 0.3 * std::cos(2 * a) * std::sin(e)), float(0.5 + 0.4 * std::cos(e)));
    });
    RadiosityOptions o;
    o.tolerance = 0.0;
    o.maxIterations = 5;
    o.sky = Sky::fromMap(W, W / 2, pixels, 1);
    EXPECT_TRUE(o.sky.isRgb());
    const std::vector<Vec3f> still = solvedColours(cup.build(), o);

    // World = R index, R a quarter turn about y; the map turned by the same angle (the azimuth
    // R gives the index x axis, from x towards z).
    openvdb::GridPtrVec grids = cup.grids();
    // Written out (not postRotate's cos(pi/2) = 6e-17), so that normals stay exactly on the
    // axes: a normal component of 1e-17 would make a voxel face directions it is edge-on to.
    const auto turned = openvdb::math::Transform::createLinearTransform(openvdb::math::Mat4d(
        0, 0, -1, 0, 0, 1, 0, 0, 1, 0, 0, 0, 0, 0, 0, 1));
    for (auto& g : grids) g->setTransform(turned->copy());
    // The `normal` grid holds world normals: turned too.
    auto normals = openvdb::gridPtrCast<openvdb::Vec3SGrid>(grids[0]);
    for (auto it = normals->beginValueOn(); it; ++it) {
        it.setValue(openvdb::Vec3s(turned->baseMap()->applyJacobian(Vec3d(*it))));
    }
    const Vec3d x = turned->baseMap()->applyJacobian(Vec3d(1, 0, 0));
    const double degrees = std::atan2(x.z(), x.x()) * 180.0 / kPi;
    EXPECT_NEAR(std::abs(degrees), 90.0, 1e-9);
    const Scene turnedCup = buildScene(grids);
    // The scene alone turned: it sees another part of the map.
    const double alone = relativeGap(solvedColours(turnedCup, o), still);
    o.sky = Sky::fromMap(W, W / 2, pixels, 1, degrees);
    const double gap = relativeGap(solvedColours(turnedCup, o), still);
    std::cout << "  map and scene turned together: " << gap << " (the scene alone: " << alone
              << ")\n";
    EXPECT_LT(gap, 1e-6);
    EXPECT_GT(alone, 0.05);
}

// Preetham's clear sky over an open floor: the floor sees the whole upper hemisphere and
// nothing else, so B = rho E, E the sky's horizontal irradiance (integrated independently,
// Sky::horizontalIrradiance); blue above, and its zenith's luminance Preetham's Y_z.
TEST_F(DirectTest, ClearSkyOnAnOpenFloorIsRhoTimesItsIrradiance)
{
    SceneBuilder b;
    for (int x = 0; x < 30; ++x) {
        for (int z = 0; z < 30; ++z) b.set(Coord(x, 0, z), Vec3d(0, 1, 0), 0.5f, 0.f);
    }
    const Scene floor = b.build();
    RadiosityOptions o;
    o.sky = Sky::clear(40.0, 30.0, 1, 3.0, 0.2);
    const Vec3d E = o.sky.horizontalIrradiance();
    const std::vector<Vec3f> B = solvedColours(floor, o);
    ASSERT_EQ(B.size(), 900u);
    double worst = 0.0;
    for (const Vec3f& v : B) {
        for (int c = 0; c < 3; ++c) worst = std::max(worst, std::abs(v[c] / (0.5 * E[c]) - 1.0));
    }
    std::cout << "  clear sky on a floor: E " << E << ", worst |B / (rho E) - 1| " << worst << "\n";
    EXPECT_LT(worst, 0.01);
    EXPECT_GT(E[2], E[0]);   // a blue sky
    // Y_z = (4.0453 T - 4.9710) tan chi - 0.2155 T + 2.4192, chi = (4/9 - T/120)(pi - 2 theta_s):
    // T = 3, theta_s = 40 degrees: chi = 0.419444 x 1.745329 = 0.732069, tan chi = 0.898650,
    // Y_z = 7.1649 x 0.898650 + 1.7727 = 8.2114 kcd/m^2.
    const Vec3d zenith = o.sky.radiance(Vec3d(0, 1, 0));
    EXPECT_NEAR(0.2126 * zenith[0] + 0.7152 * zenith[1] + 0.0722 * zenith[2], 8.2114, 2e-3);
}
