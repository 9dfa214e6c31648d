// The scene contract in memory: VoxelIndex, Scene (level set and normal-grid surfaces), Cloud,
// and the output grids written back from per-voxel arrays.
#include "vdbrad/vdbrad.h"

#include <openvdb/tools/LevelSetSphere.h>

#include <gtest/gtest.h>

#include <cmath>
#include <random>

using namespace vdbrad;
using openvdb::Coord;
using openvdb::Vec3f;

namespace {

class SceneTest : public ::testing::Test
{
protected:
    static void SetUpTestSuite() { openvdb::initialize(); }
};

openvdb::Vec3SGrid::Ptr
normalGrid(const std::vector<std::pair<Coord, Vec3f>>& voxels, double voxelSize = 0.1)
{
    auto g = openvdb::Vec3SGrid::create(Vec3f(0.f));
    g->setName("normal");
    g->setTransform(openvdb::math::Transform::createLinearTransform(voxelSize));
    auto acc = g->getAccessor();
    for (const auto& [c, n] : voxels) acc.setValueOn(c, n);
    return g;
}

template<typename GridT>
typename GridT::Ptr
attributeGrid(const std::string& name, const openvdb::GridBase& like,
    typename GridT::ValueType value)
{
    auto g = GridT::create(openvdb::zeroVal<typename GridT::ValueType>());
    g->setName(name);
    g->setTransform(like.transform().copy());
    auto acc = g->getAccessor();
    auto mask = openvdb::MaskTree(static_cast<const openvdb::Vec3SGrid&>(like).tree(), false,
        openvdb::TopologyCopy());
    for (auto it = mask.cbeginValueOn(); it; ++it) acc.setValueOn(it.getCoord(), value);
    return g;
}

// A flat 10x10 patch at y = 0 facing +y.
openvdb::Vec3SGrid::Ptr
patch()
{
    std::vector<std::pair<Coord, Vec3f>> v;
    for (int x = 0; x < 10; ++x) for (int z = 0; z < 10; ++z) v.push_back({{x, 0, z}, {0, 1, 0}});
    return normalGrid(v);
}

} // namespace

TEST_F(SceneTest, VoxelIndexIsCompactLeafOrdered)
{
    std::mt19937 rng(7);
    std::uniform_int_distribution<int> d(-200, 200);
    openvdb::MaskTree mask;
    std::set<Coord> expected;
    for (int i = 0; i < 5000; ++i) {
        const Coord c(d(rng), d(rng), d(rng));
        mask.setValueOn(c);
        expected.insert(c);
    }
    const VoxelIndex index(mask);
    ASSERT_EQ(index.size(), expected.size());
    ASSERT_EQ(index.leafBegin(index.leafCount()), index.size());
    for (size_t n = 0; n < index.leafCount(); ++n) {
        const openvdb::CoordBBox leafBox = openvdb::CoordBBox::createCube(index.leafOrigin(n), 8);
        for (size_t i = index.leafBegin(n); i < index.leafBegin(n + 1); ++i) {
            EXPECT_TRUE(leafBox.isInside(index.coord(i)));
            EXPECT_EQ(index.find(index.coord(i)), int32_t(i));
            EXPECT_TRUE(expected.count(index.coord(i)));
            // Within a leaf the order is lexicographic (x, then y, then z).
            if (i > index.leafBegin(n)) {
                EXPECT_LT(index.coord(i - 1), index.coord(i));
            }
        }
    }
    EXPECT_EQ(index.find(Coord(1000, 1000, 1000)), -1);
}

