// MonteCarloSolver against exact references: a closed furnace (every ray hits a front face, so
// the answer is exact for any sample count), the disk's irradiance field within the reported
// standard error, thread-count independence, and the line-partition solver's angular error.
#include "CanonicalScene.h"
#include "grids/CanonicalGrids.h"
#include "vdbrad/reference/MonteCarloSolver.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/vdbrad.h"

#include <gtest/gtest.h>

#include <tbb/global_control.h>

#include <cmath>
#include <iostream>

using namespace vdbrad;
using openvdb::Coord;

namespace {

class MonteCarloTest : public ::testing::Test
{
protected:
    static void SetUpTestSuite() { openvdb::initialize(); }
};

using test::canonicalScene;

} // namespace

TEST_F(MonteCarloTest, ClosedFurnaceIsExactAndEveryRayHitsAFront)
{
    // furnace-box: uniform rho and E inside a closed box, B = E / (1 - rho) (1e-4 relative).
    // The box is watertight for the traversal: no ray may reach a back face, and the only
    // rays to reach the sky are those that leave through their own voxel's cube (corner and
    // edge patches tilted across the wall), which closed-cavity voxels do not count.
    for (float rho : {0.f, 0.5f, 0.9f}) {
        const Scene scene = canonicalScene("furnace-box", 12, rho, 2.f);
        MonteCarloOptions o;
        o.samples = 64;
        o.maxIterations = 1000;
        o.tolerance = 1e-7;
        MonteCarloSolver solver(scene, o);
        size_t sky = 0;
        for (size_t i = 0; i < scene.size(); ++i) {
            for (int s = 0; s < o.samples; ++s) {
                ASSERT_NE(solver.hit(i, s), MonteCarloSolver::kBack) << "voxel " << i;
                sky += solver.hit(i, s) == MonteCarloSolver::kSky ? 1 : 0;
            }
        }
        // Only edge and corner voxels lose rays that way: a few percent of all rays.
        EXPECT_LT(double(sky), 0.05 * double(scene.size()) * o.samples);
        solver.solve();
        const double exact = 2.0 / (1.0 - rho);
        for (size_t i = 0; i < scene.size(); ++i) {
            ASSERT_NEAR(solver.grey()[i], exact, 1e-4 * exact) << "rho " << rho;
            ASSERT_LT(solver.greyError()[i], 1e-4 * exact);   // all rays see the same value
        }
    }
}

TEST_F(MonteCarloTest, DiskIrradianceWithinTheReportedError)
{
    // Receiver radiosity = the disk's irradiance (Howell B-13) at every receiver point. Over
    // the receiver voxels within 0.3 of the axis: |B - exact| <= 4 stderr + the disk's
    // digitisation (its voxel area differs from pi r^2: 1.5%), and the mean normalised error
    // is near 1 (an honest standard error).
    const Scene scene = canonicalScene("disk", 64);
    MonteCarloOptions o;
    o.samples = 1024;
    o.maxIterations = 2;   // the disk does not reflect: two iterations are exact
    o.tolerance = 0.0;
    MonteCarloSolver solver(scene, o);
    solver.solve();
    const double vs = scene.voxelSize();
    double z2 = 0.0;
    size_t count = 0;
    for (size_t i = 0; i < scene.size(); ++i) {
        const Coord c = scene.voxels().coord(i);
        if (c.y() == 0) continue;
        const double x = (c.x() + 0.5) * vs - 0.5, z = (c.z() + 0.5) * vs - 0.5;
        const double a = std::sqrt(x * x + z * z);
        if (a > 0.3) continue;
        const double exact = grids::diskIrradiance(1.0, 0.25, c.y() * vs, a);
        const double se = solver.greyError()[i];
        ASSERT_GT(se, 0.0);
        EXPECT_LE(std::abs(solver.grey()[i] - exact), 4.0 * se + 0.015 * exact)
            << "voxel " << c << " exact " << exact;
        z2 += (solver.grey()[i] - exact) * (solver.grey()[i] - exact) / (se * se);
        ++count;
    }
    ASSERT_GT(count, 100u);
    const double rms = std::sqrt(z2 / double(count));
    std::cout << "disk: " << count << " receiver voxels, rms (B - exact) / stderr = " << rms
              << "\n";
    // The paired-strata estimate is conservative (rms < 1: measured ~0.29, the golden-ratio
    // azimuths cancel more error than pairing credits) but within a factor of ~7.
    EXPECT_GT(rms, 0.15);
    EXPECT_LT(rms, 1.0);
}

TEST_F(MonteCarloTest, SameBitsForAnyThreadCount)
{
    const Scene scene = canonicalScene("cornell", 20);
    MonteCarloOptions o;
    o.samples = 32;
    o.maxIterations = 5;
    std::vector<openvdb::Vec3f> first;
    for (int threads : {1, 2}) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
        MonteCarloSolver solver(scene, o);
        solver.solve();
        if (first.empty()) first = solver.rgb();
        else EXPECT_TRUE(first == solver.rgb());
    }
}

