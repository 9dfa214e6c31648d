// CloudTransfer and SolarBeam: exact attenuation of the beam, energy balance, thin-medium limits,
// determinism. Comparisons with the independent Monte Carlo are in test_cloud_reference.cc's
// companion below (SlabAgreesWithMonteCarlo).
#include "vdbrad/cloud/CloudTransfer.h"
#include "vdbrad/cloud/DiffusionAcceleration.h"
#include "vdbrad/cloud/PhaseFunction.h"
#include "vdbrad/cloud/SolarBeam.h"
#include "vdbrad/cloud/VoxelStep.h"
#include "vdbrad/scene/Cloud.h"
#include "vdbrad/sweep/DirectionSet.h"
#include "vdbrad/sweep/RealHarmonics.h"

#include "CloudReference.h"
#include "grids/CanonicalGrids.h"

#include <gtest/gtest.h>

#include <openvdb/openvdb.h>

#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <memory>
#include <optional>
#include <tuple>

using namespace vdbrad;
using openvdb::Coord;

namespace {

class CloudTest : public ::testing::Test
{
protected:
    static void SetUpTestSuite() { openvdb::initialize(); }
};

// A homogeneous box of nx x ny x nz voxels (y up), voxel size h, vertical optical thickness tau.
Cloud
slab(int nx, int ny, int nz, double tau, float albedo, double h = 0.1)
{
    openvdb::FloatGrid::Ptr density = openvdb::FloatGrid::create(0.f);
    density->setName("density");
    density->setTransform(openvdb::math::Transform::createLinearTransform(h));
    density->setGridClass(openvdb::GRID_FOG_VOLUME);
    density->tree().fill(openvdb::CoordBBox(Coord(0), Coord(nx - 1, ny - 1, nz - 1)),
        float(tau / (ny * h)), true);
    density->tree().voxelizeActiveTiles();
    CloudOptions o;
    o.defaultAlbedo = albedo;
    return buildCloud({density}, o);
}

// The slab tests' solver settings: periodic, 303 directions, tolerance 1e-6, Anderson, the
// narrow box as given (no copies: 9-16x faster; the phase function and the voxel source are
// what they test), Henyey-Greenstein g at order 8.
CloudTransferOptions
hgSlabOptions(double g)
{
    CloudTransferOptions o;
    o.periodic = true;
    o.directions = 300;
    o.tolerance = 1e-6;
    o.minPeriod = 0;
    o.accelerate = Acceleration::Anderson;
    o.phase = PhaseFunction::henyeyGreenstein(g);
    o.phaseOrder = 8;   // the order these tests' figures were measured at
    return o;
}

TEST_F(CloudTest, BeamThroughAPeriodicAbsorberIsExact)
{
    // Pure absorber, periodic: transmittance exp(-tau / mu0) for any sun, whatever the rays'
    // sampling (the test's tolerance, 1e-5, is the issue's).
    for (double zenith : {0.0, 30.0, 60.0, 75.0}) {
        for (double tau : {1e-6, 0.5, 2.0, 10.0}) {
            const Cloud cloud = slab(12, 10, 9, tau, 0.f);
            CloudTransferOptions o;
            o.sunZenith = zenith;
            o.sunAzimuth = 20.0;
            o.periodic = true;
            o.directions = 50;
            CloudTransfer transfer(cloud, o);
            transfer.iterate();
            const double mu0 = std::cos(zenith * 3.14159265358979323846 / 180.0);
            const CloudBudget& b = transfer.budget();
            EXPECT_NEAR(b.transmittance, std::exp(-tau / mu0), 1e-5 * std::exp(-tau / mu0) + 1e-12)
                << "zenith " << zenith << " tau " << tau;
            EXPECT_NEAR(b.directTransmittance, b.transmittance, 1e-12);
            EXPECT_EQ(b.albedo, 0.0);
            EXPECT_NEAR(b.balance(), 0.0, 1e-9);
            // Incident: F0 mu0 times the top face, 12 x 9 voxel faces.
            EXPECT_NEAR(b.incident, mu0 * 12 * 9, 1e-9);
        }
    }
}

TEST_F(CloudTest, BeamDepositsAddUpToWhatTheMediumTakes)
{
    // Open box under an oblique sun: incident = deposits + transmitted, exactly.
    const Cloud cloud = slab(7, 5, 6, 3.0, 1.f);
    std::vector<float> depth(cloud.size());
    for (size_t i = 0; i < depth.size(); ++i) depth[i] = cloud.extinction(i) * float(cloud.voxelSize());
    const SolarBeamResult r = traceSolarBeam(cloud.voxels(), depth,
        openvdb::Vec3d(0.3, 1.0, -0.4), 1, false, 3, 2.0);
    double sum = r.transmitted;
    for (double d : r.deposited) { sum += d; EXPECT_GE(d, 0.0); }
    EXPECT_NEAR(sum, r.incident, 1e-9 * r.incident);
    // The box's shadow on the plane normal to the beam: F0 times the projected area of the box
    // (|d . n_face| x face area summed over the faces facing the sun), within the ray grid's
    // rim (3 rays per voxel).
    const openvdb::Vec3d d = openvdb::Vec3d(0.3, 1.0, -0.4).unit();
    const double shadow = 2.0 * (std::abs(d.x()) * 5 * 6 + std::abs(d.y()) * 7 * 6
        + std::abs(d.z()) * 7 * 5);
    EXPECT_NEAR(r.incident, shadow, 0.05 * shadow);
}

TEST_F(CloudTest, EnergyBalancesOpenAndPeriodic)
{
    // At convergence, reflected + transmitted + absorbed = incident (the issue asks 1e-4).
    for (bool periodic : {false, true}) {
        for (float albedo : {1.f, 0.8f}) {
            const Cloud cloud = slab(10, 8, 10, 4.0, albedo);
            CloudTransferOptions o;
            o.periodic = periodic;
            o.sunZenith = 40.0;
            o.directions = 111;
            o.tolerance = 1e-7;
            CloudTransfer transfer(cloud, o);
            transfer.solve();
            ASSERT_TRUE(transfer.converged());
            const CloudBudget& b = transfer.budget();
            EXPECT_NEAR(b.balance(), 0.0, 1e-4) << "periodic " << periodic << " albedo " << albedo
                << ": R " << b.albedo << " T " << b.transmittance << " A " << b.absorptance;
            if (albedo == 1.f) {
                EXPECT_EQ(b.absorptance, 0.0);
            }
            EXPECT_GT(b.albedo, 0.05);
            EXPECT_GT(b.transmittance, 0.05);
        }
    }
}

TEST_F(CloudTest, ThinSlabScattersSingly)
{
    // tau = 1e-3, omega0 = 1, isotropic, sun at the zenith: the beam loses 1 - e^-tau, and
    // isotropic scattering sends half of it up (the direction pairs are symmetric), to first
    // order: multiple scattering changes that by O(tau^2) = 1e-6. Open boundaries: light leaving
    // through the sides counts as up or down by its direction.
    const double tau = 1e-3;
    const Cloud cloud = slab(8, 8, 8, tau, 1.f);
    CloudTransferOptions o;
    o.directions = 111;
    o.tolerance = 1e-9;
    CloudTransfer transfer(cloud, o);
    transfer.solve();
    const CloudBudget& b = transfer.budget();
    std::printf("thin slab: %d iterations, R %.6g T %.6g A %.3g balance %.3g\n",
        transfer.iterationCount(), b.albedo, b.transmittance, b.absorptance, b.balance());
    const double lost = -std::expm1(-tau);
    EXPECT_NEAR(b.directTransmittance, 1.0 - lost, 1e-9);   // density stored as float
    EXPECT_NEAR(b.albedo, 0.5 * lost, 1e-3 * 0.5 * lost);
    EXPECT_NEAR(b.balance(), 0.0, 1e-6);
}

TEST_F(CloudTest, PhaseFunctionCoefficientsAndHarmonics)
{
    const PhaseFunction hg = PhaseFunction::henyeyGreenstein(0.848);
    EXPECT_DOUBLE_EQ(hg.chi(0), 1.0);
    EXPECT_DOUBLE_EQ(hg.chi(3), 0.848 * 0.848 * 0.848);
    // Delta-M at order 8: f = g^9, chi_l' = (g^l - f) / (1 - f) (Wiscombe 1977).
    const PhaseFunction::Truncated t = hg.truncate(8);
    const double f = std::pow(0.848, 9);
    EXPECT_NEAR(t.f, f, 1e-15);
    ASSERT_EQ(t.chi.size(), 9u);
    EXPECT_NEAR(t.chi[0], 1.0, 1e-15);
    EXPECT_NEAR(t.chi[4], (std::pow(0.848, 4) - f) / (1.0 - f), 1e-15);
    EXPECT_TRUE(PhaseFunction().isIsotropic());
    EXPECT_THROW(PhaseFunction::henyeyGreenstein(1.0), openvdb::ValueError);
    EXPECT_THROW(PhaseFunction::legendre({0.5, 0.2}), openvdb::ValueError);
    EXPECT_THROW(PhaseFunction::legendre({1.0, 1.5}), openvdb::ValueError);
    EXPECT_DOUBLE_EQ(PhaseFunction::legendre({1.0, 0.7, 0.4}).chi(2), 0.4);
    EXPECT_DOUBLE_EQ(PhaseFunction::legendre({1.0, 0.7, 0.4}).chi(3), 0.0);
    // Addition theorem: sum_m Y_lm(a) Y_lm(b) = (2l + 1) / 4pi P_l(a.b), to rounding.
    const int K = 12;
    std::vector<double> ya((K + 1) * (K + 1)), yb(ya.size());
    const openvdb::Vec3d a = openvdb::Vec3d(0.3, 0.5, -0.8).unit(), b = openvdb::Vec3d(-0.2, 0.9, 0.1).unit();
    realSphericalHarmonics(K, a, ya.data());
    realSphericalHarmonics(K, b, yb.data());
    const double mu = a.dot(b);
    double p0 = 1.0, p1 = mu;
    for (int l = 0; l <= K; ++l) {
        double pl = l == 0 ? 1.0 : mu;
        if (l >= 2) {
            pl = ((2 * l - 1) * mu * p1 - (l - 1) * p0) / l;
            p0 = p1;
            p1 = pl;
        }
        double sum = 0.0;
        for (int m = -l; m <= l; ++m) sum += ya[size_t(l * l + l + m)] * yb[size_t(l * l + l + m)];
        EXPECT_NEAR(sum, (2 * l + 1) / (4.0 * 3.14159265358979323846) * pl, 1e-12) << l;
    }
}

// Issue 46, Mie phase functions from a file (PhaseFunction::readLegendre): the C.1 sample's
// 300 coefficients (g 0.848) give a phase function whose mean over the sphere is 1 (Gauss-
// Legendre, 200 points, exact for its degree); white space, commas and comments are read alike;
// a word that is not a number names its line, tabulated (2l + 1) chi_l are told apart, and a
// missing or empty file is refused.
TEST_F(CloudTest, LegendreCoefficientsAreReadFromFiles)
{
    const PhaseFunction c1 = PhaseFunction::readLegendre(VDBRAD_SOURCE_DIR
        "/samples/phase/cloud_c1.txt");
    EXPECT_EQ(c1.asymmetry(), 0.848);
    EXPECT_NEAR(c1.chi(299), 0.001 / 599.0, 1e-12);
    EXPECT_EQ(c1.chi(300), 0.0);
    std::vector<double> x, w;
    test::detail::gaussLegendre01(200, x, w);
    double mean = 0.0;
    for (size_t i = 0; i < x.size(); ++i) {
        mean += w[i] * c1.value(2.0 * x[i] - 1.0);   // (1/2) int_-1^1 p dmu
    }
    EXPECT_NEAR(mean, 1.0, 1e-12);
    EXPECT_GT(c1.value(1.0), 1000.0);   // the forward peak

    const std::string dir = ::testing::TempDir();
    const auto write = [&dir](const std::string& name, const std::string& text) {
        const std::string path = dir + "/" + name;
        std::FILE* f = std::fopen(path.c_str(), "w");
        std::fputs(text.c_str(), f);
        std::fclose(f);
        return path;
    };
    const PhaseFunction mixed = PhaseFunction::readLegendre(write("mixed.txt",
        "# a comment\n1, 0.7 # chi_1\n\n0.4\t0.1,0\n"));
    EXPECT_EQ(mixed.chi(1), 0.7);
    EXPECT_EQ(mixed.chi(3), 0.1);
    const auto refusal = [](const std::string& path) {
        try {
            PhaseFunction::readLegendre(path);
        } catch (const openvdb::Exception& e) {
            return std::string(e.what());
        }
        return std::string("accepted");
    };
    EXPECT_NE(refusal(write("word.txt", "1 0.5\n0.2 x3\n")).find("line 2: 'x3' is not a number"),
        std::string::npos);
    EXPECT_NE(refusal(write("beta.txt", "1 2.544 3.883 4.568\n")).find("divide each by 2l + 1"),
        std::string::npos);
    EXPECT_NE(refusal(write("empty.txt", "# nothing\n")).find("no Legendre coefficients"),
        std::string::npos);
    EXPECT_NE(refusal(write("chi0.txt", "0.5 0.2\n")).find("chi_0 = 1"), std::string::npos);
    EXPECT_NE(refusal(write("big.txt", "1 0.5 1.5 0.2\n")).find("chi_2"), std::string::npos);
    EXPECT_THROW(PhaseFunction::readLegendre(dir + "/absent.txt"), openvdb::IoError);
}

TEST_F(CloudTest, ForwardScatteringSlabAgreesWithTheExactSolution)
{
    // Henyey-Greenstein g = 0.848 (the cloud), omega0 = 1, tau = 10, sun at the zenith,
    // periodic 4 x 20 x 4 voxels, 967 directions with weights exact for harmonics to degree 16,
    // order 8 with delta-M and the full phase for the first scattering, against adding-doubling
    // (0.4261428). Measured +0.32% (docs/journal/2026-12-04-harmonic-weights.md: 303 directions
    // give -1.2% here, their angular error, which the cells' aliasing used to offset to +0.4%).
    const Cloud cloud = slab(4, 20, 4, 10.0, 1.f);
    CloudTransferOptions o;
    o.periodic = true;
    o.directions = 1000;
    o.tolerance = 1e-6;
    o.minPeriod = 0;   // the phase function's test: the narrow box as given (16x faster)
    o.accelerate = Acceleration::Anderson;
    o.phase = PhaseFunction::henyeyGreenstein(0.848);
    o.phaseOrder = 8;
    o.harmonicWeights = true;
    CloudTransfer transfer(cloud, o);
    transfer.solve();
    ASSERT_TRUE(transfer.converged());
    test::SlabProblem problem;
    problem.tau = 10.0;
    problem.g = 0.848;
    const double exact = test::addingDoublingSlab(problem).reflectance;
    std::printf("HG slab tau 10: albedo %.5f, exact %.5f\n", transfer.budget().albedo, exact);
    EXPECT_NEAR(transfer.budget().albedo, exact, 0.01 * exact);
    // And against the photon Monte Carlo the issue names: 1% plus 3 standard errors.
    test::MonteCarloRun run;
    run.photons = 200000;
    const test::SlabResult mc = test::slabMonteCarlo(problem, run);
    EXPECT_NEAR(transfer.budget().albedo, mc.reflectance,
        0.01 * mc.reflectance + 3.0 * mc.reflectanceStderr);
    EXPECT_NEAR(transfer.budget().balance(), 0.0, 1e-4);
    EXPECT_EQ(transfer.budget().absorptance, 0.0);
}

TEST_F(CloudTest, RaisingThePhaseOrderDoesNotAlias)
{
    // Moments of order K are projected with the direction weights, so products of two order-K
    // harmonics must integrate exactly: with the cells' solid angles (the default for now)
    // order 16 on 303 directions put the HG g = 0.848, tau 2 slab at +3.4% (order 8: +1.0%);
    // with weights exact to degree 2K both orders are within 0.6% of adding-doubling and
    // agree with each other to 0.15% (measured -0.54% and -0.45%).
    const Cloud cloud = slab(4, 20, 4, 2.0, 1.f);
    test::SlabProblem problem;
    problem.tau = 2.0;
    problem.g = 0.848;
    const double exact = test::addingDoublingSlab(problem).reflectance;
    double albedo[2] = {0.0, 0.0};
    for (int i = 0; i < 2; ++i) {
        CloudTransferOptions o = hgSlabOptions(0.848);
        o.phaseOrder = i == 0 ? 8 : 16;
        o.harmonicWeights = true;
        CloudTransfer transfer(cloud, o);
        transfer.solve();
        ASSERT_TRUE(transfer.converged());
        EXPECT_NEAR(transfer.budget().balance(), 0.0, 1e-5);
        albedo[i] = transfer.budget().albedo;
        std::printf("order %d: albedo %.5f (%+.2f%%), exact %.5f\n", o.phaseOrder, albedo[i],
            100.0 * (albedo[i] / exact - 1.0), exact);
        EXPECT_NEAR(albedo[i], exact, 0.006 * exact) << o.phaseOrder;
    }
    EXPECT_NEAR(albedo[1], albedo[0], 0.0015 * exact);
}

TEST_F(CloudTest, ConservativeSlabAgreesWithTheExactSolution)
{
    // Isotropic, omega0 = 1, sun at the zenith, tau = 1, periodic 4 x 20 x 4 voxels, 303
    // directions, against adding-doubling (CloudReference.h, no shared code; 0.3413288). Measured:
    // 0.34124, -0.02% (docs/journal/2026-11-25-cloud-sweeps-vs-exact-slab.md: -0.7% at tau 10).
    const Cloud cloud = slab(4, 20, 4, 1.0, 1.f);
    CloudTransferOptions o;
    o.periodic = true;
    o.directions = 300;
    o.tolerance = 1e-6;
    CloudTransfer transfer(cloud, o);
    transfer.solve();
    test::SlabProblem problem;
    problem.tau = 1.0;
    const test::SlabResult exact = test::addingDoublingSlab(problem);
    EXPECT_NEAR(transfer.budget().albedo, exact.reflectance, 0.003 * exact.reflectance);
    EXPECT_NEAR(transfer.budget().transmittance, exact.transmittance, 0.003);
}

TEST_F(CloudTest, LinearSourceIsRightInThickVoxels)
{
    // A conservative periodic slab of optical depth 50 on 20 layers (2.5 per voxel), isotropic
    // and HG g = 0.848, 303 directions, against adding-doubling (no shared code). The constant
    // source per voxel reflects too little (measured -2.15 % / -1.28 %): each opaque-ish layer
    // sends back its mean source instead of its exit face's. A linear source along the step
    // (measured -0.64 % / -0.04 %) removes most of it and still conserves energy.
    const Cloud cloud = slab(4, 20, 4, 50.0, 1.f);
    for (double g : {0.0, 0.848}) {
        test::SlabProblem problem;
        problem.tau = 50.0;
        problem.g = g;
        const double exact = test::addingDoublingSlab(problem).reflectance;
        double error[2] = {0.0, 0.0};
        for (VoxelSource source : {VoxelSource::Constant, VoxelSource::Linear}) {
            CloudTransferOptions o = hgSlabOptions(g);
            o.source = source;
            CloudTransfer transfer(cloud, o);
            transfer.solve();
            ASSERT_TRUE(transfer.converged()) << g;
            EXPECT_NEAR(transfer.budget().balance(), 0.0, 1e-4) << g;
            error[source == VoxelSource::Linear] = transfer.budget().albedo / exact - 1.0;
        }
        std::printf("tau 50 on 20 layers, g %.3f: albedo error constant %+.2f %%, "
            "linear %+.2f %%\n", g, 100.0 * error[0], 100.0 * error[1]);
        EXPECT_LT(error[0], -0.01) << g;                  // the constant scheme's known deficit
        EXPECT_LT(std::abs(error[1]), 0.008) << g;        // the linear one within 0.8 %
        EXPECT_LT(std::abs(error[1]), 0.5 * std::abs(error[0])) << g;
    }
}

TEST_F(CloudTest, AndersonReachesAThickConservativeSlabInSixtySweeps)
{
    // Issue 8's goal: conservative (omega0 = 1) slab of optical depth 50, albedo within 1% of the
    // exact one (adding-doubling, 0.967354) in <= 60 sweeps. Source iteration's spectral radius
    // is ~1 - O(1 / tau^2) there: plain sweeps need ~2,400 iterations; Anderson mixing of the
    // moments removes the few slow diffusion modes. 50 layers (voxel depth 1; at depth 2.5 the
    // converged discretisation error alone is -2.1%), 303 directions, isotropic and HG g = 0.85,
    // plane-parallel (one voxel wide: swept along the vertical alone).
    // Measured after 60 sweeps (defaults: linear source, harmonic weights): isotropic +0.10 %,
    // g = 0.85 +0.03 %; plain sweeps -9.8 %. Anderson alone: the diffusion acceleration is off
    // (with it such slabs take a few sweeps: DiffusionAccelerationSolvesThickSlabsInAFewSweeps).
    const Cloud cloud = slab(1, 50, 1, 50.0, 1.f);   // plane-parallel: swept along y alone
    for (double g : {0.0, 0.85}) {
        CloudTransferOptions o;
        o.diffusion = false;
        o.periodic = true;
        o.directions = 300;
        o.tolerance = 0.0;
        o.maxIterations = 60;
        o.phase = PhaseFunction::henyeyGreenstein(g);
        o.phaseOrder = 8;
        test::SlabProblem problem;
        problem.tau = 50.0;
        problem.g = g;
        const double exact = test::addingDoublingSlab(problem).reflectance;
        double albedo[2] = {0.0, 0.0}, balance = 0.0;
        for (Acceleration a : {Acceleration::None, Acceleration::Anderson}) {
            if (a == Acceleration::None && g != 0.0) continue;   // once is enough to show it
            o.accelerate = a;
            CloudTransfer transfer(cloud, o);
            transfer.solve();
            EXPECT_EQ(transfer.iterationCount(), 60);
            albedo[a == Acceleration::Anderson] = transfer.budget().albedo;
            if (a == Acceleration::Anderson) {
                // Converged, the balance closes to 1e-4 (EnergyBalancesOpenAndPeriodic); after
                // 60 sweeps it measures what is left to converge (isotropic 2.4e-4, g = 0.85
                // 5.4e-4).
                balance = transfer.budget().balance();
                EXPECT_NEAR(balance, 0.0, 1e-3) << g;
                for (float J : transfer.meanIntensity()) ASSERT_TRUE(std::isfinite(J) && J > 0.f);
            }
        }
        std::printf("tau 50, g %.2f, 60 sweeps: albedo Anderson %.5f (balance %.2g), exact %.5f "
            "(plain: %.5f)\n", g, albedo[1], balance, exact, albedo[0]);
        EXPECT_NEAR(albedo[1], exact, 0.01 * exact) << g;
        // Without acceleration the same 60 sweeps are far off (the test can fail).
        if (g == 0.0) {
            EXPECT_LT(albedo[0], 0.95 * exact);
        }
    }
}

// Issue 46: diffusion synthetic acceleration (DiffusionAcceleration.h) takes the optical depth
// out of the iteration count. A conservative plane-parallel slab of optical depth 100 (80
// layers, 1.25 per voxel), 303 directions, tolerance 1e-6: with it and Anderson, 8 sweeps
// isotropic (measured) and 33 at g 0.877 (order 8), against 161 and 136 with Anderson alone
// (the g 0.877 run without it is left to the benchmark: bench_cloud, docs/performance.md).
// The answers are the same solution: the diffusion's correction vanishes at the fixed point;
// at g 0.877 the albedo is adding-doubling's to the order-8 discretisation (+0.00 %).
TEST_F(CloudTest, DiffusionAccelerationSolvesThickSlabsInAFewSweeps)
{
    const Cloud cloud = slab(1, 80, 1, 100.0, 1.f);
    for (double g : {0.0, 0.877}) {
        CloudTransferOptions o = hgSlabOptions(g);
        o.maxIterations = 400;
        int sweeps[2] = {0, 0};
        double albedo[2] = {0.0, 0.0};
        std::vector<float> J[2];
        for (bool diffusion : {false, true}) {
            if (g != 0.0 && !diffusion) continue;
            o.diffusion = diffusion;
            CloudTransfer transfer(cloud, o);
            transfer.solve();
            EXPECT_TRUE(transfer.converged()) << g << ' ' << diffusion;
            EXPECT_NEAR(transfer.budget().balance(), 0.0, 1e-4) << g << ' ' << diffusion;
            sweeps[diffusion] = transfer.iterationCount();
            albedo[diffusion] = transfer.budget().albedo;
            J[diffusion] = transfer.meanIntensity();
        }
        std::printf("slab tau 100, g %.3f: %d sweeps with diffusion acceleration, %d without; "
            "albedo %.6f / %.6f\n", g, sweeps[1], sweeps[0], albedo[1], albedo[0]);
        EXPECT_LE(sweeps[1], g == 0.0 ? 10 : 40) << g;
        if (g != 0.0) {
            test::SlabProblem problem;
            problem.tau = 100.0;
            problem.g = g;
            EXPECT_NEAR(albedo[1], test::addingDoublingSlab(problem).reflectance, 5e-4);
            continue;
        }
        EXPECT_GE(sweeps[0], 10 * sweeps[1]);
        EXPECT_NEAR(albedo[1], albedo[0], 1e-4);
        float peak = 0.f;
        for (float v : J[0]) peak = std::max(peak, v);
        for (size_t i = 0; i < J[0].size(); ++i) {
            ASSERT_NEAR(J[1][i], J[0][i], 1e-4 * peak) << g << " voxel " << i;
        }
    }
}

// The diffusion solve itself, on a small heterogeneous medium with gaps, a wall and a periodic
// wrap, against a dense Gaussian elimination of the system the file comment states (half-voxel
// conductances max(2 D, 2 X / faces), harmonic faces, Marshak's vacuum and wall conditions),
// and the balance any such solve must keep: the source equals what is absorbed plus what leaves
// through the boundary faces (interior faces cancel).
TEST(DiffusionAcceleration, SolvesTheDiscreteDiffusionEquation)
{
    openvdb::MaskTree mask;
    const Coord lo(0, 0, 0), hi(4, 3, 2);
    for (int x = lo.x(); x <= hi.x(); ++x) {
        for (int y = lo.y(); y <= hi.y(); ++y) {
            for (int z = lo.z(); z <= hi.z(); ++z) {
                if ((x * 7 + y * 3 + z * 5) % 11 != 4) mask.setValueOn(Coord(x, y, z));
            }
        }
    }
    const VoxelIndex voxels(mask);
    const size_t n = voxels.size();
    std::vector<float> kappa(n), omega(n), wall(n, DiffusionAcceleration::kMedium);
    std::vector<double> escape(n), residual(n);
    for (size_t i = 0; i < n; ++i) {
        const Coord c = voxels.coord(i);
        const int h = (c.x() * 13 + c.y() * 29 + c.z() * 7) % 17;
        kappa[i] = h == 3 ? 0.f : 0.005f * float(1 << (h % 12));   // 0.005 .. 10 per voxel
        omega[i] = h % 4 == 0 ? 1.f : 0.9f + 0.025f * float(h % 4);
        escape[i] = kappa[i] > 0.f ? (1.0 - std::exp(-double(kappa[i]))) / kappa[i] : 1.0;
        residual[i] = 0.1 + 0.05 * double((h * 5) % 7);
        if (c.y() == 0 && c.x() == 2) wall[i] = 0.6f;   // a ground cell
    }
    const double chi1 = 0.3;
    for (bool periodic : {false, true}) {
        std::optional<openvdb::CoordBBox> period;
        if (periodic) period = openvdb::CoordBBox(lo, hi);
        const DiffusionAcceleration dsa(voxels, kappa, omega, escape, chi1, wall, period, 1);
        std::vector<double> delta;
        const int iterations = dsa.correct(residual, delta);
        EXPECT_GT(iterations, 0);
        // The reference system.
        std::vector<int> unknown(n, -1);
        std::vector<size_t> voxel;
        std::vector<double> half;
        for (size_t i = 0; i < n; ++i) {
            const double k = kappa[i], m = escape[i];
            if (wall[i] != DiffusionAcceleration::kMedium || !(k > 0.0)) continue;
            unknown[i] = int(voxel.size());
            voxel.push_back(i);
            const double tr = std::max(k, DiffusionAcceleration::kMinDepth)
                * (1.0 - omega[i] * chi1);
            const double escaping = m < 1.0 ? 2.0 * k * m / (1.0 - m) / 6.0 : 0.0;
            half.push_back(std::max(2.0 / (3.0 * tr), escaping));
        }
        const size_t u = voxel.size();
        std::vector<double> A(u * u, 0.0), b(u), boundary(u, 0.0);
        for (size_t a = 0; a < u; ++a) {
            const size_t i = voxel[a];
            A[a * u + a] += kappa[i] * (1.0 - double(omega[i]));
            b[a] = double(kappa[i]) * omega[i] * residual[i];
            for (int f = 0; f < 6; ++f) {
                Coord c = voxels.coord(i);
                c[f / 2] += f % 2 ? 1 : -1;
                if (periodic && f / 2 != 1) {
                    if (c[f / 2] > hi[f / 2]) c[f / 2] = lo[f / 2];
                    if (c[f / 2] < lo[f / 2]) c[f / 2] = hi[f / 2];
                }
                const int32_t j = voxels.find(c);
                if (j >= 0 && unknown[size_t(j)] >= 0) {
                    const size_t bj = size_t(unknown[size_t(j)]);
                    const double k = half[a] * half[bj] / (half[a] + half[bj]);
                    A[a * u + a] += k;
                    A[a * u + bj] -= k;
                    continue;
                }
                const double rho = j >= 0 && wall[size_t(j)] != DiffusionAcceleration::kMedium
                    ? wall[size_t(j)] : 0.0;
                const double loss = 1.0 / (1.0 / half[a] + 2.0 * (1.0 + rho) / (1.0 - rho));
                A[a * u + a] += loss;
                boundary[a] += loss;
            }
        }
        // Gaussian elimination with partial pivoting.
        std::vector<double> M = A, x = b;
        for (size_t c = 0; c < u; ++c) {
            size_t p = c;
            for (size_t r = c + 1; r < u; ++r) {
                if (std::abs(M[r * u + c]) > std::abs(M[p * u + c])) p = r;
            }
            for (size_t k = 0; k < u; ++k) std::swap(M[c * u + k], M[p * u + k]);
            std::swap(x[c], x[p]);
            for (size_t r = c + 1; r < u; ++r) {
                const double f = M[r * u + c] / M[c * u + c];
                for (size_t k = c; k < u; ++k) M[r * u + k] -= f * M[c * u + k];
                x[r] -= f * x[c];
            }
        }
        for (size_t c = u; c-- > 0;) {
            for (size_t k = c + 1; k < u; ++k) x[c] -= M[c * u + k] * x[k];
            x[c] /= M[c * u + c];
        }
        EXPECT_EQ(dsa.size(), u);
        double peak = 0.0, source = 0.0, sink = 0.0;
        for (size_t a = 0; a < u; ++a) peak = std::max(peak, std::abs(x[a]));
        for (size_t a = 0; a < u; ++a) {
            const size_t i = voxel[a];
            EXPECT_NEAR(delta[i], x[a], 1e-3 * peak) << "voxel " << voxels.coord(i);
            source += b[a];
            sink += (kappa[i] * (1.0 - double(omega[i])) + boundary[a]) * delta[i];
        }
        for (size_t i = 0; i < n; ++i) {
            if (unknown[i] < 0) {
                EXPECT_EQ(delta[i], 0.0) << "not diffused: " << voxels.coord(i);
            }
        }
        EXPECT_NEAR(sink, source, 1e-3 * source) << periodic;
        std::printf("diffusion solve, %zu unknowns (%s): %d CG iterations, max delta %.4f\n", u,
            periodic ? "periodic" : "open", iterations, peak);
    }
}

TEST_F(CloudTest, ResultsDoNotDependOnThreads)
{
    const Cloud cloud = slab(9, 7, 8, 2.0, 0.9f);
    CloudTransferOptions o;
    o.periodic = true;
    o.sunZenith = 50.0;
    o.directions = 111;
    o.maxIterations = 5;
    for (int run = 0; run < 3; ++run) {
        // Without a ground, then over one (Ground.h), plain and accelerated.
        o.accelerate = run == 1 ? Acceleration::None : Acceleration::Anderson;
        if (run == 2) o.groundAlbedo = 0.4;
        std::vector<float> reference;
        for (int threads : {1, 2, 8}) {
            tbb::global_control limit(tbb::global_control::max_allowed_parallelism,
                size_t(threads));
            CloudTransfer transfer(cloud, o);
            transfer.solve();
            std::vector<float> J = transfer.meanIntensity();
            const std::vector<float> E = transfer.groundIrradiance();
            J.insert(J.end(), E.begin(), E.end());
            if (reference.empty()) {
                reference = J;
            } else {
                ASSERT_EQ(J.size(), reference.size());
                for (size_t i = 0; i < J.size(); ++i) {
                    ASSERT_EQ(J[i], reference[i]) << threads << " run " << run;
                }
            }
        }
    }
}

// Issue 8, extremes: per-voxel optical depths from 1e-8 to 1e4 (20 layers, sun at the zenith,
// Anderson). Always: no NaN, no Inf, no negative intensity, and the energy balance closes
// (relative to what the medium takes out of the beam, so that a thin layer's scattered light
// cannot vanish unnoticed). Thin layers (open 4 x 20 x 4 box: the direction set is symmetric,
// so single scattering sends exactly half of the scattered light up): R = omega0 tau / 2 and
// A = (1 - omega0) tau to O(tau^2 ln tau). (A thin *periodic* slab: ThinPeriodicSlabsDoNot-
// OverAbsorb; its horizontal light drifts out, PeriodicBoundary.h.) Opaque
// voxels (1e4, periodic): the beam stops in the top voxel and an absorbing slab transmits
// nothing. A conservative slab of opaque voxels converges too (the self-scattering elimination:
// measured 71 and 74 Anderson sweeps at 100 and 1e4 per voxel with the linear source; before
// it, neither had converged after 200). With a constant source over each voxel its voxels act
// as N = 20 stacked diffusing plates: T = 1 / (N + 1) (measured 0.047619 at both depths)
// against the exact slab's 8.4e-4 and 8.4e-6, so the albedo is 20 / 21, -4.7% from the exact
// 0.99916 and 0.99999; the linear source (default) leaves -1.3 %. That is the voxel
// discretisation, not the iteration: give thick clouds more voxels.
TEST_F(CloudTest, OpticalDepthsFrom1eMinus8To1e4PerVoxel)
{
    for (double perVoxel : {1e-8, 1e-4, 1.0, 100.0, 1e4}) {
        for (float omega : {0.5f, 1.f}) {
            const double tau = 20.0 * perVoxel;
            const bool thin = perVoxel < 1e-3;
            const Cloud cloud = thin ? slab(4, 20, 4, tau, omega) : slab(2, 20, 2, tau, omega);
            CloudTransferOptions o;
            o.periodic = !thin;
            o.directions = 111;
            o.tolerance = thin ? 1e-10 : 1e-7;
            o.maxIterations = 200;
            o.accelerate = Acceleration::Anderson;
            CloudTransfer transfer(cloud, o);
            transfer.solve();
            const CloudBudget& b = transfer.budget();
            const double lost = -std::expm1(-tau);
            std::printf("tau/voxel %g omega %.1f: %d sweeps, R %.6g T %.6g A %.6g balance %.2g"
                " (%.2g of the beam's loss)\n", perVoxel, omega, transfer.iterationCount(),
                b.albedo, b.transmittance, b.absorptance, b.balance(), b.balance() / lost);
            for (float J : transfer.meanIntensity()) {
                ASSERT_TRUE(std::isfinite(J) && J >= 0.f) << perVoxel << " " << omega;
            }
            EXPECT_TRUE(transfer.converged()) << perVoxel << " " << omega;
            EXPECT_NEAR(b.balance(), 0.0, std::min(1e-5, 1e-3 * lost)) << perVoxel;
            if (thin) {
                EXPECT_NEAR(b.albedo, 0.5 * omega * lost, 0.02 * 0.5 * omega * lost) << perVoxel;
                EXPECT_NEAR(b.absorptance, (1.0 - omega) * lost, 0.02 * lost) << perVoxel;
            }
            if (perVoxel >= 100.0) {
                EXPECT_EQ(b.directTransmittance, 0.0);
                if (omega < 1.f) {
                    EXPECT_LT(b.transmittance, 1e-6) << perVoxel;
                } else {
                    test::SlabProblem problem;
                    problem.tau = tau;
                    const double exact = test::addingDoublingSlab(problem).reflectance;
                    // The linear source (default): measured R -1.3 %, T 0.0139 / 0.0133.
                    EXPECT_NEAR(b.albedo, exact, 0.02 * exact) << perVoxel;
                    EXPECT_LT(b.transmittance, 0.02) << perVoxel;
                    // The constant source: N + 1 plates, exactly.
                    o.source = VoxelSource::Constant;
                    CloudTransfer plates(cloud, o);
                    plates.solve();
                    EXPECT_TRUE(plates.converged()) << perVoxel;
                    EXPECT_NEAR(plates.budget().balance(), 0.0, 1e-5) << perVoxel;
                    EXPECT_NEAR(plates.budget().albedo, exact, 0.05 * exact) << perVoxel;
                    EXPECT_NEAR(plates.budget().transmittance, 1.0 / 21.0, 1e-3 / 21.0)
                        << perVoxel;
                }
            }
        }
    }
}

// Self-scattering elimination: plain source iteration (no Anderson) on a conservative slab of
// opaque voxels, 2 x 5 x 2 periodic, 100 per voxel, 111 directions, tolerance 1e-7. Each voxel
// re-absorbs all but ~1% of what it scatters, so without the elimination the local mode decays
// like 0.99 per sweep and the voxel-to-voxel diffusion on top of it: measured 7,188 sweeps, and
// stopped there by a residual that understates the error (balance -6.1e-5). With it: 86 sweeps,
// balance -7.4e-7 (the same slab with Anderson: 8 sweeps).
TEST_F(CloudTest, PlainSweepsConvergeOnOpaqueConservativeVoxels)
{
    const Cloud cloud = slab(2, 5, 2, 500.0, 1.f);
    CloudTransferOptions o;
    o.periodic = true;
    o.directions = 111;
    o.tolerance = 1e-7;
    o.maxIterations = 120;
    CloudTransfer transfer(cloud, o);
    transfer.solve();
    const CloudBudget& b = transfer.budget();
    std::printf("plain sweeps, 100 per voxel: %d sweeps, R %.6f T %.6f balance %.2g\n",
        transfer.iterationCount(), b.albedo, b.transmittance, b.balance());
    EXPECT_TRUE(transfer.converged());
    EXPECT_LE(transfer.iterationCount(), 100);
    EXPECT_NEAR(b.balance(), 0.0, 1e-5);
    EXPECT_EQ(b.absorptance, 0.0);
    for (float J : transfer.meanIntensity()) ASSERT_TRUE(std::isfinite(J) && J > 0.f);
}

// Issue 8, thin periodic slabs: a box narrower than CloudTransferOptions::minPeriod is solved
// as copies side by side, which are the same medium: the narrow box gives exactly the budget of
// the wide box built by hand, and each voxel the mean of its copies' intensities there.
TEST_F(CloudTest, NarrowPeriodicBoxIsSolvedAsItsCopies)
{
    CloudTransferOptions o;
    o.periodic = true;
    o.sunZenith = 30.0;
    o.sunAzimuth = 20.0;
    o.directions = 111;   // auto: ceil(sqrt(111) / 2) = 6 voxels wide at least
    o.tolerance = 1e-6;
    o.accelerate = Acceleration::Anderson;
    const Cloud narrow = slab(4, 20, 3, 0.02, 0.5f), wide = slab(8, 20, 6, 0.02, 0.5f);
    CloudTransfer tiled(narrow, o);
    EXPECT_EQ(tiled.copies(), openvdb::Coord(2, 1, 2));
    o.minPeriod = 0;
    CloudTransfer plain(wide, o);
    EXPECT_EQ(plain.copies(), openvdb::Coord(1, 1, 1));
    tiled.solve();
    plain.solve();
    EXPECT_EQ(tiled.iterationCount(), plain.iterationCount());
    EXPECT_EQ(tiled.budget().albedo, plain.budget().albedo);
    EXPECT_EQ(tiled.budget().transmittance, plain.budget().transmittance);
    const std::vector<float> J = tiled.meanIntensity(), Jw = plain.meanIntensity();
    ASSERT_EQ(J.size(), narrow.size());
    for (size_t i = 0; i < J.size(); ++i) {
        const openvdb::Coord c = narrow.voxels().coord(i);
        double mean = 0.0;
        for (int a = 0; a < 2; ++a) {
            for (int b = 0; b < 2; ++b) {
                const int32_t k = wide.voxels().find(c + openvdb::Coord(4 * a, 0, 3 * b));
                ASSERT_GE(k, 0);
                mean += 0.25 * double(Jw[size_t(k)]);
            }
        }
        ASSERT_NEAR(J[i], mean, 1e-6 * mean) << c;
    }
    // Explicit widths: 5 voxels wide needs 2 copies along x only; a period wider than the
    // minimum none; optically thick boxes fewer (8 mean optical depths per period at most).
    o.minPeriod = 5;
    EXPECT_EQ(CloudTransfer::periodicCopies(slab(4, 20, 5, 0.02, 0.5f), o),
        openvdb::Coord(2, 1, 1));
    o.minPeriod = -1;
    o.directions = 967;   // auto: 16
    EXPECT_EQ(CloudTransfer::periodicCopies(slab(4, 20, 4, 0.02, 0.5f), o),
        openvdb::Coord(4, 1, 4));
    EXPECT_EQ(CloudTransfer::periodicCopies(slab(4, 20, 4, 40.0, 0.5f), o),   // 2 per voxel
        openvdb::Coord(1, 1, 1));
    o.periodic = false;
    EXPECT_EQ(CloudTransfer::periodicCopies(slab(4, 20, 4, 0.02, 0.5f), o),
        openvdb::Coord(1, 1, 1));
}

// Issue 8, thin periodic slabs against the exact slab (adding-doubling): tau 2e-3 to 0.2,
// omega0 0.5, 4 x 20 x 4 voxels, 303 directions. Two things made such slabs over-absorb
// (CloudTransfer.h): light wrapping around a narrow box rises by whole layers, and light in the
// exactly horizontal directions (6.4% of this set's solid angle) never rose at all. With the
// default copies (3 x 3 here) and the horizontal half cells drifting, measured albedo +0.11% /
// +0.20% / -0.20% (before both: -5.8% / -4.7% / -1.5%). Tolerance 0.5%; the box as given must
// still be worse than 2% at the two thinnest depths (measured -2.5% / -2.4%), so that the test
// can fail.
TEST_F(CloudTest, ThinPeriodicSlabsDoNotOverAbsorb)
{
    for (double tau : {2e-3, 0.02, 0.2}) {
        const Cloud cloud = slab(4, 20, 4, tau, 0.5f);
        test::SlabProblem problem;
        problem.tau = tau;
        problem.omega0 = 0.5;
        const double exact = test::addingDoublingSlab(problem).reflectance;
        double error[2] = {0.0, 0.0};
        for (int minPeriod : {-1, 0}) {
            CloudTransferOptions o;
            o.periodic = true;
            o.directions = 300;
            o.tolerance = 1e-7;
            o.accelerate = Acceleration::Anderson;
            o.minPeriod = minPeriod;
            CloudTransfer transfer(cloud, o);
            transfer.solve();
            EXPECT_TRUE(transfer.converged()) << tau;
            EXPECT_NEAR(transfer.budget().balance(), 0.0, 1e-5) << tau;
            error[minPeriod == 0] = transfer.budget().albedo / exact - 1.0;
        }
        std::printf("tau %g: albedo error %+.2f%% (as given %+.2f%%)\n", tau, 100 * error[0],
            100 * error[1]);
        EXPECT_LT(std::abs(error[0]), 0.005) << tau;
        if (tau < 0.1) {
            EXPECT_LT(error[1], -0.02) << tau;
        }
    }
}

// Issue 8, extremes: Henyey-Greenstein g from -0.99 (backward) to 0.99 (forward) against the
// exact slab, tau = 2, omega0 = 0.9, 4 x 10 x 4 voxels, order 8 with delta-M. The reference is
// adding-doubling where its quadrature holds (|g| <= 0.95) and the photon Monte Carlo (2e6
// photons, standard error ~3e-4) at |g| = 0.99. Within 3% (plus 1e-3 absolute for the tiny
// albedo at g = 0.99, plus 4 standard errors). A backward peak needs more directions, because
// the light it retro-reflects stays in a narrow cone around the beam: g = -0.99 is run with 967
// (measured R -0.7%, T +0.1%; with 303: R -1.5%, T -3.3%).
TEST_F(CloudTest, AsymmetryFromMinus099To099AgreesWithTheExactSlab)
{
    const Cloud cloud = slab(4, 10, 4, 2.0, 0.9f);
    for (double g : {-0.99, 0.0, 0.85, 0.99}) {
        CloudTransferOptions o;
        o.periodic = true;
        o.directions = g < -0.95 ? 1000 : 300;
        o.tolerance = 1e-7;
        o.maxIterations = 600;
        o.minPeriod = 0;   // the phase function's test: the narrow box as given (9-16x faster)
        o.accelerate = Acceleration::Anderson;
        o.phase = PhaseFunction::henyeyGreenstein(g);
        o.phaseOrder = 8;
        CloudTransfer transfer(cloud, o);
        transfer.solve();
        test::SlabProblem problem;
        problem.tau = 2.0;
        problem.omega0 = 0.9;
        problem.g = g;
        test::MonteCarloRun run;
        run.photons = 2000000;
        run.seed = 5;
        const test::SlabResult exact = std::abs(g) > 0.95 ? test::slabMonteCarlo(problem, run)
                                                          : test::addingDoublingSlab(problem);
        const CloudBudget& b = transfer.budget();
        std::printf("g %+.2f: %d directions, %d sweeps, R %.5f (exact %.5f) T %.5f (exact %.5f) "
            "balance %.2g\n", g, int(transfer.directions().size()), transfer.iterationCount(),
            b.albedo, exact.reflectance, b.transmittance, exact.transmittance, b.balance());
        EXPECT_TRUE(transfer.converged()) << g;
        for (float J : transfer.meanIntensity()) ASSERT_TRUE(std::isfinite(J) && J >= 0.f) << g;
        EXPECT_NEAR(b.balance(), 0.0, 1e-5) << g;
        EXPECT_NEAR(b.albedo, exact.reflectance, 0.03 * exact.reflectance + 1e-3
            + 4.0 * exact.reflectanceStderr) << g;
        EXPECT_NEAR(b.transmittance, exact.transmittance, 0.03 * exact.transmittance
            + 4.0 * exact.transmittanceStderr) << g;
    }
}

// Issue 8, extremes: a cloud's optics depend on extinction x length only. The same optical
// depths at 2e-5 and 1e6 world units per voxel (OpenVDB's smallest voxel is 1.44e-5) give the
// same intensities (to float rounding of the stored densities), and the beam's irradiance
// scales them linearly from 1e-30 to 1e30.
TEST_F(CloudTest, VoxelSizeAndIrradianceScaleOut)
{
    CloudTransferOptions o;
    o.periodic = true;
    o.sunZenith = 30.0;
    o.directions = 111;
    o.maxIterations = 10;
    o.tolerance = 0.0;
    o.accelerate = Acceleration::Anderson;
    auto solve = [&](double h, double irradiance) {
        CloudTransferOptions oo = o;
        oo.irradiance = irradiance;
        CloudTransfer transfer(slab(3, 8, 3, 4.0, 0.95f, h), oo);
        transfer.solve();
        return transfer.meanIntensity();
    };
    const std::vector<float> unit = solve(0.1, 1.0);
    float top = 0.f;
    for (float J : unit) top = std::max(top, J);
    for (auto [h, f] : {std::pair<double, double>{2e-5, 1.0}, {1e6, 1.0}, {0.1, 1e-30},
             {0.1, 1e30}, {0.1, 0x1p-100}}) {
        const std::vector<float> J = solve(h, f);
        ASSERT_EQ(J.size(), unit.size());
        double worst = 0.0;
        for (size_t i = 0; i < J.size(); ++i) {
            ASSERT_TRUE(std::isfinite(J[i]) && J[i] > 0.f) << h << " " << f;
            worst = std::max(worst, std::abs(double(J[i]) / f - double(unit[i])) / top);
        }
        std::printf("voxel size %g, irradiance %g: max |J / F0 - J1| / max J1 = %.2g\n", h, f,
            worst);
        EXPECT_LT(worst, 1e-5) << h << " " << f;
    }
}

// Issue 24, 2D media: along a flat axis (a periodic box one voxel deep) a direction is swept as
// its projection, each step the 3D path across it; a direction along flat axes only never
// leaves its voxel. Exact integer geometry, and without flat axes the direction's own line.
TEST(SweptLine, ProjectsAcrossFlatAxesWithTheThreeDimensionalPath)
{
    const FlatAxes none{}, z{false, false, true}, xz{true, false, true};
    auto expect = [](const SweptLine& l, const Coord& sigma, double step, bool isolated) {
        EXPECT_EQ(l.sigma, sigma);
        EXPECT_FLOAT_EQ(l.step, float(step)) << sigma;
        EXPECT_EQ(l.isolated, isolated) << sigma;
        if (!isolated) {
            EXPECT_NEAR((l.unit - sigma.asVec3d().unit()).length(), 0.0, 1e-15) << sigma;
        }
    };
    expect(sweptLine(Coord(2, -1, 1), none), Coord(2, -1, 1), std::sqrt(6.0) / 2.0, false);
    expect(sweptLine(Coord(1, 1, 3), none), Coord(1, 1, 3), std::sqrt(11.0) / 3.0, false);
    // z flat: (3, 1, 2) -> (3, 1, 0), 3D path sqrt(14) per 3 steps along x.
    expect(sweptLine(Coord(3, 1, 2), z), Coord(3, 1, 0), std::sqrt(14.0) / 3.0, false);
    // (2, 0, 4) -> (2, 0, 0) = (1, 0, 0) after the gcd; the path per x step is sqrt(20) / 2.
    expect(sweptLine(Coord(2, 0, 4), z), Coord(1, 0, 0), std::sqrt(20.0) / 2.0, false);
    expect(sweptLine(Coord(-2, 4, 1), z), Coord(-1, 2, 0), std::sqrt(21.0) / 4.0, false);
    // x and z flat: every non-horizontal direction is vertical, its step |sigma| / |sigma_y|.
    expect(sweptLine(Coord(3, -2, 1), xz), Coord(0, -1, 0), std::sqrt(14.0) / 2.0, false);
    // Along flat axes only: isolated, swept as +1 along the first other axis.
    expect(sweptLine(Coord(0, 0, -1), z), Coord(1, 0, 0), kIsolatedStep, true);
    expect(sweptLine(Coord(1, 0, 1), xz), Coord(0, 1, 0), kIsolatedStep, true);
    // The escape factors use the same steps: an isolated step makes any extinction opaque
    // (mean factor ~0) and keeps clear air clear (1).
    const std::vector<double> e = meanEscapeFactors({0.f, 1e-6f, 2.f}, {kIsolatedStep}, {1.0});
    EXPECT_EQ(e[0], 1.0);
    EXPECT_LT(e[1], 1e-20);
    EXPECT_LT(e[2], 1e-20);
}

// Two columns' media side by side, periodic, one voxel deep along @a flat (0 x or 2 z): the first
// half of the other horizontal axis of optical thickness tau / 9, the rest tau (the step cloud's
// 1:9), @a n voxels along it, n / 2 layers, voxel size 1 / n.
Cloud
columns(int n, int flat, double tau, float albedo)
{
    openvdb::FloatGrid::Ptr density = openvdb::FloatGrid::create(0.f);
    density->setName("density");
    density->setTransform(openvdb::math::Transform::createLinearTransform(1.0 / n));
    density->setGridClass(openvdb::GRID_FOG_VOLUME);
    const int across = flat == 0 ? 2 : 0;
    const double height = 0.5;
    for (int i = 0; i < n; ++i) {
        Coord lo(0), hi(0);
        lo[across] = hi[across] = i;
        hi[1] = n / 2 - 1;
        const double t = i < n / 2 ? tau / 9.0 : tau;
        density->tree().fill(openvdb::CoordBBox(lo, hi), float(t / height), true);
    }
    density->tree().voxelizeActiveTiles();
    CloudOptions o;
    o.defaultAlbedo = albedo;
    return buildCloud({density}, o);
}

// Issue 24, 2D media: the same columns one voxel deep along z (swept in the x-y plane, sun at
// azimuth 0, towards +x) and along x (swept in z-y, azimuth 90, towards +z) are mirror images
// under x <-> z, which maps the direction set onto itself: the same budget, to float rounding
// (measured: 1e-7 apart). A flat axis handled wrongly on either side (a projection, a step, an
// isolated line's sign, the faces it wraps across) breaks the symmetry.
TEST_F(CloudTest, FlatAxisSweepsAreTheSameAlongXAndZ)
{
    CloudTransferOptions o = hgSlabOptions(0.85);
    o.sunZenith = 60.0;
    o.maxIterations = 60;
    CloudBudget b[2];
    for (int flat : {2, 0}) {
        o.sunAzimuth = flat == 2 ? 0.0 : 90.0;
        CloudTransfer transfer(columns(32, flat, 18.0, 0.99f), o);
        EXPECT_NE(transfer.describe().find(flat == 2 ? "deep along z" : "deep along x"),
            std::string::npos) << transfer.describe();
        EXPECT_EQ(transfer.copies(), Coord(1));
        transfer.solve();
        ASSERT_TRUE(transfer.converged()) << flat;
        b[flat / 2] = transfer.budget();
    }
    std::printf("flat z: R %.7f T %.7f; flat x: R %.7f T %.7f\n", b[1].albedo,
        b[1].transmittance, b[0].albedo, b[0].transmittance);
    EXPECT_NEAR(b[0].albedo, b[1].albedo, 1e-5 * b[1].albedo);
    EXPECT_NEAR(b[0].transmittance, b[1].transmittance, 1e-5 * b[1].transmittance);
    EXPECT_NEAR(b[1].balance(), 0.0, 1e-4);
}

// Issue 24, 2D media against the photon Monte Carlo of the same columns (CloudReference.h
// columnsMonteCarlo: delta tracking, no shared code): the I3RC step cloud at res 32 (32 x 16 x 1
// voxels, tau 2 and 18, HG g = 0.85), swept in the x-y plane, 1000 directions with harmonic
// weights, linear source, Anderson. Measured against 1e6 photons (2e6): zenith, omega0 1: R
// +0.13 % (+0.07 %), T -0.06 % (-0.03 %); 60 degrees, omega0 0.99: R -0.00 % (+0.04 %), T +0.43 %
// (+0.31 %). Before (3D sweeps of 9 copies along z, 303 directions): 60 degrees R -3.1 %.
// Within 0.5 % plus 3 standard errors (0.1-0.3 %).
TEST_F(CloudTest, StepCloudSweptInItsPlaneAgreesWithMonteCarlo)
{
    for (auto [zenith, omega0] : {std::pair<double, double>{0.0, 1.0}, {60.0, 0.99}}) {
        grids::BuildParams params;
        params.res = 32;
        params.albedo = float(omega0);
        const Cloud cloud = buildCloud(grids::makeStepCloud(params));
        CloudTransferOptions o = hgSlabOptions(0.85);
        o.directions = 1000;
        o.harmonicWeights = true;
        o.source = VoxelSource::Linear;
        o.sunZenith = zenith;
        CloudTransfer transfer(cloud, o);
        EXPECT_EQ(transfer.copies(), Coord(1));
        transfer.solve();
        ASSERT_TRUE(transfer.converged()) << zenith;
        test::ColumnsProblem p;
        for (int c = 0; c < 32; ++c) p.columnTau.push_back(c < 16 ? 2.0 : 18.0);
        p.omega0 = omega0, p.g = 0.85, p.theta0 = zenith;
        test::MonteCarloRun run;
        run.photons = 1000000;
        run.seed = 7;
        const test::SlabResult mc = test::columnsMonteCarlo(p, run);
        const CloudBudget& b = transfer.budget();
        std::printf("step cloud res 32, sun %g, omega0 %g: R %.5f (MC %.5f, %+.2f %%), T %.5f "
            "(MC %.5f, %+.2f %%), %d sweeps\n", zenith, omega0, b.albedo, mc.reflectance,
            100.0 * (b.albedo / mc.reflectance - 1.0), b.transmittance, mc.transmittance,
            100.0 * (b.transmittance / mc.transmittance - 1.0), transfer.iterationCount());
        EXPECT_NEAR(b.albedo, mc.reflectance, 0.005 * mc.reflectance + 3 * mc.reflectanceStderr);
        EXPECT_NEAR(b.transmittance, mc.transmittance,
            0.005 * mc.transmittance + 3 * mc.transmittanceStderr);
        EXPECT_NEAR(b.balance(), 0.0, 1e-4);
    }
}

// Issue 24: a periodic box one voxel deep along both horizontal axes is a plane-parallel slab,
// swept along the vertical alone (discrete ordinates on the direction set). Issue 24's slab
// criterion: HG g = 0.848, conservative, tau 0.5 to 100, on 80 layers, against adding-doubling:
// within 0.1 % at its defaults (phase order 10, 2000 directions, harmonic weights, linear
// source, Anderson chosen from the medium); measured -0.008 / -0.042 / -0.053 / -0.037 /
// -0.000 / +0.023 % at tau 0.5 / 2 / 5 / 10 / 50 / 100; the test runs the thinnest, the worst
// and the thickest. Issue 46's, at today's defaults (order 8, 967 directions): a forward peak
// of g 0.877 within 0.3 % at tau 10 and 100 (measured -0.14 / +0.00 %), and the Mie phase
// function of cloud C.1 (samples/phase/cloud_c1.txt, 300 Legendre terms, g 0.848; the reference
// sums the series, test_cloud_reference.cc) likewise (measured +0.01 / +0.01 %; tau 2: +0.19 %).
TEST_F(CloudTest, OneVoxelWideBoxIsThePlaneParallelSlab)
{
    const PhaseFunction c1 = PhaseFunction::readLegendre(VDBRAD_SOURCE_DIR
        "/samples/phase/cloud_c1.txt");
    struct Case { double g, tau; int order, directions; double tolerance; bool mie = false; };
    for (const Case c : {Case{0.848, 0.5, 10, 2000, 0.001}, Case{0.848, 5.0, 10, 2000, 0.001},
             Case{0.848, 100.0, 10, 2000, 0.001}, Case{0.877, 10.0, -1, 0, 0.003},
             Case{0.877, 100.0, -1, 0, 0.003}, Case{0.848, 10.0, -1, 0, 0.003, true},
             Case{0.848, 100.0, -1, 0, 0.003, true}}) {
        CloudTransferOptions o;
        o.periodic = true;
        o.phase = c.mie ? c1 : PhaseFunction::henyeyGreenstein(c.g);
        o.phaseOrder = c.order;
        o.directions = c.directions;
        CloudTransfer transfer(slab(1, 80, 1, c.tau, 1.f), o);
        const std::string said = transfer.describe();
        EXPECT_NE(said.find("deep along x z"), std::string::npos) << said;
        EXPECT_NE(said.find(c.order < 0 ? "phase order 8" : "phase order 10"), std::string::npos)
            << said;
        EXPECT_EQ(transfer.directions().size(),
            DirectionSet::fromCount(c.order < 0 ? 1000 : 2000).size());
        transfer.solve();
        ASSERT_TRUE(transfer.converged()) << c.tau;
        test::SlabProblem problem;
        problem.tau = c.tau;
        problem.g = c.g;
        for (int l = 0; c.mie && l < 300; ++l) problem.legendre.push_back(c1.chi(l));
        // 128 nodes integrate C.1's series exactly (test_cloud_reference.cc).
        const double exact = test::addingDoublingSlab(problem, c.mie ? 128 : 64).reflectance;
        std::printf("plane-parallel %s g %g tau %g: albedo %.5f, exact %.5f (%+.3f %%), "
            "%d sweeps\n",
            c.mie ? "C.1" : "HG", c.g, c.tau, transfer.budget().albedo, exact,
            100.0 * (transfer.budget().albedo / exact - 1.0), transfer.iterationCount());
        EXPECT_NEAR(transfer.budget().albedo, exact, c.tolerance * exact) << c.g << " " << c.tau;
        EXPECT_NEAR(transfer.budget().balance(), 0.0, 1e-4) << c.tau;
    }
}

// Issues 24 and 46, defaults chosen from the phase function and the medium: phase order 8 for
// any anisotropic phase (delta-M beyond), 1000 directions for a peak (|g| > 0.5), acceleration
// where plain sweeps would be slow.
TEST_F(CloudTest, DefaultsFollowThePhaseFunctionAndTheMedium)
{
    CloudTransferOptions o;
    EXPECT_EQ(CloudTransfer::phaseOrderFor(o), 0);
    EXPECT_EQ(CloudTransfer::directionCount(o), 300);
    for (auto [g, order, directions] : {std::tuple<double, int, int>{0.3, 8, 300},
             {0.5, 8, 300}, {0.6, 8, 1000}, {0.85, 8, 1000}, {0.877, 8, 1000},
             {-0.95, 8, 1000}}) {
        o.phase = PhaseFunction::henyeyGreenstein(g);
        EXPECT_EQ(CloudTransfer::phaseOrderFor(o), order) << g;
        EXPECT_EQ(CloudTransfer::directionCount(o), directions) << g;
    }
    o.phaseOrder = 4;
    o.directions = 50;
    EXPECT_EQ(CloudTransfer::phaseOrderFor(o), 4);
    EXPECT_EQ(CloudTransfer::directionCount(o), 50);
    // Acceleration: omega0 tau / (tau + 2) against 1/2 for the thickest column.
    CloudTransferOptions iso;
    iso.periodic = true;
    EXPECT_EQ(CloudTransfer::chooseAcceleration(slab(2, 10, 2, 1.0, 1.f), iso),
        Acceleration::None);                                           // 1/3
    EXPECT_EQ(CloudTransfer::chooseAcceleration(slab(2, 10, 2, 3.0, 1.f), iso),
        Acceleration::Anderson);                                       // 3/5
    EXPECT_EQ(CloudTransfer::chooseAcceleration(slab(2, 10, 2, 10.0, 0.5f), iso),
        Acceleration::None);                                           // 5/12
    iso.accelerate = Acceleration::None;
    EXPECT_EQ(CloudTransfer::chooseAcceleration(slab(2, 10, 2, 10.0, 1.f), iso),
        Acceleration::None);
    CloudTransferOptions bad;
    bad.phaseOrder = -2;
    EXPECT_THROW(CloudTransfer(slab(1, 4, 1, 1.0, 1.f), bad), openvdb::ValueError);
}

} // namespace