TEST_F(SceneTest, LevelSetSphereSurfaceMatchesAnalyticSphere)
{
    const float radius = 40.f;   // voxels
    const openvdb::Vec3f centre(0.3f, -0.2f, 0.45f);
    auto ls = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(radius, centre, 1.f);
    ls->setName("sphere");
    for (int separation : {6, 26}) {
        SceneOptions options;
        options.separation = separation;
        const Scene scene = buildScene({ls}, options);
        EXPECT_EQ(scene.surfaceKind(), GridRoles::SurfaceKind::LevelSet);

        // Brute force over the analytic signed distance: voxel centres inside or on the sphere
        // with a neighbour strictly outside.
        auto phi = [&](const Coord& c) { return float((c.asVec3d() - centre).length()) - radius; };
        size_t expected = 0;
        const int r = int(radius) + 2;
        for (int x = -r; x <= r; ++x) for (int y = -r; y <= r; ++y) for (int z = -r; z <= r; ++z) {
            const Coord c(x, y, z);
            if (phi(c) > 0.f) continue;
            bool boundary = false;
            for (int i = -1; i <= 1 && !boundary; ++i) for (int j = -1; j <= 1; ++j) {
                for (int k = -1; k <= 1; ++k) {
                    const int manhattan = std::abs(i) + std::abs(j) + std::abs(k);
                    if (manhattan == 0 || (separation == 6 && manhattan > 1)) continue;
                    if (phi(c.offsetBy(i, j, k)) > 0.f) boundary = true;
                }
            }
            expected += boundary;
        }
        // The grid stores float distances computed like phi(): allow a handful of voxels whose
        // centre lies within float rounding of the sphere.
        EXPECT_NEAR(double(scene.size()), double(expected), 1e-3 * double(expected))
            << "separation " << separation;
        if (separation == 26) {
            // A plane with unit normal n has |n|_1 inner 26-boundary voxels per unit area, in a
            // shell of that thickness below the surface; the mean of |n|_1 over the sphere is
            // 3/2, so about 4 pi (R - 3/4)^2 * 3/2 voxels (1% for the digitisation).
            const double analytic = 6.0 * M_PI * (radius - 0.75) * (radius - 0.75);
            EXPECT_NEAR(double(scene.size()), analytic, 0.01 * analytic);
        }
        double worst = 0.0;
        for (size_t i = 0; i < scene.size(); ++i) {
            const openvdb::Vec3d exact = (scene.voxels().coord(i).asVec3d() - centre).unit();
            const double cosAngle = std::min(1.0, exact.dot(openvdb::Vec3d(scene.normal(i))));
            worst = std::max(worst, std::acos(cosAngle) * 180.0 / M_PI);
            ASSERT_NEAR(scene.normal(i).length(), 1.f, 1e-5f);
        }
        EXPECT_LT(worst, 5.0) << "worst normal error in degrees";   // issue 2: within 5 degrees
    }
}

TEST_F(SceneTest, NormalGridSceneKeepsOnlyWhatTheInputHas)
{
    auto n = patch();
    const Scene grey = buildScene({n});
    EXPECT_EQ(grey.size(), 100u);
    EXPECT_TRUE(grey.albedo().isUniform());
    EXPECT_FLOAT_EQ(grey.albedo().grey(0), 0.5f);   // SceneOptions default
    EXPECT_FALSE(grey.hasEmission());
    EXPECT_FALSE(grey.isRgb());
    EXPECT_EQ(grey.albedo().memUsage() + grey.emission().memUsage(), 0u);

    auto albedo = attributeGrid<openvdb::Vec3SGrid>("albedo", *n, Vec3f(0.2f, 0.4f, 0.6f));
    auto emission = attributeGrid<openvdb::FloatGrid>("emission", *n, 2.f);
    const Scene rgb = buildScene({n, albedo, emission});
    EXPECT_TRUE(rgb.isRgb());
    EXPECT_TRUE(rgb.albedo().isRgb());
    EXPECT_EQ(rgb.emission().storage(), Attribute::Storage::Grey);
    EXPECT_TRUE(rgb.hasEmission());
    for (size_t i = 0; i < rgb.size(); ++i) {
        EXPECT_EQ(rgb.albedo().rgb(i), Vec3f(0.2f, 0.4f, 0.6f));
        EXPECT_FLOAT_EQ(rgb.emission().grey(i), 2.f);
        EXPECT_EQ(rgb.normal(i), Vec3f(0, 1, 0));
    }
}

TEST_F(SceneTest, RotatedTransformNormalsGoToIndexSpaceAndBack)
{
    auto n = patch();
    openvdb::math::Transform::Ptr xform = openvdb::math::Transform::createLinearTransform(0.5);
    xform->postRotate(0.7, openvdb::math::Z_AXIS);
    n->setTransform(xform);
    // World normal = the index +y axis rotated by 0.7 rad about z.
    const openvdb::Vec3d world = xform->baseMap()->applyIJT(openvdb::Vec3d(0, 1, 0)).unit();
    for (auto it = n->beginValueOn(); it; ++it) it.setValue(Vec3f(world));
    const Scene scene = buildScene({n});
    for (size_t i = 0; i < scene.size(); ++i) {
        EXPECT_NEAR((scene.normal(i) - Vec3f(0, 1, 0)).length(), 0.f, 1e-6f);
        EXPECT_NEAR((scene.worldNormal(i) - Vec3f(world)).length(), 0.f, 1e-6f);
    }
}

// ---- each malformed scene is rejected with the right exception type ----------------------------

