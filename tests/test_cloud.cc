// CloudTransfer and SolarBeam: exact attenuation of the beam, energy balance, thin-medium limits,
// determinism. Comparisons with the independent Monte Carlo are in test_cloud_reference.cc's
// companion below (SlabAgreesWithMonteCarlo).
#include "vdbrad/Cloud.h"
#include "vdbrad/CloudTransfer.h"
#include "vdbrad/DirectionSet.h"
#include "vdbrad/PhaseFunction.h"
#include "vdbrad/SolarBeam.h"

#include "CloudReference.h"

#include <gtest/gtest.h>

#include <openvdb/openvdb.h>

#include <tbb/global_control.h>

#include <cmath>
#include <cstdio>

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

TEST_F(CloudTest, ForwardScatteringSlabAgreesWithTheExactSolution)
{
    // Henyey-Greenstein g = 0.848 (the cloud), omega0 = 1, tau = 10, sun at the zenith,
    // periodic 4 x 20 x 4 voxels, 303 directions, order 8 with delta-M and the full phase for
    // the first scattering, against adding-doubling (0.4261428). The issue aims at 1%; measured
    // +0.41% (BENCHMARKS.md: within 1.05% for tau 0.5 to 20, -1.3% at 50).
    const Cloud cloud = slab(4, 20, 4, 10.0, 1.f);
    CloudTransferOptions o;
    o.periodic = true;
    o.directions = 300;
    o.tolerance = 1e-6;
    o.phase = PhaseFunction::henyeyGreenstein(0.848);
    o.phaseOrder = 8;
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

TEST_F(CloudTest, ConservativeSlabAgreesWithTheExactSolution)
{
    // Isotropic, omega0 = 1, sun at the zenith, tau = 1, periodic 4 x 20 x 4 voxels, 303
    // directions, against adding-doubling (CloudReference.h, no shared code; 0.3413288).
    // Measured: 0.34124, -0.02% (BENCHMARKS.md: -0.7% at tau 10).
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

TEST_F(CloudTest, ResultsDoNotDependOnThreads)
{
    const Cloud cloud = slab(9, 7, 8, 2.0, 0.9f);
    CloudTransferOptions o;
    o.periodic = true;
    o.sunZenith = 50.0;
    o.directions = 111;
    o.maxIterations = 5;
    std::vector<float> reference;
    for (int threads : {1, 2, 8}) {
        tbb::global_control limit(tbb::global_control::max_allowed_parallelism, size_t(threads));
        CloudTransfer transfer(cloud, o);
        transfer.solve();
        const std::vector<float> J = transfer.meanIntensity();
        if (reference.empty()) {
            reference = J;
        } else {
            ASSERT_EQ(J.size(), reference.size());
            for (size_t i = 0; i < J.size(); ++i) ASSERT_EQ(J[i], reference[i]) << threads;
        }
    }
}

} // namespace