// Issue 24, a Lambertian ground: a plane-parallel slab (40 layers, default settings) over a
// ground of albedo 0.4 against the adding method (the ground added to adding-doubling's slab,
// tests/CloudReference.h), sun at 0 and 60 degrees: the domain albedo within 0.3 % and the
// ground's irradiance within 0.6 % (measured: worst +0.27 % and -0.48 %, where the irradiance is
// 0.062 under tau 10 at 60 degrees), and the energy balance to 1e-4.
TEST_F(CloudTest, PlaneParallelSlabOverAGroundIsTheAddingMethod)
{
    for (double g : {0.0, 0.85}) {
        for (double zenith : {0.0, 60.0}) {
            for (auto [tau, omega0] : {std::pair<double, float>{2.0, 1.f}, {10.0, 0.9f}}) {
                CloudTransferOptions o;
                o.periodic = true;
                o.groundAlbedo = 0.4;
                o.sunZenith = zenith;
                if (g != 0.0) o.phase = PhaseFunction::henyeyGreenstein(g);
                CloudTransfer transfer(slab(1, 40, 1, tau, omega0), o);
                transfer.solve();
                ASSERT_TRUE(transfer.converged()) << g << ' ' << zenith << ' ' << tau;
                test::SlabProblem problem;
                problem.tau = tau;
                problem.omega0 = omega0;
                problem.g = g;
                problem.mu0 = std::cos(zenith * vdbrad::kPi / 180.0);
                problem.groundAlbedo = 0.4;
                const test::SlabResult exact = test::slabOverGround(problem);
                const CloudBudget& b = transfer.budget();
                std::printf("g %g sun %g tau %g omega0 %g: albedo %.5f exact %.5f (%+.3f %%), "
                    "ground %.5f exact %.5f (%+.3f %%), %d sweeps, balance %.1e\n", g, zenith,
                    tau, omega0, b.albedo, exact.reflectance,
                    100.0 * (b.albedo / exact.reflectance - 1.0), b.transmittance,
                    exact.transmittance, 100.0 * (b.transmittance / exact.transmittance - 1.0),
                    transfer.iterationCount(), b.balance());
                EXPECT_NEAR(b.albedo, exact.reflectance, 0.003 * exact.reflectance);
                EXPECT_NEAR(b.transmittance, exact.transmittance, 0.006 * exact.transmittance);
                EXPECT_NEAR(b.groundReflected, 0.4 * b.transmittance, 1e-12);
                EXPECT_NEAR(b.balance(), 0.0, 1e-4);
            }
        }
    }
}