TEST_F(SceneTest, RejectsMalformedScenes)
{
    auto n = patch();
    auto expectThrow = [](const openvdb::GridPtrVec& grids, const char* what,
                           const std::string& fragment, SceneOptions o = SceneOptions()) {
        try {
            buildScene(grids, o);
            ADD_FAILURE() << what << ": no exception";
        } catch (const openvdb::Exception& e) {
            EXPECT_NE(errorMessage(e).find(fragment), std::string::npos)
                << what << ": message was '" << errorMessage(e) << "'";
        }
    };
    EXPECT_THROW(buildScene({}), openvdb::KeyError);
    expectThrow({}, "no grids", "no surface");

    auto floatNormal = openvdb::FloatGrid::create();
    floatNormal->setName("normal");
    EXPECT_THROW(buildScene({floatNormal}), openvdb::TypeError);

    auto intAlbedo = openvdb::Int32Grid::create();
    intAlbedo->setName("albedo");
    intAlbedo->setTransform(n->transform().copy());
    EXPECT_THROW(buildScene({n, intAlbedo}), openvdb::TypeError);

    auto moved = attributeGrid<openvdb::FloatGrid>("albedo", *n, 0.5f);
    moved->setTransform(openvdb::math::Transform::createLinearTransform(0.2));
    EXPECT_THROW(buildScene({n, moved}), openvdb::ValueError);
    expectThrow({n, moved}, "mismatched transform", "not on the same transform");

    expectThrow({n, attributeGrid<openvdb::FloatGrid>("albedo", *n, 1.5f)}, "albedo > 1",
        "outside [0, 1]");
    expectThrow({n, attributeGrid<openvdb::FloatGrid>("albedo", *n, -0.1f)}, "albedo < 0",
        "outside [0, 1]");
    expectThrow({n, attributeGrid<openvdb::Vec3SGrid>("albedo", *n, Vec3f(0.5f, NAN, 0.5f))},
        "NaN albedo", "nan");
    expectThrow({n, attributeGrid<openvdb::FloatGrid>("emission", *n, -1.f)}, "negative emission",
        "outside [0, inf)");
    expectThrow({n, attributeGrid<openvdb::FloatGrid>("emission", *n, INFINITY)}, "inf emission",
        "emission at voxel");

    auto zero = patch();
    zero->tree().setValue(Coord(3, 0, 3), Vec3f(0.f));
    expectThrow({zero}, "zero normal", "zero length");
    auto nan = patch();
    nan->tree().setValue(Coord(3, 0, 3), Vec3f(NAN, 0.f, 0.f));
    expectThrow({nan}, "NaN normal", "not finite");

    auto empty = openvdb::Vec3SGrid::create();
    empty->setName("normal");
    expectThrow({empty}, "empty grid", "no active voxels");

    auto stretched = patch();
    openvdb::Mat4R stretch = openvdb::Mat4R::identity();
    stretch.preScale(openvdb::Vec3d(1, 2, 1));
    stretched->setTransform(openvdb::math::Transform::createLinearTransform(stretch));
    expectThrow({stretched}, "non-cubic voxels", "non-cubic");

    auto a = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(5.f, Vec3f(0), 1.f);
    auto b = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(5.f, Vec3f(20), 1.f);
    a->setName("a");
    b->setName("b");
    expectThrow({a, b}, "two level sets", "several level sets");
    SceneOptions pick;
    pick.surface = "b";
    EXPECT_GT(buildScene({a, b}, pick).size(), 0u);
    pick.surface = "c";
    EXPECT_THROW(buildScene({a, b}, pick), openvdb::KeyError);

    auto nanLs = a->deepCopy();
    nanLs->tree().setValue(Coord(0, 0, 0), NAN);
    expectThrow({nanLs}, "NaN level set", "level set 'a' has value nan");

    // All outside: a narrow band with no zero crossing.
    auto outside = openvdb::FloatGrid::create(3.f);
    outside->setGridClass(openvdb::GRID_LEVEL_SET);
    outside->setName("ls");
    outside->tree().setValue(Coord(0), 1.f);
    expectThrow({outside}, "no zero crossing", "no zero crossing");
}

// ---- clouds ----------------------------------------------------------------------------------

TEST_F(SceneTest, CloudScalesExtinctionAndValidates)
{
    auto density = openvdb::FloatGrid::create(0.f);
    density->setName("density");
    density->setGridClass(openvdb::GRID_FOG_VOLUME);
    density->setTransform(openvdb::math::Transform::createLinearTransform(0.25));
    for (int i = 0; i < 20; ++i) density->tree().setValueOn(Coord(i, 0, 0), 0.1f * float(i));
    CloudOptions o;
    o.extinctionScale = 3.f;
    const Cloud cloud = buildCloud({density}, o);
    ASSERT_EQ(cloud.size(), 20u);
    for (size_t i = 0; i < cloud.size(); ++i) {
        EXPECT_FLOAT_EQ(cloud.extinction(i), 0.3f * float(cloud.voxels().coord(i).x()));
        EXPECT_FLOAT_EQ(cloud.albedo().grey(i), 1.f);
    }
    EXPECT_DOUBLE_EQ(cloud.voxelSize(), 0.25);

    auto bad = density->deepCopy();
    bad->tree().setValue(Coord(3, 0, 0), -1.f);
    EXPECT_THROW(buildCloud({bad}), openvdb::ValueError);
    bad->tree().setValue(Coord(3, 0, 0), NAN);
    EXPECT_THROW(buildCloud({bad}), openvdb::ValueError);
    auto vec = openvdb::Vec3SGrid::create();
    vec->setName("density");
    EXPECT_THROW(buildCloud({vec}), openvdb::TypeError);
    EXPECT_THROW(buildCloud({}), openvdb::KeyError);
    o.extinctionScale = 0.f;
    EXPECT_THROW(buildCloud({density}, o), openvdb::ValueError);
}

