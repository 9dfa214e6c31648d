// ControlPoints (thesis §5.2): the icosahedral grid, interpolation, deformation and rotations.
#include "RandomDirection.h"
#include "vdbrad/core/Constants.h"
#include "vdbrad/glossy/ControlPoints.h"

#include <gtest/gtest.h>
#include <openvdb/Exceptions.h>
#include <openvdb/math/Mat3.h>

#include <cmath>
#include <random>
#include <set>

namespace {

using vdbrad::kPi;

using openvdb::math::Mat3d;
using openvdb::math::Vec3d;
using vdbrad::ControlPoints;


using vdbrad::test::randomDirection;

// Rotation by angle a about the unit axis u (Rodrigues), acting on column vectors.
Mat3d
axisAngle(const Vec3d& u, double a)
{
    const double c = std::cos(a), s = std::sin(a), t = 1.0 - c;
    Mat3d m;
    m(0, 0) = c + u.x() * u.x() * t;       m(0, 1) = u.x() * u.y() * t - u.z() * s;
    m(0, 2) = u.x() * u.z() * t + u.y() * s;
    m(1, 0) = u.y() * u.x() * t + u.z() * s; m(1, 1) = c + u.y() * u.y() * t;
    m(1, 2) = u.y() * u.z() * t - u.x() * s;
    m(2, 0) = u.z() * u.x() * t - u.y() * s; m(2, 1) = u.z() * u.y() * t + u.x() * s;
    m(2, 2) = c + u.z() * u.z() * t;
    return m;
}

// A smooth lobe: exp(kappa (w . axis - 1)) (a von Mises-Fisher shape, width ~ 1/sqrt(kappa)).
double
lobe(const Vec3d& w, const Vec3d& axis, double kappa)
{
    return std::exp(kappa * (w.dot(axis) - 1.0));
}

TEST(ControlPoints, CountsAreasAndSpacing)
{
    const int counts[] = {12, 42, 162, 642, 2562};
    double previousSpacing = 10.0;
    for (int order = 0; order <= ControlPoints::kMaxOrder; ++order) {
        const ControlPoints cp(order);
        EXPECT_EQ(cp.size(), size_t(counts[order]));
        EXPECT_EQ(ControlPoints::orderForCount(counts[order]), order);
        EXPECT_EQ(cp.triangles().size(), size_t(20) << (2 * order));
        double total = 0.0, smallest = 1e9, largest = 0.0;
        for (size_t i = 0; i < cp.size(); ++i) {
            EXPECT_NEAR(cp.point(i).length(), 1.0, 1e-14);
            total += cp.areas()[i];
            smallest = std::min(smallest, cp.areas()[i]);
            largest = std::max(largest, cp.areas()[i]);
            // 5 neighbours at the icosahedron's vertices, 6 elsewhere.
            EXPECT_EQ(cp.neighbours(i).size(), i < 12 ? 5u : 6u);
        }
        // The small triangles tile the sphere: the areas add up to 4 pi to rounding.
        EXPECT_NEAR(total, 4.0 * kPi, 1e-10);
        // Geodesic grids are nearly uniform: the icosahedron's vertices (5 neighbours) stand
        // for the least, but not less than half of the mean.
        EXPECT_GT(smallest, 0.5 * 4.0 * kPi / double(cp.size()));
        EXPECT_LT(largest, 1.5 * 4.0 * kPi / double(cp.size()));
        // Spacing halves with each order (63.4 degrees at order 0).
        EXPECT_LT(cp.spacing(), previousSpacing * 0.6);
        previousSpacing = cp.spacing();
    }
    EXPECT_NEAR(ControlPoints(0).spacing(), std::atan(2.0), 1e-12);
    EXPECT_THROW(ControlPoints(-1), openvdb::ValueError);
    EXPECT_THROW(ControlPoints(5), openvdb::ValueError);
    EXPECT_THROW(ControlPoints::orderForCount(100), openvdb::ValueError);
}

TEST(ControlPoints, LocateMatchesBruteForce)
{
    std::mt19937_64 rng(7);
    for (int order = 0; order <= 3; ++order) {
        const ControlPoints cp(order);
        for (int s = 0; s < 2000; ++s) {
            const Vec3d d = randomDirection(rng);
            const auto& t = cp.triangles()[cp.locate(d)];
            const Vec3d &a = cp.point(t[0]), &b = cp.point(t[1]), &c = cp.point(t[2]);
            // Inside the located spherical triangle (its three edge planes), to rounding.
            EXPECT_GE(d.dot(a.cross(b)), -1e-14);
            EXPECT_GE(d.dot(b.cross(c)), -1e-14);
            EXPECT_GE(d.dot(c.cross(a)), -1e-14);
            // Exactly one triangle holds a random direction strictly.
            int holders = 0;
            for (const auto& u : cp.triangles()) {
                const Vec3d &p = cp.point(u[0]), &q = cp.point(u[1]), &r = cp.point(u[2]);
                if (d.dot(p.cross(q)) > 0 && d.dot(q.cross(r)) > 0 && d.dot(r.cross(p)) > 0) {
                    ++holders;
                }
            }
            EXPECT_EQ(holders, 1);
        }
    }
}

TEST(ControlPoints, WeightsAddUpReproduceControlValuesAndAreContinuous)
{
    std::mt19937_64 rng(11);
    const ControlPoints cp(2);
    std::vector<double> values(cp.size());
    for (auto& v : values) v = std::uniform_real_distribution<double>(0.0, 1.0)(rng);
    for (int s = 0; s < 5000; ++s) {
        const ControlPoints::Weights w = cp.weights(randomDirection(rng));
        EXPECT_NEAR(w.weight[0] + w.weight[1] + w.weight[2], 1.0, 1e-14);
        for (const double x : w.weight) EXPECT_GE(x, 0.0);
    }
    // A control point gets its own value back exactly.
    for (size_t i = 0; i < cp.size(); ++i) {
        EXPECT_NEAR(cp.evaluate(values.data(), cp.point(i)), values[i], 1e-12);
    }
    // On an edge only its two corners weigh, but the area weights split it differently seen
    // from the two triangles that share it (a spherical triangle's area is not linear in its
    // corner): the jump across an edge, and its midpoint's departure from the corners' mean,
    // stay below 2e-3 of the values' range at 162 points (and shrink with the order).
    double jump = 0.0;
    for (const auto& t : cp.triangles()) {
        const Vec3d a = cp.point(t[0]), b = cp.point(t[1]);
        const Vec3d mid = (a + b).unit(), across = a.cross(b).unit();
        const double inside = cp.evaluate(values.data(), (mid + across * 1e-9).unit());
        const double outside = cp.evaluate(values.data(), (mid - across * 1e-9).unit());
        jump = std::max(jump, std::abs(inside - outside));
        EXPECT_NEAR(cp.evaluate(values.data(), mid), 0.5 * (values[t[0]] + values[t[1]]), 2e-3);
    }
    EXPECT_LT(jump, 2e-3);
    EXPECT_GT(jump, 0.0);   // the thesis' weights, not a continuous substitute
}

TEST(ControlPoints, DeformationMovesTheInterpolatedValueWithTheLeastChange)
{
    std::mt19937_64 rng(3);
    const ControlPoints cp(2);
    for (int s = 0; s < 200; ++s) {
        std::vector<double> values(cp.size(), 0.25), before;
        const Vec3d d = randomDirection(rng);
        before = values;
        const double v0 = cp.evaluate(values.data(), d);
        cp.deform(values.data(), d, 0.7);
        EXPECT_NEAR(cp.evaluate(values.data(), d), v0 + 0.7, 1e-12);
        // Only the three corners move, by w_i delta / sum w^2 (the minimum-norm change).
        const ControlPoints::Weights w = cp.weights(d);
        const double norm = w.weight[0] * w.weight[0] + w.weight[1] * w.weight[1]
            + w.weight[2] * w.weight[2];
        size_t moved = 0;
        for (size_t i = 0; i < cp.size(); ++i) moved += values[i] != before[i];
        EXPECT_LE(moved, 3u);
        for (int k = 0; k < 3; ++k) {
            EXPECT_NEAR(values[w.index[k]] - before[w.index[k]], w.weight[k] * 0.7 / norm, 1e-12);
        }
    }
}

TEST(ControlPoints, AreasIntegrateInterpolatedFunctions)
{
    // sum_i area_i f(c_i) is the integral of the interpolated f. The grid's icosahedral symmetry
    // makes it exact for polynomials up to degree 5 (x, z^2 to rounding); a smooth f beyond
    // that converges at second order: exp(8 w.u) integrates to 4 pi sinh(8) / 8.
    const Vec3d u = Vec3d(0.3, -0.5, 0.8).unit();
    const double exact = 4.0 * kPi * std::sinh(8.0) / 8.0;
    double previous = 1.0;
    for (int order = 0; order <= 4; ++order) {
        const ControlPoints cp(order);
        double integral = 0.0, first = 0.0, second = 0.0;
        for (size_t i = 0; i < cp.size(); ++i) {
            const Vec3d& c = cp.point(i);
            integral += cp.areas()[i] * std::exp(8.0 * c.dot(u));
            first += cp.areas()[i] * c.x();
            second += cp.areas()[i] * c.z() * c.z();
        }
        EXPECT_NEAR(first, 0.0, 1e-12);
        EXPECT_NEAR(second, 4.0 * kPi / 3.0, 1e-12);
        const double error = std::abs(integral / exact - 1.0);
        std::printf("order %d: exp(8 w.u) integrated to %.2e\n", order, error);
        if (order > 0) {
            EXPECT_LT(error, previous / 3.0);   // ~4x per order
        }
        previous = error;
    }
    EXPECT_LT(previous, 2e-6);   // order 4
}

TEST(ControlPoints, FramesAreRightHandedAndCarryTheNormal)
{
    std::mt19937_64 rng(5);
    std::vector<Vec3d> normals = {Vec3d(0, 0, 1), Vec3d(0, 0, -1), Vec3d(1, 0, 0), Vec3d(0, -1, 0)};
    for (int s = 0; s < 500; ++s) normals.push_back(randomDirection(rng));
    for (const Vec3d& n : normals) {
        const Mat3d f = ControlPoints::frame(n);
        const Vec3d t(f(0, 0), f(1, 0), f(2, 0)), u(f(0, 1), f(1, 1), f(2, 1)),
            z(f(0, 2), f(1, 2), f(2, 2));
        EXPECT_NEAR((z - n).length(), 0.0, 1e-12);
        EXPECT_NEAR(t.length(), 1.0, 1e-12);
        EXPECT_NEAR(u.length(), 1.0, 1e-12);
        EXPECT_NEAR(t.dot(u), 0.0, 1e-12);
        EXPECT_NEAR((t.cross(u) - z).length(), 0.0, 1e-12);
    }
}

TEST(ControlPoints, AxisFramesMapTheGridOntoItself)
{
    const ControlPoints cp(2);
    for (int axis = 0; axis < 3; ++axis) {
        for (const double s : {-1.0, 1.0}) {
            Vec3d n(0.0);
            n[axis] = s;
            const Mat3d R = ControlPoints::frame(n);
            const ControlPoints::Map map = cp.rotation(R, ControlPoints::RotationKind::Resampled);
            // Every row takes one value, whole: a permutation.
            std::set<uint32_t> sources;
            for (size_t i = 0; i < cp.size(); ++i) {
                ASSERT_EQ(map.start[i + 1] - map.start[i], 1u);
                EXPECT_EQ(map.weight[map.start[i]], 1.f);
                sources.insert(map.source[map.start[i]]);
            }
            EXPECT_EQ(sources.size(), cp.size());
        }
    }
}

TEST(ControlPoints, SymmetryRotationsAreExactForEveryKind)
{
    // 72 degrees about an icosahedron vertex maps every level of the grid onto itself: every
    // kind of rotation is then an exact permutation of the values.
    for (int order = 0; order <= 3; ++order) {
        const ControlPoints cp(order);
        const Mat3d R = axisAngle(cp.point(0), 2.0 * kPi / 5.0);
        std::vector<double> f(cp.size()), g(cp.size());
        const Vec3d axis = Vec3d(0.3, -0.5, 0.8).unit();
        for (size_t i = 0; i < cp.size(); ++i) f[i] = lobe(cp.point(i), axis, 4.0);
        for (const auto kind : {ControlPoints::RotationKind::Permutation,
                 ControlPoints::RotationKind::Continuous, ControlPoints::RotationKind::Resampled}) {
            const ControlPoints::Map map = cp.rotation(R, kind);
            ASSERT_EQ(map.size(), cp.size());
            map.apply(f.data(), g.data());
            for (size_t i = 0; i < cp.size(); ++i) {
                EXPECT_NEAR(g[i], lobe(cp.point(i) * R, axis, 4.0), 1e-6)
                    << "order " << order << " kind " << int(kind);
            }
        }
    }
}

TEST(ControlPoints, RotationErrorsAgainstTheRotatedFunction)
{
    // A lobe of width ~ 1/sqrt(kappa) = 0.35 rad rotated by random rotations: each kind's values
    // against the rotated lobe sampled at the points, relative to the lobe's peak (1). Stated
    // bounds: at 162 points (spacing 0.32 rad) resampling and the continuous rotation stay
    // within 0.15, the permutation within 0.35 (it moves values by up to half a spacing); each
    // falls with the order.
    std::mt19937_64 rng(13);
    const double kappa = 8.0;
    double prev[3] = {1.0, 1.0, 1.0};
    for (int order = 1; order <= 4; ++order) {
        const ControlPoints cp(order);
        double worst[3] = {0.0, 0.0, 0.0};
        for (int s = 0; s < 10; ++s) {
            const Mat3d R = axisAngle(randomDirection(rng),
                std::uniform_real_distribution<double>(0.1, kPi)(rng));
            const Vec3d axis = randomDirection(rng);
            std::vector<double> f(cp.size()), g(cp.size());
            for (size_t i = 0; i < cp.size(); ++i) f[i] = lobe(cp.point(i), axis, kappa);
            int k = 0;
            for (const auto kind : {ControlPoints::RotationKind::Permutation,
                     ControlPoints::RotationKind::Continuous,
                     ControlPoints::RotationKind::Resampled}) {
                cp.rotation(R, kind).apply(f.data(), g.data());
                for (size_t i = 0; i < cp.size(); ++i) {
                    const double exact = lobe(cp.point(i), R * axis, kappa);
                    worst[k] = std::max(worst[k], std::abs(g[i] - exact));
                }
                ++k;
            }
        }
        ::testing::Test::RecordProperty("order" + std::to_string(order),
            std::to_string(worst[0]) + " " + std::to_string(worst[1]) + " "
                + std::to_string(worst[2]));
        std::printf("order %d (%zu points): max error permutation %.4f continuous %.4f "
                    "resampled %.4f\n", order, cp.size(), worst[0], worst[1], worst[2]);
        if (order == 2) {
            EXPECT_LT(worst[0], 0.35);
            EXPECT_LT(worst[1], 0.15);
            EXPECT_LT(worst[2], 0.15);
        }
        for (int k = 0; k < 3; ++k) {
            EXPECT_LT(worst[k], prev[k]);
            prev[k] = worst[k];
        }
    }
}

TEST(ControlPoints, PermutationPairsEveryPointOnceWithANearPartner)
{
    std::mt19937_64 rng(17);
    for (int order = 1; order <= 3; ++order) {
        const ControlPoints cp(order);
        for (int s = 0; s < 20; ++s) {
            const Mat3d R = axisAngle(randomDirection(rng),
                std::uniform_real_distribution<double>(0.0, kPi)(rng));
            const ControlPoints::Map map = cp.rotation(R, ControlPoints::RotationKind::Permutation);
            std::set<uint32_t> sources(map.source.begin(), map.source.end());
            EXPECT_EQ(sources.size(), cp.size());
            double far = 0.0;
            for (size_t i = 0; i < cp.size(); ++i) {
                const Vec3d from = R * cp.point(map.source[map.start[i]]);
                far = std::max(far, std::acos(std::min(1.0, from.dot(cp.point(i)))));
            }
            // No catastrophic partner: every value moves by at most one grid spacing.
            EXPECT_LE(far, cp.spacing()) << "order " << order;
        }
    }
}

TEST(ControlPoints, RefusesImproperRotations)
{
    const ControlPoints cp(1);
    Mat3d mirror = Mat3d::identity();
    mirror(2, 2) = -1.0;
    EXPECT_THROW(cp.rotation(mirror, ControlPoints::RotationKind::Resampled), openvdb::ValueError);
    Mat3d scaled = Mat3d::identity() * 1.01;
    EXPECT_THROW(cp.rotation(scaled, ControlPoints::RotationKind::Continuous), openvdb::ValueError);
}

} // namespace