// The ground alone (clear air above it) sends up everything it reflects: a periodic box
// reflects exactly the ground's albedo for any sun (the weights reflect exactly rho E, Ground.h);
// an open box lit at 60 degrees rho times the part of the beam that reaches its footprint (the
// beam enters its sunlit side too, and leaves through the far side). The ground's grid holds
// the direct irradiance, F0 cos(zenith) on every cell.
TEST_F(CloudTest, ClearAirOverAGroundReflectsTheGroundsAlbedo)
{
    for (bool periodic : {true, false}) {
        for (double zenith : {0.0, 60.0}) {
            CloudTransferOptions o;
            o.periodic = periodic;
            o.groundAlbedo = 0.4;
            o.sunZenith = zenith;
            o.directions = 300;
            o.irradiance = 3.0;
            const Cloud cloud = slab(6, 5, 4, 0.0, 1.f);
            CloudTransfer transfer(cloud, o);
            transfer.solve();
            ASSERT_TRUE(transfer.converged());
            const CloudBudget& b = transfer.budget();
            EXPECT_NEAR(b.albedo, b.groundReflected, 1e-6) << periodic << ' ' << zenith;
            EXPECT_NEAR(b.transmittance, 1.0, 1e-9);
            EXPECT_NEAR(b.balance(), 0.0, 1e-6);
            EXPECT_EQ(b.absorptance, 0.0);
            const openvdb::FloatGrid::Ptr ground = transfer.groundGrid();
            ASSERT_TRUE(ground);
            EXPECT_EQ(ground->activeVoxelCount(), openvdb::Index64(6 * 4));
            EXPECT_EQ(ground->evalActiveVoxelBoundingBox(),
                openvdb::CoordBBox(Coord(0, -1, 0), Coord(5, -1, 3)));
            const double mu0 = std::cos(zenith * vdbrad::kPi / 180.0);
            // Clear air: every cell of the footprint is lit alike, through the top and the
            // sunlit side (the beam's rays meet the ground equally spaced: SolarBeam.h).
            for (auto it = ground->cbeginValueOn(); it; ++it) {
                EXPECT_NEAR(*it, 3.0 * mu0, 1e-5) << it.getCoord() << ' ' << periodic << ' '
                                                  << zenith;
            }
            if (periodic || zenith == 0.0) {
                EXPECT_NEAR(b.albedo, 0.4, 1e-6) << zenith;
            } else {
                // The beam enters the open box's top (6 x 4 voxels) and its sunlit side (5 x 4),
                // and the ground sends up 0.4 times what lands on it, F0 mu0 on its 6 x 4.
                const double top = 24.0 * mu0, side = 20.0 * std::sin(60.0 * vdbrad::kPi / 180.0);
                // (The rays cross the side's 5 x tan(60) = 8.66 voxels of reach in whole
                // steps of half a voxel: 1 %.)
                EXPECT_NEAR(b.albedo, 0.4 * top / (top + side), 0.015 * b.albedo);
            }
        }
    }
}

