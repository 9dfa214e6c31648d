// Tests of the canonical scenes and of the exact answers they come with (grids/CanonicalGrids.h).
//
// Geometry is checked against rules re-derived here from the header's wording (not against the
// builder's own helpers), and the closed forms against brute-force quadrature.

#include "grids/CanonicalGrids.h"
#include "vdbrad/core/Constants.h"

#include <gtest/gtest.h>
#include <openvdb/openvdb.h>

#include <array>
#include <cmath>
#include <deque>
#include <iostream>
#include <set>
#include <vector>

namespace {

using vdbrad::kPi;

namespace vg = vdbrad::grids;
using openvdb::Coord;
using openvdb::CoordBBox;
using openvdb::FloatGrid;
using openvdb::Vec3d;
using openvdb::Vec3f;
using openvdb::Vec3SGrid;


class VdbEnvironment : public ::testing::Environment
{
public:
    void SetUp() override { openvdb::initialize(); }
};
const auto* const gEnv = ::testing::AddGlobalTestEnvironment(new VdbEnvironment);

template<typename GridT>
typename GridT::Ptr
grid(const openvdb::GridPtrVec& grids, const std::string& name)
{
    for (const auto& g : grids) {
        if (g && g->getName() == name) return openvdb::gridPtrCast<GridT>(g);
    }
    return nullptr;
}

vg::BuildParams
withRes(int res)
{
    vg::BuildParams p;
    p.res = res;
    return p;
}

/// Active voxels of a grid (the builders store voxels, not tiles; a tile would show up here as
/// a count mismatch).
template<typename GridT>
std::set<Coord>
activeSet(const GridT& g)
{
    std::set<Coord> s;
    for (auto it = g.cbeginValueOn(); it; ++it) {
        EXPECT_TRUE(it.isVoxelValue());
        s.insert(it.getCoord());
    }
    return s;
}

/// The three surface grids, checked for the scene contract shared by every surface scene.
struct SurfaceScene
{
    Vec3SGrid::Ptr normal;
    openvdb::GridBase::Ptr albedo;
    FloatGrid::Ptr emission;
};

SurfaceScene
checkSurface(const openvdb::GridPtrVec& grids, const std::string& scene)
{
    SurfaceScene s;
    EXPECT_EQ(grids.size(), 3u);
    s.normal = grid<Vec3SGrid>(grids, "normal");
    s.emission = grid<FloatGrid>(grids, "emission");
    for (const auto& g : grids) {
        if (g->getName() == "albedo") s.albedo = g;
    }
    EXPECT_TRUE(s.normal && s.albedo && s.emission);
    if (!s.normal || !s.albedo || !s.emission) return s;
    EXPECT_EQ(s.normal->getVectorType(), openvdb::VEC_COVARIANT_NORMALIZE);
    EXPECT_EQ(s.normal->getGridClass(), openvdb::GRID_UNKNOWN);
    EXPECT_EQ(s.normal->background(), Vec3f(0.f));
    for (const auto& g : grids) {
        EXPECT_EQ(g->metaValue<std::string>("vdbrad:scene"), scene);
        EXPECT_EQ(g->transform(), s.normal->transform());
    }
    EXPECT_TRUE(s.normal->tree().hasSameTopology(s.emission->tree()));
    if (auto a = openvdb::gridPtrCast<FloatGrid>(s.albedo)) {
        EXPECT_TRUE(s.normal->tree().hasSameTopology(a->tree()));
    } else if (auto a3 = openvdb::gridPtrCast<Vec3SGrid>(s.albedo)) {
        EXPECT_TRUE(s.normal->tree().hasSameTopology(a3->tree()));
    } else {
        ADD_FAILURE() << "albedo is neither float nor Vec3f";
    }
    return s;
}

/// Voxel centre in world space through the grid's own transform.
Vec3d
centre(const openvdb::GridBase& g, const Coord& ijk)
{
    return g.indexToWorld(ijk);
}

/// Flood fill from @a seed through voxels not in @a shell (26-connected), bounded by the shell's
/// bbox grown by one voxel. Returns the visited voxels; escaping the shell's bbox is a leak.
std::vector<Coord>
floodFill(const std::set<Coord>& shell, const Coord& seed, bool& leaked)
{
    CoordBBox box;
    for (const Coord& c : shell) box.expand(c);
    CoordBBox grown = box;
    grown.expand(1);
    leaked = false;
    std::set<Coord> seen{seed};
    std::deque<Coord> todo{seed};
    std::vector<Coord> visited;
    while (!todo.empty()) {
        const Coord c = todo.front();
        todo.pop_front();
        visited.push_back(c);
        if (!box.isInside(c)) leaked = true;
        for (int di = -1; di <= 1; ++di) {
            for (int dj = -1; dj <= 1; ++dj) {
                for (int dk = -1; dk <= 1; ++dk) {
                    const Coord n = c.offsetBy(di, dj, dk);
                    if (!grown.isInside(n) || shell.count(n) || seen.count(n)) continue;
                    seen.insert(n);
                    todo.push_back(n);
                }
            }
        }
    }
    return visited;
}

// ---- builder list ------------------------------------------------------------------------------

TEST(Builders, ListNamesDocsAndContract)
{
    const std::vector<std::string> names{
        "furnace-box", "furnace-sphere", "disk", "plates", "lamp", "cornell", "slab", "cumulus",
        "step-cloud"};
    const auto& all = vg::builders();
    ASSERT_EQ(all.size(), names.size());
    for (std::size_t b = 0; b < names.size(); ++b) {
        EXPECT_EQ(all[b].name, names[b]);
        EXPECT_FALSE(all[b].doc.empty());
        EXPECT_EQ(all[b].doc.find('\n'), std::string::npos) << "doc must be one line";
        ASSERT_EQ(vg::findBuilder(names[b]), &all[b]);
        // The step cloud's 32 columns need a multiple of 32 voxels.
        const auto grids = all[b].build(withRes(names[b] == "step-cloud" ? 32 : 16));
        if (names[b] == "slab" || names[b] == "cumulus" || names[b] == "step-cloud") {
            ASSERT_EQ(grids.size(), 2u);
            auto density = grid<FloatGrid>(grids, "density");
            auto albedo = grid<FloatGrid>(grids, "albedo");
            ASSERT_TRUE(density && albedo);
            EXPECT_EQ(density->getGridClass(), openvdb::GRID_FOG_VOLUME);
            EXPECT_EQ(density->background(), 0.f);
            EXPECT_TRUE(density->tree().hasSameTopology(albedo->tree()));
            EXPECT_EQ(density->transform(), albedo->transform());
            EXPECT_EQ(density->metaValue<std::string>("vdbrad:scene"), names[b]);
            EXPECT_GT(density->activeVoxelCount(), 0u);
        } else {
            checkSurface(grids, names[b]);
        }
        // Voxel (0,0,0) is the cell [0, vs]^3: its centre is at vs/2 on every axis.
        const double vs = grids[0]->voxelSize()[0];
        EXPECT_NEAR((centre(*grids[0], Coord(0)) - Vec3d(vs / 2)).length(), 0.0, 1e-15);
    }
    EXPECT_EQ(vg::findBuilder("no-such-scene"), nullptr);
}

// ---- furnace box -------------------------------------------------------------------------------

TEST(FurnaceBox, ShellNormalsAndValues)
{
    for (int res : {16, 17}) {
        const auto s = checkSurface(vg::makeFurnaceBox(withRes(res)), "furnace-box");
        ASSERT_TRUE(s.normal);
        // Shell of a res^3 cube: exact integer count.
        EXPECT_EQ(s.normal->activeVoxelCount(),
            openvdb::Index64(res * res * res - (res - 2) * (res - 2) * (res - 2)));
        EXPECT_NEAR(s.normal->voxelSize()[0], 1.0 / res, 1e-15);
        const Vec3d mid(0.5);
        for (auto it = s.normal->cbeginValueOn(); it; ++it) {
            const Coord c = it.getCoord();
            for (int a = 0; a < 3; ++a) {
                ASSERT_TRUE(c[a] >= 0 && c[a] < res);
            }
            const Vec3d n(*it);
            EXPECT_NEAR(n.length(), 1.0, 1e-6);
            EXPECT_GT(n.dot(mid - centre(*s.normal, c)), 0.0) << c;
        }
        auto albedo = openvdb::gridPtrCast<FloatGrid>(s.albedo);
        ASSERT_TRUE(albedo);
        for (auto it = albedo->cbeginValueOn(); it; ++it) ASSERT_EQ(*it, 0.5f);   // default rho
        for (auto it = s.emission->cbeginValueOn(); it; ++it) ASSERT_EQ(*it, 1.f); // default E
    }
    // Non-default values reach every voxel.
    vg::BuildParams p = withRes(8);
    p.albedo = 0.8f;
    p.emission = 3.f;
    const auto s = checkSurface(vg::makeFurnaceBox(p), "furnace-box");
    for (auto it = openvdb::gridPtrCast<FloatGrid>(s.albedo)->cbeginValueOn(); it; ++it) {
        ASSERT_EQ(*it, 0.8f);
    }
    for (auto it = s.emission->cbeginValueOn(); it; ++it) ASSERT_EQ(*it, 3.f);
}

TEST(Furnace, ShellsAreClosed)
{
    const int res = 20;
    for (const std::string scene : {"furnace-box", "furnace-sphere"}) {
        const auto grids = vg::findBuilder(scene)->build(withRes(res));
        const auto shell = activeSet(*grid<Vec3SGrid>(grids, "normal"));
        const Coord seed(res / 2);
        ASSERT_EQ(shell.count(seed), 0u);
        bool leaked = true;
        const auto inside = floodFill(shell, seed, leaked);
        EXPECT_FALSE(leaked) << scene << ": a 26-connected path crosses the shell";
        if (scene == "furnace-box") {
            // The enclosed voxels are exactly the (res-2)^3 interior.
            EXPECT_EQ(inside.size(), std::size_t((res - 2) * (res - 2) * (res - 2)));
        } else {
            // ...and for the sphere exactly the voxels whose centre is strictly inside.
            std::size_t strict = 0;
            for (int i = 0; i < res; ++i) {
                for (int j = 0; j < res; ++j) {
                    for (int k = 0; k < res; ++k) {
                        const Vec3d c = (Vec3d(i, j, k) + Vec3d(0.5)) / res - Vec3d(0.5);
                        strict += c.length() < 0.5;
                    }
                }
            }
            EXPECT_EQ(inside.size(), strict);
        }
    }
}

// ---- furnace sphere ----------------------------------------------------------------------------

TEST(FurnaceSphere, ShellIsExactlyTheRule)
{
    for (int res : {20, 21}) {
        const auto s = checkSurface(vg::makeFurnaceSphere(withRes(res)), "furnace-sphere");
        ASSERT_TRUE(s.normal);
        const Vec3d c0(0.5);
        // The header's rule, in world space through the grid's transform.
        auto inside = [&](const Coord& ijk) {
            return (centre(*s.normal, ijk) - c0).length() < 0.5;
        };
        auto rule = [&](const Coord& ijk) {
            if (inside(ijk)) return false;
            for (int di = -1; di <= 1; ++di) {
                for (int dj = -1; dj <= 1; ++dj) {
                    for (int dk = -1; dk <= 1; ++dk) {
                        if (inside(ijk.offsetBy(di, dj, dk))) return true;
                    }
                }
            }
            return false;
        };
        const auto shell = activeSet(*s.normal);
        for (const Coord& c : shell) {
            EXPECT_TRUE(rule(c)) << c;
            const Vec3d n(s.normal->tree().getValue(c));
            const Vec3d toCentre = (c0 - centre(*s.normal, c)).unit();
            EXPECT_NEAR((n - toCentre).length(), 0.0, 1e-5) << c;   // float normals: ~1e-7
        }
        // Brute force over a box well beyond the sphere: nothing that obeys the rule is missing.
        std::size_t ruleCount = 0;
        for (int i = -3; i < res + 3; ++i) {
            for (int j = -3; j < res + 3; ++j) {
                for (int k = -3; k < res + 3; ++k) {
                    if (!rule(Coord(i, j, k))) continue;
                    ++ruleCount;
                    EXPECT_TRUE(shell.count(Coord(i, j, k))) << Coord(i, j, k);
                }
            }
        }
        EXPECT_EQ(ruleCount, shell.size());
        std::cout << "furnace-sphere res " << res << ": " << shell.size() << " voxels\n";
        for (auto it = openvdb::gridPtrCast<FloatGrid>(s.albedo)->cbeginValueOn(); it; ++it) {
            ASSERT_EQ(*it, 0.5f);
        }
        for (auto it = s.emission->cbeginValueOn(); it; ++it) ASSERT_EQ(*it, 1.f);
    }
}

// ---- disk and plates ---------------------------------------------------------------------------

struct Layers
{
    std::size_t emitters = 0, receivers = 0;
};

/// Checks the two one-voxel layers of the disk and plates scenes: emitter at y = 0 (normal +y,
/// albedo 0, emission E) and receiver at y = top (normal -y, albedo 1, emission 0).
Layers
checkLayers(const SurfaceScene& s, int res, int top, float E)
{
    Layers l;
    auto albedo = openvdb::gridPtrCast<FloatGrid>(s.albedo);
    EXPECT_TRUE(albedo);
    if (!albedo) return l;
    auto emission = s.emission->getConstAccessor();
    auto alb = albedo->getConstAccessor();
    for (auto it = s.normal->cbeginValueOn(); it; ++it) {
        const Coord c = it.getCoord();
        EXPECT_TRUE(c.x() >= 0 && c.x() < res && c.z() >= 0 && c.z() < res) << c;
        if (c.y() == 0) {
            ++l.emitters;
            EXPECT_EQ(*it, Vec3f(0, 1, 0));
            EXPECT_EQ(alb.getValue(c), 0.f);
            EXPECT_EQ(emission.getValue(c), E);
        } else {
            EXPECT_EQ(c.y(), top);
            ++l.receivers;
            EXPECT_EQ(*it, Vec3f(0, -1, 0));
            EXPECT_EQ(alb.getValue(c), 1.f);
            EXPECT_EQ(emission.getValue(c), 0.f);
        }
    }
    return l;
}

TEST(Disk, LayersAndCounts)
{
    const int res = 64;
    const auto s = checkSurface(vg::makeDisk(withRes(res)), "disk");
    ASSERT_TRUE(s.normal);
    // Defaults r = h = 0.25: receiver at layer 0.25 * 64 = 16.
    const Layers l = checkLayers(s, res, 16, 1.f);
    EXPECT_EQ(l.receivers, std::size_t(res * res));
    const double vs = 1.0 / res, area = kPi * 0.25 * 0.25 / (vs * vs);   // 804.2 voxels
    EXPECT_NEAR(double(l.emitters) / area, 1.0, 0.03);
    std::cout << "disk res 64: " << l.emitters << " emitter voxels (pi r^2/vs^2 = " << area
              << "), " << l.receivers << " receiver voxels\n";
    // Every disk voxel centre is within r of the axis x = z = 0.5.
    for (auto it = s.emission->cbeginValueOn(); it; ++it) {
        if (it.getCoord().y() != 0) continue;
        const Vec3d c = centre(*s.emission, it.getCoord());
        EXPECT_LE(std::hypot(c.x() - 0.5, c.z() - 0.5), 0.25 + 1e-12);
    }

    // Non-default geometry: h = 0.3 -> layer round(0.3 * 32) = 10 (9.6 rounds up).
    vg::BuildParams p = withRes(32);
    p.height = 0.3f;
    p.radius = 0.4f;
    p.emission = 2.f;
    const auto s2 = checkSurface(vg::makeDisk(p), "disk");
    const Layers l2 = checkLayers(s2, 32, 10, 2.f);
    EXPECT_NEAR(double(l2.emitters) / (kPi * 0.4 * 0.4 * 32 * 32), 1.0, 0.03);
}

TEST(Plates, LayersAndCounts)
{
    for (int res : {32, 33}) {
        const auto s = checkSurface(vg::makePlates(withRes(res)), "plates");
        ASSERT_TRUE(s.normal);
        const int top = int(std::lround(0.5 * res));   // default h = 0.5
        const Layers l = checkLayers(s, res, top, 1.f);
        EXPECT_EQ(s.normal->activeVoxelCount(), openvdb::Index64(2 * res * res));
        EXPECT_EQ(l.emitters, std::size_t(res * res));
        EXPECT_EQ(l.receivers, std::size_t(res * res));
    }
}

// ---- exact answers -----------------------------------------------------------------------------

/// Irradiance from a disk (radiosity E, radius r) at a point at distance h, offset a from the
/// axis: midpoint rule in polar coordinates of the kernel cos cos / (pi d^2) = h^2 / (pi d^4).
double
diskQuadrature(double E, double r, double h, double a, int n)
{
    double sum = 0.0;
    const double dr = r / n, dphi = 2 * kPi / n;
    for (int ir = 0; ir < n; ++ir) {
        const double rho = (ir + 0.5) * dr;
        for (int ip = 0; ip < n; ++ip) {
            const double phi = (ip + 0.5) * dphi;
            const double dx = rho * std::cos(phi) - a, dz = rho * std::sin(phi);
            const double d2 = dx * dx + dz * dz + h * h;
            sum += h * h / (kPi * d2 * d2) * rho;
        }
    }
    return E * sum * dr * dphi;
}

/// Factor from a point at the origin to the parallel rectangle at distance h: midpoint rule.
double
rectangleQuadrature(double x0, double x1, double z0, double z1, double h, int n)
{
    double sum = 0.0;
    const double dx = (x1 - x0) / n, dz = (z1 - z0) / n;
    for (int i = 0; i < n; ++i) {
        const double x = x0 + (i + 0.5) * dx;
        for (int k = 0; k < n; ++k) {
            const double z = z0 + (k + 0.5) * dz;
            const double d2 = x * x + z * z + h * h;
            sum += h * h / (kPi * d2 * d2);
        }
    }
    return sum * dx * dz;
}

/// View factor between directly opposed squares of side w at distance h: 4D midpoint rule over
/// both squares, F = 1/A1 * integral of h^2 / (pi d^4).
double
squaresQuadrature(double w, double h, int n)
{
    const double d = w / n;
    std::vector<double> x(n);
    for (int i = 0; i < n; ++i) x[i] = (i + 0.5) * d;
    double sum = 0.0;
    for (int i1 = 0; i1 < n; ++i1) {
        for (int k1 = 0; k1 < n; ++k1) {
            for (int i2 = 0; i2 < n; ++i2) {
                const double dx = x[i1] - x[i2];
                for (int k2 = 0; k2 < n; ++k2) {
                    const double dz = x[k1] - x[k2];
                    const double d2 = dx * dx + dz * dz + h * h;
                    sum += h * h / (kPi * d2 * d2);
                }
            }
        }
    }
    return sum * d * d * d * d / (w * w);
}

TEST(ExactAnswers, DiskIrradianceOnAxis)
{
    // On the axis B-13 reduces to E r^2 / (r^2 + h^2) (the disk's solid-angle form).
    for (double r : {0.1, 0.25, 1.0}) {
        for (double h : {0.05, 0.25, 2.0}) {
            EXPECT_NEAR(vg::diskIrradiance(3.0, r, h, 0.0), 3.0 * r * r / (r * r + h * h), 1e-12);
        }
    }
    EXPECT_NEAR(vg::diskIrradiance(1.0, 0.25, 0.25, 0.0), 0.5, 1e-12);   // the disk scene's axis
}

TEST(ExactAnswers, DiskIrradianceOffAxisMatchesQuadrature)
{
    // a < r, a = r (above the rim) and a > r (outside the disk's shadow).
    for (double a : {0.1, 0.25, 0.4, 1.0}) {
        const double exact = vg::diskIrradiance(1.0, 0.25, 0.25, a);
        const double quad = diskQuadrature(1.0, 0.25, 0.25, a, 1500);
        EXPECT_NEAR(exact / quad, 1.0, 1e-5) << "a = " << a;   // midpoint error ~1e-7 here
        std::cout << "diskIrradiance a=" << a << ": exact " << exact << ", quadrature rel err "
                  << exact / quad - 1 << "\n";
    }
}

TEST(ExactAnswers, RectangleFactorMatchesQuadrature)
{
    struct Case { double x0, x1, z0, z1, h; };
    const Case cases[] = {
        {0.0, 1.0, 0.0, 0.5, 0.5},      // corner at the foot: plain B-3
        {-0.3, 0.7, -0.4, 0.6, 0.5},    // foot inside
        {0.2, 0.9, 0.1, 0.6, 0.3},      // foot outside, diagonal quadrant
        {-0.5, 0.5, 0.3, 1.2, 0.8},     // foot outside, beside one edge
        {-1.5, -0.5, -2.0, -1.0, 1.0},  // foot outside, negative quadrant
    };
    for (const Case& c : cases) {
        const double exact = vg::rectangleFactor(c.x0, c.x1, c.z0, c.z1, c.h);
        const double quad = rectangleQuadrature(c.x0, c.x1, c.z0, c.z1, c.h, 1500);
        EXPECT_NEAR(exact / quad, 1.0, 1e-5);   // midpoint error ~1e-6 at most here
        std::cout << "rectangleFactor [" << c.x0 << "," << c.x1 << "]x[" << c.z0 << "," << c.z1
                  << "] h=" << c.h << ": " << exact << ", rel err " << exact / quad - 1 << "\n";
    }
    // B-3 by itself: unit square corner at distance 1 is 0.13853 (Howell's tables).
    EXPECT_NEAR(vg::rectangleFactor(0, 1, 0, 1, 1), 0.13853, 1e-5);
}

TEST(ExactAnswers, ParallelSquaresMatchTextbookAndQuadrature)
{
    // Textbook value for X = Y = 1 (Howell's C-11 table; also Incropera's chart): 0.19982.
    EXPECT_NEAR(vg::parallelSquaresViewFactor(1, 1), 0.19982, 1e-5);
    // Scale invariance: only w/h matters.
    EXPECT_NEAR(vg::parallelSquaresViewFactor(2, 2), vg::parallelSquaresViewFactor(1, 1), 1e-14);
    for (double h : {1.0, 0.5}) {
        // 4D midpoint, Richardson-extrapolated from n and n/2 (the midpoint error is O(1/n^2)).
        const double fine = squaresQuadrature(1, h, 40), coarse = squaresQuadrature(1, h, 20);
        const double quad = (4 * fine - coarse) / 3;
        const double exact = vg::parallelSquaresViewFactor(1, h);
        // Extrapolated error is ~1e-6 here; unextrapolated (n = 40) ~3e-4.
        EXPECT_NEAR(exact / quad, 1.0, 1e-5) << "h = " << h;
        std::cout << "parallelSquaresViewFactor(1," << h << ") = " << exact
                  << ", quadrature rel err " << exact / quad - 1 << " (unextrapolated "
                  << exact / fine - 1 << ")\n";
    }
    // The plate scene's two answers agree: mean over the receiver of the point factor.
    const int n = 200;
    double mean = 0.0;
    for (int i = 0; i < n; ++i) {
        for (int k = 0; k < n; ++k) {
            const double x = (i + 0.5) / n, z = (k + 0.5) / n;
            mean += vg::rectangleFactor(-x, 1 - x, -z, 1 - z, 0.5);
        }
    }
    EXPECT_NEAR(mean / (n * n) / vg::parallelSquaresViewFactor(1, 0.5), 1.0, 1e-4);
}

// ---- Cornell box -------------------------------------------------------------------------------

/// The room's air, re-derived from the brief's corner lists: inside the room box, outside both
/// blocks (convex quadrilaterals in x, z extruded from y = 0 to their tops).
struct CornellAir
{
    using Quad = std::array<std::array<double, 2>, 4>;
    static bool inQuad(const Quad& q, double x, double z)
    {
        // Convex: the point is inside iff it is on the same side of all four edges.
        int pos = 0, neg = 0;
        for (int e = 0; e < 4; ++e) {
            const auto &a = q[e], &b = q[(e + 1) % 4];
            const double cross = (b[0] - a[0]) * (z - a[1]) - (b[1] - a[1]) * (x - a[0]);
            pos += cross >= 0;
            neg += cross <= 0;
        }
        return pos == 4 || neg == 4;
    }
    bool operator()(const Vec3d& p) const
    {
        static const Quad shortQ{{{0.130, 0.065}, {0.082, 0.225}, {0.240, 0.272}, {0.290, 0.114}}};
        static const Quad tallQ{{{0.423, 0.247}, {0.265, 0.296}, {0.314, 0.456}, {0.472, 0.406}}};
        if (!(p.x() > 0 && p.x() < 0.556 && p.y() > 0 && p.y() < 0.5488 && p.z() > 0 &&
                p.z() < 0.5592)) {
            return false;
        }
        if (p.y() <= 0.165 && inQuad(shortQ, p.x(), p.z())) return false;
        if (p.y() <= 0.330 && inQuad(tallQ, p.x(), p.z())) return false;
        return true;
    }
};

TEST(Cornell, GeometryColoursAndLight)
{
    const int res = 128;
    const auto s = checkSurface(vg::makeCornell(withRes(res)), "cornell");
    ASSERT_TRUE(s.normal);
    auto albedo = openvdb::gridPtrCast<Vec3SGrid>(s.albedo);
    ASSERT_TRUE(albedo) << "the Cornell box's albedo is RGB";
    EXPECT_EQ(albedo->getVectorType(), openvdb::VEC_INVARIANT);
    const double vs = 0.5592 / res;   // z is the longest axis
    EXPECT_NEAR(s.normal->voxelSize()[0], vs, 1e-15);

    const CornellAir air;
    auto alb = albedo->getConstAccessor();
    auto em = s.emission->getConstAccessor();
    const int iRed = int(std::floor(0.556 / vs - 0.5)) + 1;      // first x index past the room
    const int jCeil = int(std::floor(0.5488 / vs - 0.5)) + 1;    // first y index past the room
    const Vec3f white(0.73f), red(0.63f, 0.065f, 0.05f), green(0.14f, 0.45f, 0.091f);
    std::size_t count = 0, intoAir = 0, farIntoAir = 0, lights = 0, redCount = 0, greenCount = 0;
    for (auto it = s.normal->cbeginValueOn(); it; ++it) {
        const Coord c = it.getCoord();
        const Vec3d p = centre(*s.normal, c), n(*it);
        ++count;
        EXPECT_FALSE(air(p)) << "surface voxel centred in the air: " << c;
        EXPECT_GT(p.z(), 0.0) << "the front is open";
        EXPECT_NEAR(n.length(), 1.0, 1e-6);
        // Into the air: one voxel along the normal, or the 26-neighbour in the normal's octant
        // (axes where |n| > 0.25). The blocks are turned ~17 degrees, so their stair-stepped faces
        // hold voxels up to sqrt(2) voxels deep that see the air only diagonally.
        Coord step(0);
        for (int a = 0; a < 3; ++a) step[a] = n[a] > 0.25 ? 1 : (n[a] < -0.25 ? -1 : 0);
        if (air(p + vs * n) || air(centre(*s.normal, c + step))) ++intoAir;
        // A voxel with an air 26-neighbour is at most sqrt(3) voxels inside a flat face, so
        // 1.75 voxels along a correct normal always lands in the air.
        if (air(p + 1.75 * vs * n)) ++farIntoAir;
        // Walls away from edges and blocks have pure axis normals and their wall's colour.
        if (c.x() == iRed && Vec3d(n) == Vec3d(-1, 0, 0)) {
            ++redCount;
            EXPECT_EQ(alb.getValue(c), red) << c;
        }
        if (c.x() == -1 && Vec3d(n) == Vec3d(1, 0, 0)) {
            ++greenCount;
            EXPECT_EQ(alb.getValue(c), green) << c;
        }
        if (c.y() == -1 && Vec3d(n) == Vec3d(0, 1, 0)) {
            EXPECT_EQ(alb.getValue(c), white) << c;
        }
        const float e = em.getValue(c);
        if (e != 0.f) {
            ++lights;
            EXPECT_EQ(e, 1.f);
            EXPECT_EQ(c.y(), jCeil) << "emitters sit on the ceiling layer only";
            EXPECT_TRUE(p.x() >= 0.213 && p.x() <= 0.343 && p.z() >= 0.227 && p.z() <= 0.332);
        }
    }
    EXPECT_GE(double(intoAir) / count, 0.99);
    EXPECT_EQ(farIntoAir, count);
    // Nearly a full wall each (the walls are 125.6 x 128 voxels).
    EXPECT_GT(redCount, std::size_t(0.9 * 125 * 127));
    EXPECT_GT(greenCount, std::size_t(0.9 * 125 * 127));
    // Light area 0.130 x 0.105 m^2 in voxels: 715.2 at res 128.
    const double lightArea = 0.130 * 0.105 / (vs * vs);
    EXPECT_NEAR(lights / lightArea, 1.0, 0.05);
    std::cout << "cornell res 128: " << count << " surface voxels, " << lights
              << " light voxels (area " << lightArea << "), normals into air "
              << 100.0 * intoAir / count << "% (1 voxel / octant neighbour), "
              << 100.0 * farIntoAir / count << "% (1.75 voxels)\n";
}

TEST(Cornell, SurfaceIsExactlyTheRuleAtLowRes)
{
    // Brute force over the whole room: a voxel is a surface voxel iff its centre is not air, lies
    // at z > 0 (no front wall) and a 26-neighbour's centre is air.
    for (int res : {40, 57}) {
        const auto s = checkSurface(vg::makeCornell(withRes(res)), "cornell");
        ASSERT_TRUE(s.normal);
        const CornellAir air;
        const auto shell = activeSet(*s.normal);
        std::size_t ruleCount = 0;
        for (int i = -3; i < res + 3; ++i) {
            for (int j = -3; j < res + 3; ++j) {
                for (int k = -3; k < res + 3; ++k) {
                    const Coord c(i, j, k);
                    const Vec3d p = centre(*s.normal, c);
                    bool rule = !air(p) && p.z() > 0;
                    if (rule) {
                        rule = false;
                        for (int d = 0; d < 27 && !rule; ++d) {
                            const Coord n = c.offsetBy(d % 3 - 1, d / 3 % 3 - 1, d / 9 - 1);
                            rule = air(centre(*s.normal, n));
                        }
                    }
                    ruleCount += rule;
                    EXPECT_EQ(rule, shell.count(c) == 1) << c;
                }
            }
        }
        EXPECT_EQ(ruleCount, shell.size());
    }
}

TEST(Cornell, ShellGrowsAsASurfaceUpToRes256)
{
    // The scene is a thin shell of surface voxels, so what the solver and the tests pay grows with
    // res², not res³. Checked by counting, not timing (the build time is measured by
    // benchmarks/bench_grids.cc, docs/journal/2026-12-03-canonical-scenes.md): doubling the
    // resolution quadruples the surface voxels (a volume would grow 8×; the walls' O(res) edges and
    // the blocks' rounding keep it within 2% of 4), and the shell stays under 8 res² voxels (five
    // walls of about res² each, the two blocks and the edges: 6.26-6.31 res² at res 64 to 256).
    std::size_t previous = 0;
    for (int res : {64, 128, 256}) {
        const auto normal = grid<Vec3SGrid>(vg::makeCornell(withRes(res)), "normal");
        ASSERT_TRUE(normal);
        const std::size_t count = normal->activeVoxelCount();
        if (previous > 0) {
            EXPECT_NEAR(double(count) / double(previous), 4.0, 0.08) << "res " << res;
        }
        previous = count;
        EXPECT_LT(double(count), 8.0 * res * res) << "res " << res;
    }
}

// ---- clouds ------------------------------------------------------------------------------------

TEST(Slab, EveryColumnHasOpticalThicknessTau)
{
    for (int res : {32, 30}) {
        vg::BuildParams p = withRes(res);
        p.tau = 7.f;
        const auto grids = vg::makeSlab(p);
        auto density = grid<FloatGrid>(grids, "density");
        auto albedo = grid<FloatGrid>(grids, "albedo");
        ASSERT_TRUE(density && albedo);
        const int ny = std::max(1, int(std::lround(res / 4.0)));   // 30 -> 8 (7.5 rounds up)
        EXPECT_EQ(density->activeVoxelCount(), openvdb::Index64(res * ny * res));
        const double vs = density->voxelSize()[0];
        EXPECT_NEAR(vs, 1.0 / res, 1e-15);
        auto acc = density->getConstAccessor();
        for (int i = 0; i < res; ++i) {
            for (int k = 0; k < res; ++k) {
                double path = 0.0;
                for (int j = -1; j <= ny; ++j) path += acc.getValue(Coord(i, j, k)) * vs;
                ASSERT_NEAR(path / 7.0, 1.0, 1e-5);   // float density: ~1e-7
            }
        }
        for (auto it = albedo->cbeginValueOn(); it; ++it) ASSERT_EQ(*it, 1.f);   // default omega
    }
}

TEST(Cumulus, DeterministicFiniteAndScaled)
{
    const int res = 64;
    auto build = [&](unsigned seed, float tau) {
        vg::BuildParams p = withRes(res);
        p.seed = seed;
        p.tau = tau;
        return grid<FloatGrid>(vg::makeCumulus(p), "density");
    };
    const auto a = build(1, -1.f), b = build(1, -1.f), c = build(2, -1.f);
    ASSERT_TRUE(a && b && c);
    // Same seed: identical voxel for voxel.
    ASSERT_TRUE(a->tree().hasSameTopology(b->tree()));
    auto bAcc = b->getConstAccessor();
    for (auto it = a->cbeginValueOn(); it; ++it) ASSERT_EQ(*it, bAcc.getValue(it.getCoord()));
    // Another seed: another cloud.
    bool differs = !a->tree().hasSameTopology(c->tree());
    auto cAcc = c->getConstAccessor();
    for (auto it = a->cbeginValueOn(); it && !differs; ++it) {
        differs = *it != cAcc.getValue(it.getCoord());
    }
    EXPECT_TRUE(differs);

    for (const auto& g : {a, c}) {
        EXPECT_GT(g->activeVoxelCount(), openvdb::Index64(res * res * res / 50));
        for (auto it = g->cbeginValueOn(); it; ++it) {
            ASSERT_TRUE(std::isfinite(*it) && *it > 0.f);
            for (int ax = 0; ax < 3; ++ax) {
                ASSERT_TRUE(it.getCoord()[ax] >= 0 && it.getCoord()[ax] < res);
            }
        }
        // Default tau = 20 along the centre column (index res/2, res/2), summed density * vs.
        auto acc = g->getConstAccessor();
        double path = 0.0;
        for (int j = 0; j < res; ++j) path += acc.getValue(Coord(res / 2, j, res / 2)) / res;
        EXPECT_NEAR(path / 20.0, 1.0, 1e-3);
    }
    const auto d = build(3, 5.f);
    auto acc = d->getConstAccessor();
    double path = 0.0;
    for (int j = 0; j < res; ++j) path += acc.getValue(Coord(res / 2, j, res / 2)) / res;
    EXPECT_NEAR(path / 5.0, 1.0, 1e-3);
    std::cout << "cumulus res 64: seed 1 " << a->activeVoxelCount() << " voxels, seed 2 "
              << c->activeVoxelCount() << " voxels\n";
}

// ---- parameter validation ----------------------------------------------------------------------

TEST(StepCloud, ColumnsHaveTheirOpticalThickness)
{
    // I3RC's step cloud: 16 columns of 2 then 16 of 18 over 0.5 km, 0.25 km thick.
    for (int res : {32, 64}) {
        vg::BuildParams p = withRes(res);
        const auto grids = vg::makeStepCloud(p);
        auto density = grid<FloatGrid>(grids, "density");
        ASSERT_TRUE(density);
        EXPECT_EQ(density->activeVoxelCount(), openvdb::Index64(res * (res / 2)));
        const double vs = density->voxelSize()[0];
        EXPECT_NEAR(vs, 0.5 / res, 1e-15);
        EXPECT_NEAR(vs * (res / 2), 0.25, 1e-15);
        auto acc = density->getConstAccessor();
        for (int i = 0; i < res; ++i) {
            double path = 0.0;
            for (int j = -1; j <= res / 2; ++j) path += acc.getValue(Coord(i, j, 0)) * vs;
            ASSERT_NEAR(path / (i < res / 2 ? 2.0 : 18.0), 1.0, 1e-5) << i;
            EXPECT_EQ(acc.getValue(Coord(i, 0, 1)), 0.f);   // one voxel deep
        }
    }
}

TEST(Params, BadValuesThrow)
{
    auto throws = [](const std::string& scene, auto edit) {
        vg::BuildParams p = withRes(scene == "step-cloud" ? 32 : 16);
        edit(p);
        EXPECT_THROW(vg::findBuilder(scene)->build(p), openvdb::ValueError) << scene;
    };
    for (const auto& b : vg::builders()) {
        throws(b.name, [](vg::BuildParams& p) { p.res = 0; });
        throws(b.name, [](vg::BuildParams& p) { p.res = 4097; });
        throws(b.name, [](vg::BuildParams& p) { p.albedo = 1.5f; });
        throws(b.name, [](vg::BuildParams& p) { p.albedo = std::nanf(""); });
        throws(b.name, [](vg::BuildParams& p) { p.emission = INFINITY; });
        throws(b.name, [](vg::BuildParams& p) { p.emission = std::nanf(""); });
    }
    throws("furnace-box", [](vg::BuildParams& p) { p.res = 2; });   // no interior
    throws("disk", [](vg::BuildParams& p) { p.radius = 0.f; });
    throws("disk", [](vg::BuildParams& p) { p.radius = 0.6f; });    // wider than the receiver
    throws("disk", [](vg::BuildParams& p) { p.radius = 0.01f; });   // covers no voxel at res 16
    throws("disk", [](vg::BuildParams& p) { p.height = 0.f; });
    throws("disk", [](vg::BuildParams& p) { p.height = 0.02f; });   // rounds to layer 0
    throws("plates", [](vg::BuildParams& p) { p.height = 0.f; });
    throws("slab", [](vg::BuildParams& p) { p.tau = 0.f; });
    throws("cumulus", [](vg::BuildParams& p) { p.tau = 0.f; });
    throws("step-cloud", [](vg::BuildParams& p) { p.tau = 0.f; });
    throws("step-cloud", [](vg::BuildParams& p) { p.res = 48; });   // not a multiple of 32
    EXPECT_THROW(vg::diskIrradiance(1, 1, 0, 0), openvdb::ValueError);
    EXPECT_THROW(vg::rectangleFactor(0, 1, 0, 1, 0), openvdb::ValueError);
    EXPECT_THROW(vg::parallelSquaresViewFactor(0, 1), openvdb::ValueError);
    // Negative values select the defaults rather than fail.
    vg::BuildParams p = withRes(16);
    p.albedo = -3.f;
    p.emission = -2.f;
    EXPECT_NO_THROW(vg::makeFurnaceBox(p));
}

} // namespace