// ---- output grids ----------------------------------------------------------------------------

TEST_F(SceneTest, RadiosityGridIsActiveExactlyOnSurfaceWithMetadata)
{
    auto ls = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(12.f, Vec3f(0), 0.1f);
    const Scene scene = buildScene({ls});
    std::vector<float> values(scene.size());
    for (size_t i = 0; i < values.size(); ++i) values[i] = float(i);
    SolveStats stats;
    stats.directions = 42;
    stats.iterations = 7;
    stats.residual = 1e-5;
    stats.seconds = 1.5;
    stats.lines = "standard";
    auto grid = makeRadiosityGrid(scene, values, stats);
    auto fg = openvdb::gridPtrCast<openvdb::FloatGrid>(grid);
    ASSERT_TRUE(fg);
    EXPECT_EQ(fg->getName(), "radiosity");
    EXPECT_EQ(fg->activeVoxelCount(), scene.size());
    EXPECT_TRUE(fg->tree().hasSameTopology(scene.voxels().tree()));
    EXPECT_EQ(fg->transform(), scene.transform());
    for (size_t i = 0; i < scene.size(); ++i) {
        ASSERT_EQ(fg->tree().getValue(scene.voxels().coord(i)), float(i));
    }
    EXPECT_EQ(fg->metaValue<int32_t>("vdbrad:voxels"), int32_t(scene.size()));
    EXPECT_EQ(fg->metaValue<int32_t>("vdbrad:directions"), 42);
    EXPECT_EQ(fg->metaValue<int32_t>("vdbrad:iterations"), 7);
    EXPECT_FLOAT_EQ(fg->metaValue<float>("vdbrad:residual"), 1e-5f);
    EXPECT_FLOAT_EQ(fg->metaValue<float>("vdbrad:seconds"), 1.5f);
    EXPECT_EQ(fg->metaValue<std::string>("vdbrad:lines"), "standard");
    EXPECT_EQ(fg->metaValue<std::string>("vdbrad:version"), VDBRAD_VERSION_STRING);

    std::vector<Vec3f> rgb(scene.size(), Vec3f(1, 2, 3));
    auto vg = openvdb::gridPtrCast<openvdb::Vec3SGrid>(makeRadiosityGrid(scene, rgb, stats));
    ASSERT_TRUE(vg);
    EXPECT_EQ(vg->getVectorType(), openvdb::VEC_INVARIANT);
    EXPECT_TRUE(vg->tree().hasSameTopology(scene.voxels().tree()));
}

TEST_F(SceneTest, ExplicitSceneRoundTripsThroughGrids)
{
    auto ls = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(15.f, Vec3f(1, 2, 3), 0.1f);
    ls->setName("ls");
    auto emission = openvdb::FloatGrid::create(0.f);
    emission->setName("emission");
    emission->setTransform(ls->transform().copy());
    // Emitting half: every surface voxel with x >= 10 (the centre's index x).
    emission->fill(openvdb::CoordBBox(Coord(10, -200, -200), Coord(200, 200, 200)), 3.f);
    const Scene a = buildScene({ls, emission});
    const openvdb::GridPtrVec explicitGrids = sceneToGrids(a);
    ASSERT_EQ(explicitGrids.size(), 3u);
    const Scene b = buildScene(explicitGrids);
    EXPECT_EQ(b.surfaceKind(), GridRoles::SurfaceKind::NormalGrid);
    ASSERT_EQ(a.size(), b.size());
    for (size_t i = 0; i < a.size(); ++i) {
        ASSERT_EQ(a.voxels().coord(i), b.voxels().coord(i));
        EXPECT_NEAR((a.normal(i) - b.normal(i)).length(), 0.f, 1e-6f);
        EXPECT_EQ(a.albedo().grey(i), b.albedo().grey(i));
        EXPECT_EQ(a.emission().grey(i), b.emission().grey(i));
    }
}