// A white ground under a conservative cloud: nothing is absorbed anywhere, so everything comes
// back up (the slowest loop, light between cloud and ground, converges under Anderson).
TEST_F(CloudTest, WhiteGroundUnderAConservativeCloudReflectsEverything)
{
    for (double g : {0.0, 0.85}) {
        CloudTransferOptions o;
        o.periodic = true;
        o.groundAlbedo = 1.0;
        o.sunZenith = 30.0;
        o.directions = 300;
        if (g != 0.0) {
            o.phase = PhaseFunction::henyeyGreenstein(g);
            o.phaseOrder = 8;
        }
        CloudTransfer transfer(slab(1, 20, 1, 5.0, 1.f), o);
        EXPECT_NE(transfer.describe().find("Anderson"), std::string::npos);
        transfer.solve();
        ASSERT_TRUE(transfer.converged()) << g;
        const CloudBudget& b = transfer.budget();
        std::printf("white ground, g %g: albedo %.7f, %d sweeps\n", g, b.albedo,
            transfer.iterationCount());
        EXPECT_NEAR(b.albedo, 1.0, 1e-4) << g;
        EXPECT_EQ(b.absorptance, 0.0);
        EXPECT_NEAR(b.groundReflected, b.transmittance, 1e-12);
    }
}