TEST_F(MonteCarloTest, SweepsConvergeTowardsMonteCarloWithDirections)
{
    // The Cornell box by the line sweeps against Monte Carlo (2048 rays per voxel) on the same
    // voxels: the mean relative difference is the direction set's angular error (plus the
    // digital lines' and the Monte Carlo noise: rays rarely find the small light, so the mean
    // reported stderr is ~5% of B here, though independent solves differ by ~1.0%: it is
    // conservative), so it must shrink from 111 to 967 directions (measured 17% ->
    // 6.2%) and end within 8%.
    const Scene scene = canonicalScene("cornell", 32);
    MonteCarloOptions mo;
    mo.samples = 2048;
    mo.tolerance = 1e-6;
    MonteCarloSolver mc(scene, mo);
    mc.solve();
    double noise = 0.0, total = 0.0;
    for (size_t i = 0; i < scene.size(); ++i) {
        for (int c = 0; c < 3; ++c) {
            noise += mc.rgbError()[i][c];
            total += mc.rgb()[i][c];
        }
    }
    std::vector<double> differences;
    for (int dirs : {111, 1000}) {
        RadiosityOptions ro;
        ro.directions = dirs;
        ro.tolerance = 1e-6;
        RadiositySolver sweep(scene, ro);
        sweep.solve();
        double diff = 0.0;
        for (size_t i = 0; i < scene.size(); ++i) {
            for (int c = 0; c < 3; ++c) {
                diff += std::abs(double(sweep.rgb()[i][c]) - mc.rgb()[i][c]);
            }
        }
        differences.push_back(diff / total);
        std::cout << "Cornell 32, " << sweep.directions().size()
                  << " directions: mean |sweep - MC| / mean B = " << diff / total
                  << " (mean MC stderr / mean B = " << noise / total << ")\n";
    }
    EXPECT_LT(differences[1], differences[0]);
    EXPECT_LT(differences[1], 0.08);
}

TEST_F(MonteCarloTest, FinalGatherIsExactInTheFurnace)
{
    // Every gathered ray of a closed furnace sees E / (1 - rho): exact (1e-4) with zero spread.
    const Scene scene = canonicalScene("furnace-box", 12, 0.5f, 2.f);
    MonteCarloOptions o;
    o.samples = 16;
    o.maxIterations = 1000;
    o.tolerance = 1e-7;
    MonteCarloSolver solver(scene, o);
    solver.solve();
    std::vector<size_t> all(scene.size());
    for (size_t i = 0; i < all.size(); ++i) all[i] = i;
    const MonteCarloGather g = solver.gather(all, 256);
    ASSERT_EQ(g.grey.size(), scene.size());
    EXPECT_TRUE(g.rgb.empty());
    for (size_t k = 0; k < all.size(); ++k) {
        ASSERT_NEAR(g.grey[k], 4.0, 4e-4) << "voxel " << k;
        ASSERT_LT(g.greyError[k], 4e-4);
    }
    EXPECT_THROW(solver.gather(all, 0), openvdb::ValueError);
    EXPECT_THROW(solver.gather({scene.size()}, 64), openvdb::ValueError);
}

TEST_F(MonteCarloTest, FinalGatherReportsAnHonestStandardError)
{
    // Two independent two-pass solves of the Cornell box (256 stored rays, 4096 gathered, every
    // fifth voxel): their differences, divided by the combined reported errors, must look like
    // unit normal deviates: RMS within [0.7, 1.25] (measured 0.92-0.98 over four seed pairs;
    // without the stored pass's carried-in noise it was 4.6, voxels behind a staircase step
    // reporting ~0; with 64 stored rays 1.27, their own error estimate being too rough) and at
    // most 1% beyond 4. And the gather must be much less noisy than the stored pass: the mean
    // difference of the two gathers / mean B < 2.5% (measured 1.6-1.7%; the stored rays alone
    // differ by 5.7-6.7%).
    const Scene scene = canonicalScene("cornell", 16);
    std::vector<size_t> probes;
    for (size_t i = 0; i < scene.size(); i += 5) probes.push_back(i);
    MonteCarloGather g[2];
    std::vector<openvdb::Vec3f> stored[2];
    for (int k = 0; k < 2; ++k) {
        MonteCarloOptions o;
        o.samples = 256;
        o.tolerance = 1e-6;
        o.seed = uint64_t(11 + k);
        MonteCarloSolver solver(scene, o);
        solver.solve();
        stored[k] = solver.rgb();
        g[k] = solver.gather(probes, 4096);
        ASSERT_EQ(g[k].rgb.size(), probes.size());
    }
    double z2 = 0.0, total = 0.0, diff = 0.0, storedDiff = 0.0;
    size_t count = 0, far = 0;
    for (size_t k = 0; k < probes.size(); ++k) {
        for (int c = 0; c < 3; ++c) {
            const double d = double(g[0].rgb[k][c]) - g[1].rgb[k][c];
            const double v = double(g[0].rgbError[k][c]) * g[0].rgbError[k][c]
                + double(g[1].rgbError[k][c]) * g[1].rgbError[k][c];
            total += g[0].rgb[k][c];
            diff += std::abs(d);
            storedDiff += std::abs(double(stored[0][probes[k]][c]) - stored[1][probes[k]][c]);
            if (v == 0.0) { EXPECT_EQ(d, 0.0); continue; }
            z2 += d * d / v;
            far += d * d > 16.0 * v ? 1 : 0;
            ++count;
        }
    }
    ASSERT_GT(count, 500u);
    const double rms = std::sqrt(z2 / double(count));
    std::cout << "Cornell 16, final gather: RMS z " << rms << ", beyond 4: " << far << " of "
              << count << ", mean |g1 - g2| / mean B " << diff / total << " (stored rays: "
              << storedDiff / total << ")\n";
    EXPECT_GT(rms, 0.7);
    EXPECT_LT(rms, 1.25);
    EXPECT_LE(far, count / 100);
    EXPECT_LT(diff / total, 0.025);
    EXPECT_LT(diff, 0.5 * storedDiff);
}