// The 2D step cloud (res 32, sun 60 degrees, conservative, default settings) over a ground of
// albedo 0.4 against the photon Monte Carlo of the same columns over the same ground: domain
// albedo and the ground's mean irradiance within 0.5 % + 3 sigma, the balance to 1e-4.
TEST_F(CloudTest, StepCloudOverAGroundAgreesWithMonteCarlo)
{
    grids::BuildParams params;
    params.res = 32;
    params.albedo = 1.f;
    const Cloud cloud = buildCloud(grids::makeStepCloud(params));
    CloudTransferOptions o;
    o.periodic = true;
    o.phase = PhaseFunction::henyeyGreenstein(0.85);
    o.sunZenith = 60.0;
    o.groundAlbedo = 0.4;
    CloudTransfer transfer(cloud, o);
    transfer.solve();
    ASSERT_TRUE(transfer.converged());
    test::ColumnsProblem p;
    for (int c = 0; c < 32; ++c) p.columnTau.push_back(c < 16 ? 2.0 : 18.0);
    p.omega0 = 1.0, p.g = 0.85, p.theta0 = 60.0, p.groundAlbedo = 0.4;
    test::MonteCarloRun run;
    run.photons = 1000000;
    run.seed = 11;
    const test::SlabResult mc = test::columnsMonteCarlo(p, run);
    const CloudBudget& b = transfer.budget();
    std::printf("step cloud over a ground of 0.4: R %.5f (MC %.5f, %+.2f %%), ground %.5f "
        "(MC %.5f, %+.2f %%), %d sweeps\n", b.albedo, mc.reflectance,
        100.0 * (b.albedo / mc.reflectance - 1.0), b.transmittance, mc.transmittance,
        100.0 * (b.transmittance / mc.transmittance - 1.0), transfer.iterationCount());
    EXPECT_NEAR(b.albedo, mc.reflectance, 0.005 * mc.reflectance + 3 * mc.reflectanceStderr);
    EXPECT_NEAR(b.transmittance, mc.transmittance,
        0.005 * mc.transmittance + 3 * mc.transmittanceStderr);
    EXPECT_NEAR(b.balance(), 0.0, 1e-4);
    // The ground's cells hold its irradiance: their mean is the transmittance times F0 mu0, but
    // for what the periodic matching lets leave the box where no line re-enters and the last
    // sweep's against the mixed iterate's (0.03 % at order 10 and 2013 directions, 0.05 % at
    // the defaults since issue 46, order 8 and 967).
    const std::vector<float> E = transfer.groundIrradiance();
    ASSERT_EQ(E.size(), size_t(params.res));
    double mean = 0.0;
    for (float e : E) mean += double(e) / double(E.size());
    EXPECT_NEAR(mean, 0.5 * b.transmittance, 1e-3 * mean);
}

// A checkpoint of a solve over a ground holds the ground's light and budget: restored, the
// budget is the saved one and the next sweeps give the uninterrupted run's bits.
TEST_F(CloudTest, StateOverAGroundRestoresTheSameSolve)
{
    const Cloud cloud = slab(4, 6, 3, 3.0, 0.95f);
    CloudTransferOptions o;
    o.periodic = true;
    o.groundAlbedo = 0.4;
    o.directions = 60;
    o.accelerate = Acceleration::Anderson;
    CloudTransfer full(cloud, o);
    for (int i = 0; i < 4; ++i) full.iterate();
    SolverState state;
    full.saveState(state);
    const CloudBudget saved = full.budget();
    for (int i = 0; i < 3; ++i) full.iterate();
    CloudTransfer resumed(cloud, o);
    resumed.restoreState(state);
    EXPECT_GT(saved.groundReflected, 0.0);
    EXPECT_EQ(resumed.budget().groundReflected, saved.groundReflected);
    EXPECT_EQ(resumed.budget().balance(), saved.balance());
    for (int i = 0; i < 3; ++i) resumed.iterate();
    EXPECT_EQ(resumed.budget().groundReflected, full.budget().groundReflected);
    EXPECT_EQ(resumed.groundIrradiance(), full.groundIrradiance());
    EXPECT_EQ(resumed.meanIntensity(), full.meanIntensity());
}

// An RGB single-scattering albedo (Houdini's `Cd`, Blender's `color` on smoke) is three grey
// problems: light of each colour travels alone. Each channel of the RGB solve must be the grey
// solve of that channel's albedo, bit for bit, with the colours' budgets as metadata.
TEST_F(CloudTest, RgbAlbedoIsSolvedChannelByChannel)
{
    auto density = openvdb::FloatGrid::create(0.f);
    density->setName("density");
    density->setTransform(openvdb::math::Transform::createLinearTransform(0.2));
    auto rgb = openvdb::Vec3SGrid::create();
    rgb->setName("albedo");
    rgb->setTransform(density->transform().copy());
    for (int x = 0; x < 9; ++x) {
        for (int y = 0; y < 8; ++y) {
            for (int z = 0; z < 7; ++z) {
                density->tree().setValueOn({x, y, z}, 0.5f + float((x + 2 * y + z) % 5));
                rgb->tree().setValueOn({x, y, z},
                    openvdb::Vec3f(0.99f, 0.6f + 0.05f * float(x % 3), 0.2f));
            }
        }
    }
    CloudTransferOptions o;
    o.directions = 50;
    o.sunZenith = 40.0;
    o.tolerance = 1e-7;
    const Cloud cloud = buildCloud({density, rgb});
    ASSERT_TRUE(cloud.albedo().isRgb());
    const auto J = openvdb::gridPtrCast<openvdb::Vec3SGrid>(solveCloud(cloud, o));
    ASSERT_TRUE(J);
    const auto reflected = J->metaValue<openvdb::Vec3f>("vdbrad:albedo");
    for (int c = 0; c < 3; ++c) {
        auto grey = openvdb::FloatGrid::create(0.f);
        grey->setName("albedo");
        grey->setTransform(density->transform().copy());
        for (auto it = rgb->cbeginValueOn(); it; ++it) {
            grey->tree().setValueOn(it.getCoord(), (*it)[c]);
        }
        const auto j = openvdb::gridPtrCast<openvdb::FloatGrid>(
            solveCloud(buildCloud({density, grey}), o));
        ASSERT_TRUE(j);
        size_t voxels = 0;
        for (auto it = j->cbeginValueOn(); it; ++it, ++voxels) {
            ASSERT_EQ(J->tree().getValue(it.getCoord())[c], *it) << c << " " << it.getCoord();
        }
        EXPECT_EQ(voxels, 504u);
        EXPECT_EQ(reflected[c], j->metaValue<float>("vdbrad:albedo"));
    }
    // Whiter scatters more: the red channel (0.99) reflects more than the blue (0.2).
    EXPECT_GT(reflected[0], 2.f * reflected[2]);
}

// Volume emission (fire: Blender's and Houdini's `flame`) in a plane-parallel slab (a periodic
// box one voxel wide) emitting epsilon per unit length, optical depth 40. Deep inside, the
// radiance is the infinite medium's for any direction set, epsilon / sigma_a (the source
// omega0 J + epsilon / sigma_t equals J there); a pure absorber sends
// pi epsilon / sigma_t (1 - 2 E3(tau)) out of each face, 1 / (4 tau) of what it emits
// (E3(40) ~ 1e-19); and the energy balances.
TEST_F(CloudTest, EmittingSlabHasTheInfiniteMediumsRadianceInside)
{
    const double h = 0.1, sigma = 10.0;   // optical depth 1 per voxel
    const int ny = 40;
    for (float albedo : {0.f, 0.5f, 0.9f}) {
        auto density = openvdb::FloatGrid::create(0.f);
        density->setName("density");
        density->setTransform(openvdb::math::Transform::createLinearTransform(h));
        density->tree().fill(openvdb::CoordBBox(Coord(0), Coord(0, ny - 1, 0)), float(sigma), true);
        density->tree().voxelizeActiveTiles();
        auto flame = density->deepCopy();
        flame->setName("flame");
        for (auto it = flame->beginValueOn(); it; ++it) it.setValue(4.f);
        CloudOptions co;
        co.defaultAlbedo = albedo;
        co.emissionScale = 0.5f;   // epsilon = 2 per world unit
        const Cloud cloud = buildCloud({density, flame}, co);
        EXPECT_EQ(cloud.emissionName(), "flame");
        EXPECT_EQ(cloud.lostEmitters(), 0u);
        CloudTransferOptions o;
        o.periodic = true;
        o.irradiance = 0.0;
        o.directions = 300;
        o.tolerance = 1e-7;
        CloudTransfer transfer(cloud, o);
        transfer.solve();
        ASSERT_TRUE(transfer.converged()) << albedo;
        const std::vector<float> J = transfer.meanIntensity();
        const double infinite = 2.0 / ((1.0 - albedo) * sigma);
        const int mid = cloud.voxels().find(Coord(0, ny / 2, 0));
        const CloudBudget& b = transfer.budget();
        std::printf("emitting slab, albedo %.1f: J mid %.7g (infinite medium %.7g), up %.6f "
            "(pure absorber 1 / (4 tau) = %.6f), balance %.2g\n", albedo, J[size_t(mid)],
            infinite, b.albedo, 1.0 / (4.0 * ny), b.balance());
        EXPECT_NEAR(J[size_t(mid)], infinite, 1e-4 * infinite) << albedo;
        EXPECT_NEAR(b.balance(), 0.0, 1e-5) << albedo;
        EXPECT_DOUBLE_EQ(b.mediumEmitted, 1.0);   // no sun: all the light is the fire's
        EXPECT_NEAR(b.albedo, b.transmittance, 1e-6) << albedo;   // symmetric
        if (albedo == 0.f) {
            EXPECT_NEAR(b.albedo, 1.0 / (4.0 * ny), 0.01 / (4.0 * ny));   // measured 0.16 %
        }
    }
}

// ---- light from the sky (issue 45) -------------------------------------------------------------

namespace {

// E_n(x) = integral over mu in (0, 1] of mu^(n - 2) exp(-x / mu) (Simpson; x > 0 keeps it smooth).
double
exponentialIntegral(int n, double x)
{
    const int steps = 20000;
    double sum = 0.0;
    for (int k = 1; k <= steps; ++k) {
        const double mu = double(k) / steps;
        const double w = k == steps ? 1.0 : (k % 2 ? 4.0 : 2.0);
        sum += w * std::pow(mu, n - 2) * std::exp(-x / mu);
    }
    return sum / (3.0 * steps);
}

} // namespace

// The cloud furnace: albedo 1 under a uniform sky L and no sun, the radiance is L everywhere,
// so J = L in every voxel of a non-convex cumulus, scattering isotropically or forward; all the
// light is the sky's, none absorbed, and the energy balances.
TEST_F(CloudTest, ConservativeCloudUnderAUniformSkyIsAFurnace)
{
    grids::BuildParams p;
    p.res = 32;
    p.albedo = 1.f;
    const Cloud cloud = buildCloud(grids::makeCumulus(p));
    const double L = 0.7;
    for (double g : {0.0, 0.7}) {
        CloudTransferOptions o;
        o.irradiance = 0.0;
        o.sky = Sky::uniform(openvdb::Vec3d(L));
        o.directions = 100;
        o.tolerance = 1e-7;
        if (g != 0.0) {
            o.phase = PhaseFunction::henyeyGreenstein(g);
            o.phaseOrder = 4;
        }
        CloudTransfer transfer(cloud, o);
        transfer.solve();
        ASSERT_TRUE(transfer.converged()) << g;
        const std::vector<float> J = transfer.meanIntensity();
        float lo = J[0], hi = J[0];
        for (float j : J) {
            lo = std::min(lo, j);
            hi = std::max(hi, j);
        }
        std::printf("cumulus furnace under a sky, g %.1f: J in [%.7f, %.7f] (L %.1f)\n", g, lo, hi,
            L);
        EXPECT_NEAR(lo, L, 1e-4 * L) << g;
        EXPECT_NEAR(hi, L, 1e-4 * L) << g;
        const CloudBudget& b = transfer.budget();
        EXPECT_DOUBLE_EQ(b.sky, 1.0);
        EXPECT_EQ(b.absorptance, 0.0);
        EXPECT_NEAR(b.balance(), 0.0, 1e-5) << g;
        // The scattered source is L in every direction: its Y_00 coefficient sqrt(4 pi) L,
        // the others 0 (order 4 asked; an isotropic solve has order 0 only).
        const std::vector<float> c = transfer.scatteredSource(4);
        const size_t width = g == 0.0 ? 1 : 25;
        ASSERT_EQ(c.size(), cloud.size() * width) << g;
        double y00 = 0.0, rest = 0.0;
        for (size_t i = 0; i < cloud.size(); ++i) {
            y00 = std::max(y00, std::abs(c[i * width] / std::sqrt(4.0 * kPi) - L));
            for (size_t k = 1; k < width; ++k) {
                rest = std::max(rest, double(std::abs(c[i * width + k])));
            }
        }
        EXPECT_LT(y00, 1e-4 * L) << g;
        EXPECT_LT(rest, 1e-4 * L) << g;
    }
}

// The phase function as text (a solved file carries it for the renderer): read back, the same
// function to the bit; anything else is refused.
TEST(PhaseFunctionText, ReadsBackTheSameFunction)
{
    for (const PhaseFunction& p : {PhaseFunction(), PhaseFunction::henyeyGreenstein(0.877),
             PhaseFunction::henyeyGreenstein(-0.3), PhaseFunction::legendre({1.0, 0.7, 0.45,
             1.0 / 3.0, 1e-17})}) {
        const PhaseFunction q = PhaseFunction::parse(p.text());
        EXPECT_EQ(q.text(), p.text());
        for (const double mu : {-1.0, -0.3, 0.0, 0.5, 0.99, 1.0}) {
            EXPECT_EQ(q.value(mu), p.value(mu)) << p.text() << " " << mu;
        }
        for (int l = 0; l < 12; ++l) EXPECT_EQ(q.chi(l), p.chi(l)) << p.text() << " " << l;
    }
    for (const char* bad : {"", "hg", "hg 0.5 0.6", "hg 1.5", "legendre", "legendre 0.9 0.5",
             "isotropic 1", "mie 0.8", "hg 0.5x"}) {
        EXPECT_THROW(PhaseFunction::parse(bad), openvdb::ValueError) << bad;
    }
}

// A periodic, purely absorbing slab of optical thickness tau under a uniform sky L: at depth t
// the mean radiance is L / 2 (E2(t) + E2(tau - t)), a layer's mean of it (E3 differences), and
// 2 E3(tau) of the incident light (pi L from each side) leaves; the side faces pass it on. The
// directions' discretisation shows near the grazing ones: 1.7 % at 300 directions, 0.6 % at
// 1000 (measured), so the test holds both bounds and the fall between them.
TEST_F(CloudTest, AbsorbingPeriodicSlabUnderASkyFollowsTheExponentialIntegrals)
{
    const int ny = 10;
    const double tau = 1.0, L = 0.5, dt = tau / ny, A = 256.0;
    const Cloud cloud = slab(16, ny, 16, tau, 0.f);
    double worst[2] = {0.0, 0.0};
    for (int k = 0; k < 2; ++k) {
        CloudTransferOptions o;
        o.periodic = true;
        o.minPeriod = 0;
        o.irradiance = 0.0;
        o.sky = Sky::uniform(openvdb::Vec3d(L));
        o.directions = k == 0 ? 300 : 1000;
        o.tolerance = 1e-7;
        CloudTransfer transfer(cloud, o);
        transfer.solve();
        ASSERT_TRUE(transfer.converged());
        const std::vector<float> J = transfer.meanIntensity();
        for (int y = 0; y < ny; ++y) {
            double mean = 0.0;
            for (int x = 0; x < 16; ++x) {
                for (int z = 0; z < 16; ++z) {
                    mean += J[size_t(cloud.voxels().find(Coord(x, y, z)))];
                }
            }
            mean /= A;
            const double a = y * dt, b = (y + 1) * dt;
            const double exact = 0.5 * L / dt * (exponentialIntegral(3, a)
                - exponentialIntegral(3, b) + exponentialIntegral(3, tau - b)
                - exponentialIntegral(3, tau - a));
            worst[k] = std::max(worst[k], std::abs(mean / exact - 1.0));
        }
        const CloudBudget& bu = transfer.budget();
        const double out = 2.0 * exponentialIntegral(3, tau), in = 2.0 * kPi * L * A;
        std::printf("absorbing periodic slab under a sky, %d directions: layers' J within %.3f %%; "
            "out %.5f (2 E3 %.5f), incident %.2f (2 pi L A %.2f)\n", o.directions,
            100.0 * worst[k], bu.albedo + bu.transmittance, out, bu.incident, in);
        const double tolerance = k == 0 ? 0.02 : 0.01;
        EXPECT_LT(worst[k], tolerance);
        EXPECT_NEAR(bu.albedo + bu.transmittance, out, tolerance * out);
        EXPECT_NEAR(bu.albedo, bu.transmittance, 3e-4 * bu.albedo);   // 1.3e-4 at 300
        EXPECT_NEAR(bu.incident, in, tolerance * in);
        EXPECT_NEAR(bu.balance(), 0.0, 1e-5);
    }
    EXPECT_LT(worst[1], 0.5 * worst[0]);
}

// A coloured sky and a coloured sun are solved channel by channel: each channel of the RGB
// solve is the grey solve under that channel's sky and sun, to the bit.
TEST_F(CloudTest, ColouredSkyAndSunAreSolvedChannelByChannel)
{
    const Cloud cloud = slab(6, 5, 7, 2.0, 0.9f);
    const openvdb::Vec3d sky(0.2, 0.3, 0.5), colour(1.0, 0.6, 0.3);
    CloudTransferOptions o;
    o.directions = 50;
    o.sunZenith = 40.0;
    o.irradiance = 2.0;
    o.sunColour = colour;
    o.sky = Sky::uniform(sky);
    o.tolerance = 1e-7;
    const auto J = openvdb::gridPtrCast<openvdb::Vec3SGrid>(solveCloud(cloud, o));
    ASSERT_TRUE(J);
    for (int c = 0; c < 3; ++c) {
        CloudTransferOptions grey = o;
        grey.irradiance = 2.0 * colour[c];
        grey.sunColour = openvdb::Vec3d(1.0);
        grey.sky = Sky::uniform(openvdb::Vec3d(sky[c]));
        const auto j = openvdb::gridPtrCast<openvdb::FloatGrid>(solveCloud(cloud, grey));
        ASSERT_TRUE(j);
        size_t voxels = 0;
        for (auto it = j->cbeginValueOn(); it; ++it, ++voxels) {
            ASSERT_EQ(J->tree().getValue(it.getCoord())[c], *it) << c << " " << it.getCoord();
        }
        EXPECT_EQ(voxels, 210u);
    }
}

// A constant latitude-longitude map is the uniform sky of its value.
TEST_F(CloudTest, ConstantMapIsTheUniformSky)
{
    const Cloud cloud = slab(6, 5, 7, 2.0, 0.8f);
    CloudTransferOptions o;
    o.directions = 50;
    o.irradiance = 0.0;
    o.tolerance = 1e-7;
    o.sky = Sky::uniform(openvdb::Vec3d(0.4));
    CloudTransfer uniform(cloud, o);
    uniform.solve();
    o.sky = Sky::fromMap(16, 8, std::vector<openvdb::Vec3f>(128, openvdb::Vec3f(0.4f)), 1);
    ASSERT_FALSE(o.sky.sun());
    CloudTransfer map(cloud, o);
    map.solve();
    const std::vector<float> a = uniform.meanIntensity(), b = map.meanIntensity();
    ASSERT_EQ(a.size(), b.size());
    for (size_t i = 0; i < a.size(); ++i) EXPECT_NEAR(b[i], a[i], 1e-6 * a[i]) << i;
}

// Issue 46: the defaults must not depend on how a file happens to be written. The step cloud
// written four voxels deep along its uniform axis (z), over a ground, is solved as the one-deep
// cloud (uniformSlice): its mean radiance is the one-deep solve's, every layer, to the bit, and
// so is the ground's irradiance; a cloud that varies along an axis is not sliced along it.
TEST_F(CloudTest, PeriodicBoxesUniformAlongAnAxisAreSolvedOneVoxelDeep)
{
    grids::BuildParams params;
    params.res = 32;
    params.albedo = 1.f;
    const Cloud thin = buildCloud(grids::makeStepCloud(params));
    ASSERT_EQ(thin.voxels().bbox().dim().z(), 1);
    const Cloud deep = tileCloud(thin, openvdb::Coord(1, 1, 4));
    EXPECT_EQ(uniformAxes(deep, 1), (std::array<bool, 3>{false, false, true}));
    EXPECT_EQ(uniformAxes(thin, 1), (std::array<bool, 3>{}));   // one deep: nothing to slice
    CloudTransferOptions o;
    o.periodic = true;
    o.phase = PhaseFunction::henyeyGreenstein(0.85);
    o.phaseOrder = 4;
    o.directions = 100;
    o.sunZenith = 60.0;
    o.groundAlbedo = 0.4;
    o.maxIterations = 8;
    o.tolerance = 0.0;
    const std::unique_ptr<Cloud> slice = uniformSlice(deep, o);
    ASSERT_TRUE(slice);
    EXPECT_EQ(slice->size(), thin.size());
    openvdb::FloatGrid::Ptr groundThin, groundDeep;
    const auto Jthin = openvdb::gridPtrCast<openvdb::FloatGrid>(
        solveCloud(thin, o, nullptr, SolveControl(), &groundThin));
    const auto Jdeep = openvdb::gridPtrCast<openvdb::FloatGrid>(
        solveCloud(deep, o, nullptr, SolveControl(), &groundDeep));
    ASSERT_TRUE(Jthin && Jdeep && groundThin && groundDeep);
    EXPECT_EQ(Jdeep->activeVoxelCount(), deep.size());
    EXPECT_EQ(groundDeep->activeVoxelCount(), 4 * groundThin->activeVoxelCount());
    EXPECT_EQ(Jdeep->metaValue<int32_t>("vdbrad:iterations"), 8);
    auto thinAcc = Jthin->getConstAccessor(), groundAcc = groundThin->getConstAccessor();
    size_t checked = 0;
    for (auto it = Jdeep->cbeginValueOn(); it; ++it, ++checked) {
        openvdb::Coord c = it.getCoord();
        c.z() = thin.voxels().bbox().min().z();
        ASSERT_EQ(*it, thinAcc.getValue(c)) << it.getCoord();
    }
    EXPECT_EQ(checked, deep.size());
    for (auto it = groundDeep->cbeginValueOn(); it; ++it) {
        openvdb::Coord c = it.getCoord();
        c.z() = thin.voxels().bbox().min().z();
        ASSERT_EQ(*it, groundAcc.getValue(c)) << it.getCoord();
    }
    // A cumulus varies along both horizontal axes; an open box is never sliced.
    const Cloud cumulus = buildCloud(grids::makeCumulus(params));
    EXPECT_EQ(uniformAxes(cumulus, 1), (std::array<bool, 3>{}));
    o.periodic = false;
    EXPECT_FALSE(uniformSlice(deep, o));
}
