// The renderer and its image files against exact references: flat walls seen head-on (value,
// hit count from the camera geometry, per-pixel hit test), smooth interpolation of a linear ramp,
// no bleeding across a corner, a level-set sphere's silhouette, exact emission-absorption through
// a homogeneous cloud, the default camera, EXR and PNG bytes, and the errors users meet.
#include "grids/CanonicalGrids.h"
#include "vdbrad/mesh/MeshTracer.h"
#include "vdbrad/render/CloudShading.h"
#include "vdbrad/render/ImageIO.h"
#include "vdbrad/render/Renderer.h"
#include "vdbrad/vdbrad.h"

#include <openvdb/tools/Composite.h>
#include <openvdb/tools/LevelSetSphere.h>

#include <gtest/gtest.h>

#include <zlib.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <functional>
#include <iostream>
#include <limits>
#include <memory>
#include <string>

using namespace vdbrad;
using openvdb::Coord;
using openvdb::Vec3d;
using openvdb::Vec3f;

namespace {

class RenderTest : public ::testing::Test
{
protected:
    static void SetUpTestSuite() { openvdb::initialize(); }
};

struct SurfaceVoxel
{
    Coord ijk;
    Vec3f normal;   // world space (the transforms here only scale)
    Vec3f radiosity;
};

// A solved explicit-surface scene: `normal` and `radiosity` grids on one transform.
openvdb::GridPtrVec
solvedSurface(const std::vector<SurfaceVoxel>& voxels, double voxelSize, bool rgb)
{
    auto xform = openvdb::math::Transform::createLinearTransform(voxelSize);
    auto normal = openvdb::Vec3SGrid::create(Vec3f(0.f));
    normal->setName("normal");
    normal->setTransform(xform);
    auto grey = openvdb::FloatGrid::create(0.f);
    auto colour = openvdb::Vec3SGrid::create(Vec3f(0.f));
    for (const auto& v : voxels) {
        normal->tree().setValueOn(v.ijk, v.normal);
        grey->tree().setValueOn(v.ijk, v.radiosity[0]);
        colour->tree().setValueOn(v.ijk, v.radiosity);
    }
    openvdb::GridBase::Ptr radiosity = rgb ? openvdb::GridBase::Ptr(colour) : grey;
    radiosity->setName("radiosity");
    radiosity->setTransform(xform);
    return {normal, radiosity};
}

// A 64 x 64 square of voxels (i, j, 0), facing -z (towards the camera), radiosity f(i).
template<typename F>
openvdb::GridPtrVec
wall(double voxelSize, bool rgb, F f)
{
    std::vector<SurfaceVoxel> v;
    for (int i = 0; i < 64; ++i) {
        for (int j = 0; j < 64; ++j) v.push_back({Coord(i, j, 0), Vec3f(0, 0, -1), f(i)});
    }
    return solvedSurface(v, voxelSize, rgb);
}

// Camera on the wall's axis, D world units in front of its voxel centres.
Camera
headOn(double voxelSize, double D)
{
    const double c = 31.5 * voxelSize;   // the centre of the 64 cubes [-0.5, 63.5]
    Camera cam;
    cam.eye = Vec3d(c, c, -D);
    cam.target = Vec3d(c, c, 0.0);
    cam.fov = 40.0;
    return cam;
}

// Where @a ray meets the plane z = @a z (world).
Vec3d
onPlaneZ(const Renderer::RayT& ray, double z)
{
    return ray.eye() + ray.dir() * ((z - ray.eye()[2]) / ray.dir()[2]);
}

class CancelAtOnce : public openvdb::util::NullInterrupter
{
public:
    bool wasInterrupted(int) override { return true; }
};

// One PNG chunk: where its data starts and its length.
struct Chunk { std::string type; size_t data; uint32_t length; };

std::vector<Chunk>
chunks(const std::string& png)
{
    std::vector<Chunk> out;
    auto u32 = [&](size_t at) {
        return uint32_t(uint8_t(png[at])) << 24 | uint32_t(uint8_t(png[at + 1])) << 16
            | uint32_t(uint8_t(png[at + 2])) << 8 | uint32_t(uint8_t(png[at + 3]));
    };
    for (size_t at = 8; at + 12 <= png.size();) {
        const uint32_t len = u32(at);
        out.push_back({png.substr(at + 4, 4), at + 8, len});
        const uLong crc = crc32(0L, reinterpret_cast<const Bytef*>(png.data() + at + 4), len + 4);
        EXPECT_EQ(uint32_t(crc), u32(at + 8 + len)) << "CRC of " << out.back().type;
        at += 12 + len;
    }
    return out;
}

} // namespace

TEST_F(RenderTest, FlatWallHeadOnShowsItsRadiosityAndItsProjectedArea)
{
    // At distance D the square (side 1) spans 22.6 pixels: its edges cross pixels at 0.3 and 0.7
    // of their width, so the 4 x 4 samples below see partial coverage.
    const double vs = 1.0 / 64.0, D = 0.5 * vs + 24.0 / (22.6 * std::tan(20.0 * M_PI / 180.0));
    const openvdb::GridPtrVec grids = wall(vs, false, [](int) { return Vec3f(0.37f); });
    RenderOptions o;
    o.width = 64;
    o.height = 48;
    o.camera = headOn(vs, D);
    o.background = Vec3f(0.1f, 0.2f, 0.3f);
    const Renderer renderer(grids, o);
    const Image image = renderer.render();
    ASSERT_EQ(image.pixels.size(), size_t(64 * 48));
    EXPECT_TRUE(image.warnings.empty());

    size_t hits = 0;
    const double zFront = -0.5 * vs, lo = -0.5 * vs, hi = 63.5 * vs;
    for (int y = 0; y < o.height; ++y) {
        for (int x = 0; x < o.width; ++x) {
            const Vec3f p = image.at(x, y);
            const float cov = image.coverage[size_t(y * o.width + x)];
            if (cov == 1.f) {
                ++hits;
                for (int c = 0; c < 3; ++c) ASSERT_NEAR(p[c], 0.37f, 1e-6f);   // B, not B / pi
            } else {
                ASSERT_EQ(cov, 0.f);
                ASSERT_EQ(p, o.background);   // exactly: T = 1
            }
            // The pixel's ray hits iff it meets the front face inside the square (pixels
            // within 1e-9 of an edge are left out: either answer is right there).
            const Vec3d q = onPlaneZ(renderer.primaryRay(x + 0.5, y + 0.5), zFront);
            const double margin = std::min({q[0] - lo, hi - q[0], q[1] - lo, hi - q[1]});
            if (std::abs(margin) > 1e-9) {
                ASSERT_EQ(cov == 1.f, margin > 0.0) << x << ", " << y;
            }
        }
    }
    // The square (side 1 world unit) at distance D - vs / 2 spans s pixels: pixel centres
    // inside it number s^2 up to the rim, |count - s^2| <= 2 s + 1.
    const double s = 1.0 / (D - 0.5 * vs) / std::tan(20.0 * M_PI / 180.0) * (o.height / 2.0);
    EXPECT_NEAR(double(hits), s * s, 2.0 * s + 1.0);
    EXPECT_GT(hits, 400u);   // the wall is in the picture

    // Antialiasing: 4 x 4 samples give rim pixels a fractional coverage, and each pixel is
    // exactly the coverage-weighted mix of wall and background (1e-6).
    o.samplesPerPixel = 4;
    const Image aa = renderImage(grids, o);
    size_t partial = 0;
    for (size_t i = 0; i < aa.pixels.size(); ++i) {
        const float c = aa.coverage[i];
        if (c > 0.f && c < 1.f) ++partial;
        for (int k = 0; k < 3; ++k) {
            ASSERT_NEAR(aa.pixels[i][k], c * 0.37f + (1.f - c) * o.background[k], 1e-6f);
        }
    }
    EXPECT_GT(partial, size_t(4.0 * s) - 8);   // the rim, four sides
}

// MeshTracer (render --mesh) against brute force: the nearest hit over all triangles, for rays
// from outside and inside a cloud of random triangles, with bounded and unbounded ranges.
TEST_F(RenderTest, MeshTracerFindsTheNearestTriangle)
{
    TriangleMesh mesh;
    uint64_t state = 12345;
    auto uniform = [&]() {
        state = state * 6364136223846793005ull + 1442695040888963407ull;
        return double(state >> 11) * (1.0 / 9007199254740992.0);
    };
    for (int t = 0; t < 1500; ++t) {
        const Vec3d c(uniform(), uniform(), uniform());
        const uint32_t base = uint32_t(mesh.points.size());
        for (int k = 0; k < 3; ++k) {
            // Sizes from a tenth of a cell to several cells.
            const double r = 0.005 + 0.15 * uniform() * uniform();
            mesh.points.push_back(Vec3f(c + Vec3d(uniform() - 0.5, uniform() - 0.5,
                uniform() - 0.5) * (2.0 * r)));
        }
        mesh.triangles.push_back(openvdb::Vec3I(base, base + 1, base + 2));
    }
    mesh.triangles.push_back(openvdb::Vec3I(0, 0, 1));   // no area: left out
    const MeshTracer tracer(mesh, 0.02);
    EXPECT_EQ(tracer.triangleCount(), 1500u);
    MeshTracer::Accessor acc = tracer.accessor();
    size_t hits = 0;
    for (int r = 0; r < 4000; ++r) {
        const Vec3d eye = r % 2 ? Vec3d(uniform(), uniform(), uniform())
                                : Vec3d(uniform() * 3 - 1, uniform() * 3 - 1, -1.0);
        const Vec3d dir = Vec3d(uniform() - 0.5, uniform() - 0.5, uniform() - 0.2).unit();
        const double t1 = r % 3 ? std::numeric_limits<double>::infinity() : 0.5 + uniform();
        double best = t1;
        int64_t want = -1;
        for (size_t i = 0; i + 1 < mesh.triangles.size(); ++i) {
            const Vec3d a(mesh.points[mesh.triangles[i][0]]);
            const Vec3d e1 = Vec3d(mesh.points[mesh.triangles[i][1]]) - a;
            const Vec3d e2 = Vec3d(mesh.points[mesh.triangles[i][2]]) - a;
            // Cramer's rule for eye + t dir = a + u e1 + v e2.
            const double det = -dir.dot(e1.cross(e2));
            if (det == 0.0) continue;
            const Vec3d s = eye - a;
            const double t = s.dot(e1.cross(e2)) / det;
            const double u = -dir.dot(s.cross(e2)) / det;
            const double v = -dir.dot(e1.cross(s)) / det;
            if (u >= 0 && v >= 0 && u + v <= 1 && t >= 0 && t <= best) {
                best = t;
                want = int64_t(i);
            }
        }
        MeshTracer::Hit hit;
        const bool got = tracer.intersect(eye, dir, 0.0, t1, hit, acc);
        ASSERT_EQ(got, want >= 0) << "ray " << r;
        if (!got) continue;
        ++hits;
        ASSERT_NEAR(hit.t, best, 1e-12) << "ray " << r;
        EXPECT_EQ(int64_t(hit.triangle), want) << "ray " << r;
        EXPECT_LT(hit.normal.dot(dir), 0.0);
        EXPECT_NEAR(hit.normal.length(), 1.0, 1e-12);
    }
    EXPECT_GT(hits, 500u);   // 689 of the 4000 rays hit

    EXPECT_THROW(MeshTracer(mesh, 0.0), openvdb::ValueError);
    mesh.points[5] = Vec3f(std::nanf(""));
    EXPECT_THROW(MeshTracer(mesh, 0.02), openvdb::ValueError);
}

// render --mesh: a mesh rectangle inside a wall of voxels is drawn with its exact outline (a
// pixel shows the wall iff its ray meets the rectangle), shaded by the voxels around each hit.
TEST_F(RenderTest, MeshOutlineIsExact)
{
    const double vs = 1.0 / 64.0, D = 2.5;
    const openvdb::GridPtrVec grids = wall(vs, false, [](int) { return Vec3f(0.37f); });
    // Corners off the voxel grid, a quarter voxel in front of the centres.
    const double x0 = 10.3 * vs, x1 = 50.7 * vs, y0 = 5.2 * vs, y1 = 60.1 * vs, z = -0.25 * vs;
    auto mesh = std::make_shared<TriangleMesh>();
    mesh->points = {Vec3f(x0, y0, z), Vec3f(x1, y0, z), Vec3f(x1, y1, z), Vec3f(x0, y1, z)};
    mesh->triangles = {openvdb::Vec3I(0, 1, 2), openvdb::Vec3I(0, 2, 3)};
    RenderOptions o;
    o.width = 64;
    o.height = 48;
    o.camera = headOn(vs, D);
    o.mesh = mesh;
    const Renderer renderer(grids, o);
    const Image image = renderer.render();
    size_t hits = 0;
    for (int y = 0; y < o.height; ++y) {
        for (int x = 0; x < o.width; ++x) {
            const Vec3d q = onPlaneZ(renderer.primaryRay(x + 0.5, y + 0.5), z);
            const double margin = std::min({q[0] - x0, x1 - q[0], q[1] - y0, y1 - q[1]});
            if (std::abs(margin) < 1e-9) continue;
            const float cov = image.coverage[size_t(y * o.width + x)];
            ASSERT_EQ(cov == 1.f, margin > 0.0) << x << ", " << y;
            if (cov == 1.f) {
                ++hits;
                ASSERT_NEAR(image.at(x, y)[0], 0.37f, 1e-6f);
            }
        }
    }
    EXPECT_GT(hits, 200u);

    // A mesh that is not the scene's, and a mesh with nothing to show.
    auto far = std::make_shared<TriangleMesh>(*mesh);
    for (Vec3f& p : far->points) p += Vec3f(5.f, 0.f, 0.f);
    o.mesh = far;
    try {
        renderImage(grids, o);
        ADD_FAILURE() << "rendered a mesh far from the voxels";
    } catch (const openvdb::ValueError& e) {
        EXPECT_NE(std::string(e.what()).find("is not within the surface's voxels"),
            std::string::npos) << e.what();
    }
    auto flat = std::make_shared<TriangleMesh>(*mesh);
    flat->triangles = {openvdb::Vec3I(0, 1, 1)};
    o.mesh = flat;
    EXPECT_THROW(renderImage(grids, o), openvdb::ValueError);
}

TEST_F(RenderTest, RadiosityRampIsInterpolatedLinearlyWithoutSteps)
{
    // B(i) = (0.1 + 0.01 i, 0.2 + 0.02 i, 0.5) on voxel column i: at a hit point with index
    // x-coordinate X the blend is B(X) exactly (trilinear weights on a linear function), clamped
    // to the end columns beyond the outer voxel centres.
    const double vs = 1.0 / 64.0;
    auto ramp = [](double i) { return Vec3d(0.1 + 0.01 * i, 0.2 + 0.02 * i, 0.5); };
    const openvdb::GridPtrVec grids = wall(vs, true, [&](int i) { return Vec3f(ramp(i)); });
    RenderOptions o;
    o.width = 64;
    o.height = 48;
    o.camera = headOn(vs, 0.9);   // the wall fills the picture
    const Renderer renderer(grids, o);
    const Image image = renderer.render();
    size_t checked = 0;
    for (int y = 0; y < o.height; ++y) {
        float previous = -1.f;
        for (int x = o.width - 1; x >= 0; --x) {   // image right = world -x: walk towards +x
            ASSERT_EQ(image.coverage[size_t(y * o.width + x)], 1.f);
            const Vec3d q = onPlaneZ(renderer.primaryRay(x + 0.5, y + 0.5), -0.5 * vs);
            const double X = std::clamp(q[0] / vs, 0.0, 63.0);
            const Vec3d expected = ramp(X);
            const Vec3f p = image.at(x, y);
            for (int c = 0; c < 3; ++c) ASSERT_NEAR(p[c], expected[c], 1e-5) << x << ", " << y;
            ASSERT_GT(p[0], previous);   // strictly increasing: no flat steps
            previous = p[0];
            ++checked;
        }
    }
    EXPECT_EQ(checked, size_t(64 * 48));
}

TEST_F(RenderTest, CornerDoesNotBleedAcrossPerpendicularWalls)
{
    // A floor (y = 0, facing +y, B = 0.2) meeting a back wall (z = 31, facing -z, B = 0.8).
    // Near the corner the 2x2x2 blend reaches voxels of the other wall with trilinear weights up
    // to 1/2; their normals are perpendicular, so they must get weight 0: every pixel shows
    // exactly one of the two values (1e-6).
    std::vector<SurfaceVoxel> v;
    for (int i = 0; i < 32; ++i) {
        for (int k = 0; k < 31; ++k) v.push_back({Coord(i, 0, k), Vec3f(0, 1, 0), Vec3f(0.2f)});
        for (int j = 0; j < 32; ++j) v.push_back({Coord(i, j, 31), Vec3f(0, 0, -1), Vec3f(0.8f)});
    }
    const double vs = 1.0 / 32.0;
    const openvdb::GridPtrVec grids = solvedSurface(v, vs, false);
    RenderOptions o;
    o.width = 48;
    o.height = 48;
    Camera cam;
    cam.eye = Vec3d(15.5, 24.0, -16.0) * vs;
    cam.target = Vec3d(15.5, 4.0, 30.0) * vs;
    o.camera = cam;
    const Renderer renderer(grids, o);
    const Image image = renderer.render();
    size_t floor = 0, back = 0;
    for (size_t i = 0; i < image.pixels.size(); ++i) {
        if (image.coverage[i] == 0.f) continue;
        const float p = image.pixels[i][0];
        if (std::abs(p - 0.2f) <= 1e-6f) ++floor;
        else if (std::abs(p - 0.8f) <= 1e-6f) ++back;
        else FAIL() << "pixel " << i << " = " << p << ": blended across the corner";
    }
    EXPECT_GT(floor, 100u);
    EXPECT_GT(back, 100u);

    // Rays aimed just beside the corner, where half of the blend's trilinear weight lies on the
    // other wall's voxels (index points; world = index * vs).
    auto at = [&](const Vec3d& index) {
        const Vec3d target = index * vs;
        return renderer.radiance(Renderer::RayT(cam.eye, (target - cam.eye).unit()))[0];
    };
    EXPECT_NEAR(at(Vec3d(16.0, 0.5, 30.4)), 0.2f, 1e-6f);   // floor top, 0.1 voxel from the wall
    EXPECT_NEAR(at(Vec3d(16.0, 0.9, 30.5)), 0.8f, 1e-6f);   // wall face, 0.4 voxel above floor
}

TEST_F(RenderTest, LevelSetSphereHasASmoothSilhouette)
{
    // Sphere of radius R = 6 voxels at the origin, seen from distance D: its silhouette is a
    // circle of angular radius asin(R / D). Pixels whose ray passes closer to the centre than
    // R - 0.15 vs must hit, farther than R + 0.15 vs must miss (the zero crossing of the
    // trilinear distance field is within ~0.06 voxel of the sphere; the surface voxels' cubes
    // would stick out by up to 0.7 voxel), and the hit area gives the projected radius within
    // 0.25 pixel (a voxel is 2.2 pixels here).
    const float R = 0.3f, vs = 0.05f;
    const double D = 2.0;
    auto ls = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(R, Vec3f(0.f), vs, 3.f);
    ls->setName("sphere");
    const Scene scene = buildScene({ls});
    ASSERT_EQ(scene.surfaceKind(), GridRoles::SurfaceKind::LevelSet);
    const std::vector<float> values(scene.size(), 0.5f);
    const openvdb::GridPtrVec grids{ls, makeRadiosityGrid(scene, values, SolveStats())};

    RenderOptions o;
    o.width = 64;
    o.height = 64;
    Camera cam;
    cam.eye = Vec3d(0.0, 0.0, -D);
    cam.target = Vec3d(0.0);
    o.camera = cam;
    const Renderer renderer(grids, o);
    const Image image = renderer.render();
    size_t hits = 0;
    for (int y = 0; y < o.height; ++y) {
        for (int x = 0; x < o.width; ++x) {
            const bool hit = image.coverage[size_t(y * o.width + x)] == 1.f;
            if (hit) {
                ++hits;
                ASSERT_NEAR(image.at(x, y)[0], 0.5f, 1e-6f);
            }
            const Renderer::RayT ray = renderer.primaryRay(x + 0.5, y + 0.5);
            const double miss = (ray.eye() - ray.eye().dot(ray.dir()) * ray.dir()).length();
            if (miss < R - 0.15 * vs) {
                ASSERT_TRUE(hit) << x << ", " << y;
            } else if (miss > R + 0.15 * vs) {
                ASSERT_FALSE(hit) << x << ", " << y;
            }
        }
    }
    const double radius = std::tan(std::asin(R / D)) / std::tan(20.0 * M_PI / 180.0) * 32.0;
    EXPECT_NEAR(std::sqrt(double(hits) / M_PI), radius, 0.25);   // ~13.3 pixels
}

TEST_F(RenderTest, HomogeneousCloudIntegratesExactly)
{
    // A cube of 15^3 voxels of side 1/15 (so 1 world unit), extinction sigma, source J, albedo 1:
    // along an axis the pixel is pi J (1 - e^-tau) + b e^-tau with tau = sigma * 1 (1e-5
    // relative; pixels hold radiosity, pi x radiance),
    // for tau from 1e-4 (where 1 - e^-tau needs expm1) to 30. A wall behind the cloud shows
    // through with the same transmittance.
    const double vs = 1.0 / 15.0;
    auto xform = openvdb::math::Transform::createLinearTransform(vs);
    const double c = 7.0 * vs;   // the cube's centre is voxel 7's centre
    for (const float sigma : {1e-4f, 1.f, 30.f}) {
        for (const bool withSource : {true, false}) {
            for (const bool withWall : {false, true}) {
                const float J = 2.f;
                auto density = openvdb::FloatGrid::create(0.f);
                density->setName("density");
                density->setGridClass(openvdb::GRID_FOG_VOLUME);
                density->setTransform(xform);
                density->denseFill(openvdb::CoordBBox(Coord(0), Coord(14)), sigma, true);
                openvdb::GridPtrVec grids{density};
                if (withSource) {
                    auto source = openvdb::FloatGrid::create(0.f);
                    source->setName("mean_intensity");
                    source->setTransform(xform);
                    source->denseFill(openvdb::CoordBBox(Coord(0), Coord(14)), J, true);
                    grids.push_back(source);
                }
                if (withWall) {
                    std::vector<SurfaceVoxel> v;
                    for (int i = 0; i < 15; ++i) {
                        for (int j = 0; j < 15; ++j) {
                            v.push_back({Coord(i, j, 20), Vec3f(0, 0, -1), Vec3f(0.37f)});
                        }
                    }
                    for (auto& g : solvedSurface(v, vs, false)) {
                        g->setTransform(xform);
                        grids.push_back(g);
                    }
                }
                RenderOptions o;
                o.width = o.height = 33;   // odd: the centre pixel's ray is the axis
                o.background = Vec3f(0.25f);
                Camera cam;
                cam.eye = Vec3d(c, c, -3.0);
                cam.target = Vec3d(c, c, c);
                o.camera = cam;
                const Image image = renderImage(grids, o);
                EXPECT_EQ(image.warnings.size(), withSource ? 0u : 1u);
                const double tau = double(sigma) * 1.0, T = std::exp(-tau);
                const double behind = withWall ? 0.37 : 0.25;
                const double expected = (withSource ? kPi * J * -std::expm1(-tau) : 0.0)
                    + behind * T;
                // Below a transmittance of 1e-10 the ray counts as opaque, hence the 1e-9.
                EXPECT_NEAR(image.at(16, 16)[0], expected, 1e-5 * expected + 1e-9)
                    << "sigma " << sigma << " source " << withSource << " wall " << withWall;
                const float cov = image.coverage[16 * 33 + 16];
                EXPECT_NEAR(cov, withWall ? 1.0 : -std::expm1(-tau), 1e-6);
            }
        }
    }
    {
        // Thin cloud, black background: the pixel is pi J tau (1 - tau / 2 + ...), all from the
        // expm1 term (1e-5 relative).
        auto density = openvdb::FloatGrid::create(0.f);
        density->setName("density");
        density->setTransform(xform);
        density->denseFill(openvdb::CoordBBox(Coord(0), Coord(14)), 1e-4f, true);
        auto source = density->deepCopy();
        source->setName("mean_intensity");
        source->denseFill(openvdb::CoordBBox(Coord(0), Coord(14)), 2.f, true);
        RenderOptions o;
        o.width = o.height = 33;
        Camera cam;
        cam.eye = Vec3d(c, c, -3.0);
        cam.target = Vec3d(c, c, c);
        o.camera = cam;
        const Image image = renderImage({density, source}, o);
        const double expected = kPi * 2.0 * -std::expm1(-double(1e-4f));
        EXPECT_NEAR(image.at(16, 16)[0], expected, 1e-5 * expected);
    }
}

TEST_F(RenderTest, DefaultCameraFramesTheBox)
{
    const openvdb::BBoxd box(Vec3d(-1.0, 2.0, 3.0), Vec3d(4.0, 3.5, 5.0));
    for (const double aspect : {4.0 / 3.0, 0.5, 3.0}) {
        const Camera cam = defaultCamera(box, aspect, 40.0);
        EXPECT_LT(cam.eye[2], box.min()[2]);   // in front of the open (-z) side
        const Vec3d f = (cam.target - cam.eye).unit();
        EXPECT_NEAR(f[2], 1.0, 1e-12);          // looking along +z
        const Vec3d r = f.cross(cam.up).unit(), u = r.cross(f);
        const double tanV = std::tan(20.0 * M_PI / 180.0);
        for (int k = 0; k < 8; ++k) {
            const Vec3d corner((k & 1) ? box.max()[0] : box.min()[0],
                (k & 2) ? box.max()[1] : box.min()[1], (k & 4) ? box.max()[2] : box.min()[2]);
            const Vec3d v = corner - cam.eye;
            const double depth = v.dot(f);
            ASSERT_GT(depth, 0.0);
            EXPECT_LE(std::abs(v.dot(r) / depth), tanV * aspect) << "aspect " << aspect;
            EXPECT_LE(std::abs(v.dot(u) / depth), tanV) << "aspect " << aspect;
        }
    }
    EXPECT_THROW(defaultCamera(openvdb::BBoxd(), 1.0), openvdb::ValueError);   // empty box
}

TEST_F(RenderTest, ExrRoundTrip)
{
    Image image;
    image.width = 7;
    image.height = 5;
    for (int i = 0; i < 35; ++i) {
        const float v = float(i);
        image.pixels.emplace_back(0.001f * (v + 1.f), v * 31.7f + 0.5f, -0.25f * v);
    }
    const std::string full = encodeExr(image, ExrPixel::Float);
    ASSERT_GE(full.size(), 4u);
    EXPECT_EQ(std::string(full, 0, 4), std::string("\x76\x2f\x31\x01", 4));   // EXR magic
    const Image back = decodeExr(full);
    ASSERT_EQ(back.width, 7);
    ASSERT_EQ(back.height, 5);
    for (size_t i = 0; i < image.pixels.size(); ++i) ASSERT_EQ(back.pixels[i], image.pixels[i]);

    const std::string halves = encodeExr(image);
    EXPECT_EQ(std::string(halves, 0, 4), std::string("\x76\x2f\x31\x01", 4));
    const Image h = decodeExr(halves);
    for (size_t i = 0; i < image.pixels.size(); ++i) {
        for (int c = 0; c < 3; ++c) {
            // Half keeps 11 significant bits: round to nearest, relative error <= 2^-11.
            const float v = image.pixels[i][c];
            ASSERT_NEAR(h.pixels[i][c], v, std::ldexp(std::abs(v), -11)) << i << " " << c;
        }
    }
    EXPECT_THROW(decodeExr("not an exr"), openvdb::IoError);
    EXPECT_THROW(decodeExr(std::string(full, 0, full.size() / 2)), openvdb::IoError);

    // OpenEXR's own tool reads the file (Debian package openexr), when installed.
    if (std::system("command -v exrheader > /dev/null 2>&1") == 0) {
        const std::string path = ::testing::TempDir() + "vdbrad_render_test.exr";
        std::ofstream(path, std::ios::binary) << halves;
        const std::string cmd = "exrheader '" + path + "' > /dev/null 2>&1";
        EXPECT_EQ(std::system(cmd.c_str()), 0);
        std::remove(path.c_str());
    } else {
        std::cout << "exrheader not installed: its check is skipped\n";
    }
}

TEST_F(RenderTest, PngHasValidChunksAndTheToneMappedValues)
{
    // Ten grey pixels 0.1 .. 1.0 (luminance = value), two background ones (coverage 0, left out
    // of the auto-exposure): the 90th percentile of the ten is element 8 of the sorted
    // values, 0.9, so the scale is 0.8 / 0.9.
    Image image;
    image.width = 4;
    image.height = 3;
    for (int i = 0; i < 10; ++i) {
        image.pixels.emplace_back(0.1f * float(i + 1));
        image.coverage.push_back(1.f);
    }
    image.pixels.emplace_back(50.f);
    image.coverage.push_back(0.f);
    image.pixels.emplace_back(0.3f, 0.6f, 0.05f);
    image.coverage.push_back(0.f);
    const double scale = toneMapScale(image);
    EXPECT_NEAR(scale, 0.8 / 0.9, 1e-6);   // float luminance weights: ~1e-7 relative
    ToneMap brighter;
    brighter.exposureStops = 1.0;
    EXPECT_NEAR(toneMapScale(image, brighter), 2.0 * scale, 1e-12);
    ToneMap fixed;
    fixed.autoExposure = false;
    fixed.exposureStops = -2.0;
    EXPECT_EQ(toneMapScale(image, fixed), 0.25);

    for (const ToneMap& tm : {ToneMap(), fixed}) {
        const std::string png = encodePng(image, tm);
        ASSERT_GT(png.size(), 8u);
        EXPECT_EQ(std::string(png, 0, 8), std::string("\x89PNG\r\n\x1a\n", 8));
        const std::vector<Chunk> cs = chunks(png);
        ASSERT_GE(cs.size(), 3u);
        ASSERT_EQ(cs.front().type, "IHDR");
        ASSERT_EQ(cs.front().length, 13u);
        EXPECT_EQ(cs.back().type, "IEND");
        const std::string ihdr = png.substr(cs.front().data, 13);
        EXPECT_EQ(ihdr.substr(0, 8), std::string("\0\0\0\x04\0\0\0\x03", 8));   // 4 x 3
        EXPECT_EQ(ihdr.substr(8), std::string("\x08\x02\0\0\0", 5));   // 8-bit RGB
        std::string idat;
        for (const Chunk& c : cs) if (c.type == "IDAT") idat += png.substr(c.data, c.length);
        std::string raw(3 * (1 + 3 * 4), '\0');
        uLongf rawSize = uLongf(raw.size());
        ASSERT_EQ(uncompress(reinterpret_cast<Bytef*>(&raw[0]), &rawSize,
            reinterpret_cast<const Bytef*>(idat.data()), uLong(idat.size())), Z_OK);
        ASSERT_EQ(rawSize, raw.size());
        const double s = toneMapScale(image, tm);
        for (int y = 0; y < 3; ++y) {
            EXPECT_EQ(raw[size_t(y) * 13], 0);   // filter type none
            for (int x = 0; x < 4; ++x) {
                for (int c = 0; c < 3; ++c) {
                    // 8-bit sRGB of the clamped, scaled value: IEC 61966-2-1.
                    const double v = std::clamp(double(image.at(x, y)[c]) * s, 0.0, 1.0);
                    const double e = v <= 0.0031308 ? 12.92 * v
                        : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
                    EXPECT_EQ(int(uint8_t(raw[size_t(y) * 13 + 1 + size_t(x) * 3 + size_t(c)])),
                        int(std::lround(255.0 * e))) << x << ", " << y << ", " << c;
                }
            }
        }
    }
    // The 90th-percentile pixel (0.9) maps to 0.8: sRGB 0.906 -> 231.
    EXPECT_EQ(std::lround(255.0 * srgbEncode(0.9 * scale)), 231);
}

TEST_F(RenderTest, ClearErrors)
{
    const double vs = 1.0 / 64.0;
    const openvdb::GridPtrVec grids = wall(vs, false, [](int) { return Vec3f(0.37f); });
    auto expectError = [&](const RenderOptions& o, const std::string& what) {
        try {
            renderImage(grids, o);
            ADD_FAILURE() << "no error, expected: " << what;
        } catch (const openvdb::ValueError& e) {
            EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
        }
    };
    RenderOptions o;
    o.width = 8;
    o.height = 6;
    o.width = 0;
    expectError(o, "image size");
    o.width = 16385;
    expectError(o, "image size");
    o.width = 8;
    o.height = -3;
    expectError(o, "image size");
    o.height = 6;
    o.samplesPerPixel = 0;
    expectError(o, "samples per pixel");
    o.samplesPerPixel = 17;
    expectError(o, "samples per pixel");
    o.samplesPerPixel = 1;
    o.background = Vec3f(std::nanf(""));
    expectError(o, "background");
    o.background = Vec3f(0.f);
    Camera cam;
    cam.eye = cam.target = Vec3d(1.0);
    o.camera = cam;
    expectError(o, "same point");
    cam.target = Vec3d(1.0, 5.0, 1.0);   // looking along up
    o.camera = cam;
    expectError(o, "parallel");
    cam.target = Vec3d(1.0, 1.0, std::nan(""));
    o.camera = cam;
    expectError(o, "NaN");
    cam.target = Vec3d(1.0, 1.0, 5.0);
    cam.fov = 180.0;
    o.camera = cam;
    expectError(o, "field of view");
    o.camera.reset();

    // An unsolved scene.
    try {
        renderImage({grids[0]}, o);
        ADD_FAILURE() << "rendered a scene without radiosity";
    } catch (const openvdb::ValueError& e) {
        EXPECT_NE(std::string(e.what()).find("no radiosity grid: solve the scene first"),
            std::string::npos) << e.what();
    }
    // Radiosity on other voxels than the surface's (e.g. solved with another --separation).
    auto other = grids[1]->deepCopyGrid();
    static_cast<openvdb::FloatGrid&>(*other).tree().setValueOn(Coord(100, 0, 0), 1.f);
    try {
        renderImage({grids[0], other}, o);
        ADD_FAILURE() << "rendered mismatched radiosity";
    } catch (const openvdb::ValueError& e) {
        EXPECT_NE(std::string(e.what()).find("--separation"), std::string::npos) << e.what();
    }
    // NaN radiosity.
    auto nan = grids[1]->deepCopyGrid();
    static_cast<openvdb::FloatGrid&>(*nan).tree().setValueOn(Coord(3, 3, 0), std::nanf(""));
    EXPECT_THROW(renderImage({grids[0], nan}, o), openvdb::ValueError);
    // Cancellation.
    CancelAtOnce cancel;
    EXPECT_THROW(renderImage(grids, o, &cancel), Cancelled);   // while reading the scene
    const Renderer renderer(grids, o);
    EXPECT_THROW(renderer.render(&cancel), Cancelled);         // after the first row

    Image bad;
    EXPECT_THROW(encodeExr(bad), openvdb::ValueError);
    EXPECT_THROW(encodePng(bad), openvdb::ValueError);
    bad.width = 2;
    bad.height = 2;
    bad.pixels.resize(3);
    EXPECT_THROW(encodeExr(bad), openvdb::ValueError);
}

// The final gather on curved surfaces, an environment furnace: two overlapping level-set
// spheres (a crease where they meet), albedo 1, under a uniform sky L: the solution is pi L on
// every voxel, and so is every pixel, whatever the gather's rays meet (sky or voxels at pi L).
// Rays from a voxel between curved neighbours that meet a neighbour's back pass through a
// digitisation crack: counted as black they made dark specks (the Stanford bunny's ears).
TEST_F(RenderTest, GatherOnCurvedSurfacesKeepsTheFurnace)
{
    openvdb::FloatGrid::Ptr a = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(1.f,
        Vec3f(-0.6f, 0.f, 0.f), 0.05f);
    openvdb::FloatGrid::Ptr b = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(0.8f,
        Vec3f(0.7f, 0.2f, 0.f), 0.05f);
    openvdb::tools::csgUnion(*a, *b);
    a->setName("surface");
    openvdb::GridPtrVec grids{a};
    SceneOptions so;
    so.defaultAlbedo = 1.f;
    const Scene scene = buildScene(grids, so);
    RadiosityOptions ro;
    ro.sky = Sky::uniform(Vec3d(1.0));
    ro.directions = 300;
    ro.tolerance = 1e-7;
    grids.push_back(solveRadiosity(scene, ro));
    RenderOptions o;
    o.width = 96;
    o.height = 64;
    o.gather = 16;
    o.sky = ro.sky;
    o.scene = so;
    Camera cam;
    cam.eye = Vec3d(0.0, 1.5, -4.0);
    cam.target = Vec3d(0.0, 0.0, 0.0);
    cam.fov = 40.0;
    o.camera = cam;
    const Image image = renderImage(grids, o);
    size_t on = 0, dark = 0;
    double lo = 1e9, hi = 0.0;
    for (int y = 0; y < o.height; ++y) {
        for (int x = 0; x < o.width; ++x) {
            if (image.coverage[size_t(y * o.width + x)] < 1.f) continue;
            const double v = image.at(x, y)[0];
            lo = std::min(lo, v);
            hi = std::max(hi, v);
            if (v < 0.999 * kPi) ++dark;
            ++on;
        }
    }
    std::printf("gather on curved surfaces, furnace under a sky: %zu pixels in [%.5f, %.5f] x pi L, "
        "%zu below 0.999\n", on, lo / kPi, hi / kPi, dark);
    EXPECT_GT(on, 2000u);
    EXPECT_EQ(dark, 0u);
    EXPECT_LT(hi, 1.001 * kPi);
}

// Issue 23, the final gather (--gather): a pixel shows E + rho (D + G) at the point of the voxel's
// plane the camera sees. Under a black lamp over an open floor G is 0 (the gather's rays find the
// black lamp or the sky) and D is exact at that point, not at the voxel's centre: every floor
// pixel equals rho E F(point -> lamp cells) to float rounding.
TEST_F(RenderTest, FinalGatherShowsTheExactDirectLightAtEachPixelsPoint)
{
    grids::BuildParams p;
    p.res = 32;
    p.radius = 0.1f;
    p.height = 0.25f;
    openvdb::GridPtrVec grids = grids::makeLamp(p);
    const Scene scene = buildScene(grids);
    grids.push_back(solveRadiosity(scene));
    // The lamp's cells in index space, from its voxels.
    double lo = 1e9, hi = -1e9, top = 0.0;
    for (size_t i = 0; i < scene.size(); ++i) {
        if (scene.emission().grey(i) <= 0.f) continue;
        const Coord c = scene.voxels().coord(i);
        lo = std::min(lo, c.x() - 0.5);
        hi = std::max(hi, c.x() + 0.5);
        top = c.y();
    }
    RenderOptions o;
    o.width = 48;
    o.height = 36;
    o.gather = 8;
    Camera cam;
    cam.eye = Vec3d(0.5, 0.15, -0.3);
    cam.target = Vec3d(0.5, 0.0, 0.45);
    cam.fov = 50.0;
    o.camera = cam;
    const Renderer renderer(grids, o);
    const Image image = renderer.render();
    const openvdb::math::Transform& xform = scene.transform();
    size_t checked = 0;
    double worst = 0.0;
    for (int y = 0; y < o.height; ++y) {
        for (int x = 0; x < o.width; ++x) {
            const Renderer::RayT ray = renderer.primaryRay(x + 0.5, y + 0.5);
            // Where the ray enters the floor voxels' cubes (index y = 1/2), moved onto their
            // plane (index y = 0).
            const Vec3d e = xform.worldToIndex(ray.eye());
            const Vec3d f = xform.worldToIndex(ray.eye() + ray.dir()) - e;
            if (!(f[1] < 0.0)) continue;
            const Vec3d q = e + f * ((0.5 - e[1]) / f[1]);
            // Away from the floor's rim and from the lamp's shadowless but cut-off view.
            if (q[0] < 1.0 || q[0] > p.res - 2.0 || q[2] < 1.0 || q[2] > p.res - 2.0) continue;
            const double exact = 0.5 * grids::rectangleFactor(lo - q[0], hi - q[0], lo - q[2],
                hi - q[2], top);
            const double got = image.at(x, y)[0];
            worst = std::max(worst, std::abs(got - exact) / exact);
            ++checked;
        }
    }
    EXPECT_GT(checked, 300u);
    EXPECT_LT(worst, 1e-4);
}

// The cloud solver's ground under a cloud (`ground_irradiance`, CloudTransfer::groundGrid) is
// drawn, seen from above, as its radiosity rho E attenuated by the cloud in front: looking
// straight down through a uniform cloud of optical depth tau onto a ground of irradiance E, the
// pixel is pi J (1 - e^-tau) + rho E e^-tau (1e-5). Seen from below, the ground is not drawn.
TEST_F(RenderTest, GroundUnderACloudShowsItsRadiosity)
{
    const double vs = 1.0 / 15.0;
    auto xform = openvdb::math::Transform::createLinearTransform(vs);
    const double c = 7.0 * vs;
    const float sigma = 0.7f, J = 2.f, E = 3.f, rho = 0.4f;
    auto density = openvdb::FloatGrid::create(0.f);
    density->setName("density");
    density->setGridClass(openvdb::GRID_FOG_VOLUME);
    density->setTransform(xform);
    density->denseFill(openvdb::CoordBBox(Coord(0), Coord(14)), sigma, true);
    auto source = density->deepCopy();
    source->setName("mean_intensity");
    source->denseFill(openvdb::CoordBBox(Coord(0), Coord(14)), J, true);
    auto ground = openvdb::FloatGrid::create(0.f);
    ground->setName("ground_irradiance");
    ground->setTransform(xform);
    ground->denseFill(openvdb::CoordBBox(Coord(0, -1, 0), Coord(14, -1, 14)), E, true);
    ground->insertMeta("vdbrad:ground_albedo", openvdb::FloatMetadata(rho));
    ground->insertMeta("vdbrad:up", openvdb::Int32Metadata(1));
    for (const bool fromAbove : {true, false}) {
        RenderOptions o;
        o.width = o.height = 33;
        o.background = Vec3f(0.25f);
        Camera cam;
        cam.eye = Vec3d(c, fromAbove ? 3.0 : -3.0, c);
        cam.target = Vec3d(c, c, c);
        cam.up = Vec3d(0, 0, 1);
        o.camera = cam;
        const Image image = renderImage({density, source, ground}, o);
        EXPECT_TRUE(image.warnings.empty());
        // The density is interpolated between voxel centres, so it reaches down to the centre
        // of the ground's layer: from above, the ground's top face cuts off the eighth of a
        // voxel's depth that lies below it (the integral of the tent from -1 to -1/2).
        const double T = std::exp(-double(sigma) * (fromAbove ? 1.0 - 0.125 / 15.0 : 1.0));
        const double behind = fromAbove ? rho * E : 0.25;
        EXPECT_NEAR(image.at(16, 16)[0], kPi * J * (1.0 - T) + behind * T, 1e-5) << fromAbove;
    }
}

// A fog volume on voxels [0, 14]^3 of size vs whose density is @a density(x) along x.
openvdb::FloatGrid::Ptr
rampCloud(double vs, const std::function<float(int)>& density)
{
    auto grid = openvdb::FloatGrid::create(0.f);
    grid->setName("density");
    grid->setGridClass(openvdb::GRID_FOG_VOLUME);
    grid->setTransform(openvdb::math::Transform::createLinearTransform(vs));
    for (int x = 0; x < 15; ++x) {
        grid->denseFill(openvdb::CoordBBox(Coord(x, 0, 0), Coord(x, 14, 14)), density(x), true);
    }
    return grid;
}

TEST_F(RenderTest, CloudDensityIsInterpolatedBetweenVoxelCentres)
{
    // Density a + b x along x (index x, voxel size vs): a ray along z at x = 3.3 voxels
    // crosses the optical depth (a + 3.3 b) x 15 vs exactly (trilinear interpolation is exact
    // for a linear field, the tents along z add up to the 15 voxels, the midpoint steps
    // integrate it exactly); voxel cubes would give voxel 3's density, 9 % less here. Beyond
    // the last centre the density fades to 0 over one voxel: at x = -0.7, 0.3 a.
    const double vs = 0.1, a = 0.5, b = 0.5;
    const auto density = rampCloud(vs, [&](int x) { return float(a + b * x); });
    RenderOptions o;
    o.background = Vec3f(1.f);
    const Renderer renderer({density}, o);
    ASSERT_EQ(renderer.warnings().size(), 1u);   // no source: it only absorbs
    for (const double x : {3.3, 7.0, 11.75, -0.7, 14.2}) {
        const double sigma = x >= 0.0 && x <= 14.0 ? a + b * x
            : x < 0.0 ? (1.0 + x) * a : (15.0 - x) * (a + 14.0 * b);
        for (const double step : {0.5, 0.25}) {
            RenderOptions so = o;
            so.cloudStep = step;
            const Renderer r({density}, so);
            const Renderer::RayT ray(Vec3d(x * vs, 6.4 * vs, -1.0), Vec3d(0.0, 0.0, 1.0));
            const double T = std::exp(-sigma * 15.0 * vs);
            EXPECT_NEAR(r.radiance(ray)[0], T, 2e-6 * T) << "x " << x << " step " << step;
        }
    }
}

TEST_F(RenderTest, SolvedConservativeCloudVanishesIntoItsUniformSky)
{
    // Albedo 1 under a uniform sky L (a furnace): the light scattered towards the eye is L in
    // every direction, from the solved moments (Henyey-Greenstein g 0.7, order 4, written to
    // order 2 and 4, and an RGB solve's) or from J (isotropic), so every pixel is pi L wherever
    // the cloud is and however thick (1e-4: the solve's tolerance and the harmonic series'
    // rounding).
    grids::BuildParams p;
    p.res = 24;
    p.albedo = 1.f;
    openvdb::GridPtrVec cumulus = grids::makeCumulus(p);
    const double L = 0.7;
    for (const int order : {0, 2, 4, -1}) {
        if (order == -1) {
            // An RGB albedo (grey values): three solves, vec3s moments.
            const auto albedo = findGrid(cumulus, "albedo");
            ASSERT_TRUE(albedo && albedo->isType<openvdb::FloatGrid>());
            auto rgb = openvdb::Vec3SGrid::create(Vec3f(0.f));
            rgb->setName("albedo");
            rgb->setTransform(albedo->transform().copy());
            rgb->topologyUnion(static_cast<const openvdb::FloatGrid&>(*albedo));
            for (auto it = rgb->beginValueOn(); it; ++it) it.setValue(Vec3f(1.f));
            std::replace(cumulus.begin(), cumulus.end(),
                std::const_pointer_cast<openvdb::GridBase>(albedo), openvdb::GridBase::Ptr(rgb));
        }
        const Cloud cloud = buildCloud(cumulus);
        CloudTransferOptions o;
        o.irradiance = 0.0;
        o.sky = Sky::uniform(Vec3d(L));
        o.directions = 100;
        o.tolerance = 1e-7;
        if (order != 0) {
            o.phase = PhaseFunction::henyeyGreenstein(0.7);
            o.phaseOrder = 4;
        }
        openvdb::GridPtrVec sources;
        const openvdb::GridBase::Ptr J = solveCloud(cloud, o, nullptr, SolveControl(), nullptr,
            nullptr, &sources, order < 0 ? 2 : order);
        const int written = order < 0 ? 2 : order;
        ASSERT_EQ(sources.size(), size_t((written + 1) * (written + 1)));
        EXPECT_EQ(sources[0]->isType<openvdb::Vec3SGrid>(), order < 0);
        openvdb::GridPtrVec grids = cumulus;
        grids.push_back(J);
        grids.insert(grids.end(), sources.begin(), sources.end());
        RenderOptions ro;
        ro.width = ro.height = 24;
        ro.sky = o.sky;
        const Image image = renderImage(grids, ro);
        EXPECT_TRUE(image.warnings.empty());
        float lo = 1e30f, hi = 0.f, covered = 0.f;
        for (size_t i = 0; i < image.pixels.size(); ++i) {
            for (int c = 0; c < 3; ++c) {
                lo = std::min(lo, image.pixels[i][c]);
                hi = std::max(hi, image.pixels[i][c]);
            }
            covered = std::max(covered, image.coverage[i]);
        }
        EXPECT_GT(covered, 0.99f) << order;   // the cloud is opaque somewhere
        EXPECT_NEAR(lo, kPi * L, 1e-4 * kPi * L) << order;
        EXPECT_NEAR(hi, kPi * L, 1e-4 * kPi * L) << order;
        if (order == 4) {
            // Fewer of the moments (RenderOptions::cloudSourceOrder): the same furnace.
            ro.cloudSourceOrder = 1;
            const Image fewer = renderImage(grids, ro);
            for (const Vec3f& v : fewer.pixels) ASSERT_NEAR(v[0], kPi * L, 1e-4 * kPi * L);
        }
    }
}

TEST_F(RenderTest, SurfacesShadeTheCloudsSingleScattering)
{
    // A fog slab (16 x 2 x 16 voxels) under a high sun, a plane of surface voxels four voxels
    // above its half x <= 7 (a fog solved inside a scene: the renderer gets the scene's voxels
    // as blockers): no sun reaches the shaded half; the other half keeps the transmittance of
    // the fog above each centre, as without the plane (where the shadow rays pass beside it).
    const double vs = 0.1;
    auto density = openvdb::FloatGrid::create(0.f);
    density->setName("density");
    density->setGridClass(openvdb::GRID_FOG_VOLUME);
    density->setTransform(openvdb::math::Transform::createLinearTransform(vs));
    density->denseFill(openvdb::CoordBBox(Coord(0, 0, 0), Coord(15, 1, 15)), 2.f, true);
    const Cloud cloud = buildCloud({density});
    auto J = density->deepCopy();
    J->setName("mean_intensity");
    auto moment = density->deepCopy();
    moment->setName(ScatteredSource::gridName("mean_intensity", 0));
    moment->denseFill(openvdb::CoordBBox(Coord(0, 0, 0), Coord(15, 1, 15)), 0.f, true);
    ScatteredSource light;
    light.toSun = Vec3d(0.0, 1.0, 0.0);
    light.sunIrradiance = Vec3d(1.0);
    light.record(*J);
    openvdb::MaskTree plane;
    for (int x = 0; x <= 7; ++x) {
        for (int z = -2; z <= 17; ++z) plane.setValueOn(Coord(x, 6, z));
    }
    const VoxelIndex blockers(plane);
    const CloudShading unshaded(cloud, J, {density, J, moment});
    const CloudShading shaded(cloud, J, {density, J, moment}, 0.5, -1, &blockers);
    for (size_t i = 0; i < cloud.size(); ++i) {
        const Coord c = cloud.voxels().coord(i);
        // Above a centre of layer y: the rest of its voxel and the layer above, with the
        // interpolated density fading over one voxel beyond the last centre.
        const double depth = 2.0 * vs * (c.y() == 1 ? 0.5 : 1.5);
        EXPECT_NEAR(unshaded.sunTransmittance()[i][0], std::exp(-depth), 1e-6) << c;
        EXPECT_EQ(shaded.sunTransmittance()[i][0],
            c.x() <= 7 ? 0.f : unshaded.sunTransmittance()[i][0]) << c;
    }
}

TEST_F(RenderTest, CloudSingleScatteringUsesTheWholePhaseFunction)
{
    // A thin plane-parallel slab (periodic, 24 x 2 x 24 voxels, vertical optical depth 0.02,
    // albedo 0.5, Henyey-Greenstein g 0.877, sun 30 degrees from the zenith) solved at phase
    // order 8 (delta-M moves f = g^9 = 0.31 into the forward peak), seen from below at 20
    // degrees from the sunlight's direction and from above at 110 degrees. The sun's single
    // scattering is the slab formula in the delta-M scaled problem the solve solves (TMS):
    //     L = w / (1 - w f) F p(Theta) / 4pi
    //         x (1 / mu) int_0^tau' e^(-t / mu0) e^(-(tau' - t) / mu) dt
    // (tau' = (1 - w f) tau; reflected: the camera's path through the depth above t instead),
    // with the whole phase function p: the order-8 series differs by 40 % at 20 degrees.
    // With the solved moments zeroed the render is that alone (1e-4: the source is
    // interpolated between voxel centres, each with its own shadow ray; measured 6e-6 and
    // 2e-5); with them, multiple scattering adds a little (measured 0.4 % and 1.6 %).
    const double vs = 1.0 / 24.0, tau = 0.02, w = 0.5, g = 0.877;
    auto density = openvdb::FloatGrid::create(0.f);
    density->setName("density");
    density->setGridClass(openvdb::GRID_FOG_VOLUME);
    density->setTransform(openvdb::math::Transform::createLinearTransform(vs));
    density->denseFill(openvdb::CoordBBox(Coord(0, 0, 0), Coord(23, 1, 23)),
        float(tau / (2.0 * vs)), true);
    CloudOptions co;
    co.defaultAlbedo = float(w);
    const Cloud cloud = buildCloud({density}, co);
    CloudTransferOptions to;
    to.periodic = true;
    to.sunZenith = 30.0;
    to.phase = PhaseFunction::henyeyGreenstein(g);
    to.tolerance = 1e-7;
    openvdb::GridPtrVec sources;
    const openvdb::GridBase::Ptr J = solveCloud(cloud, to, nullptr, SolveControl(), nullptr,
        nullptr, &sources, 4);
    ASSERT_EQ(sources.size(), 25u);
    const double f = std::pow(g, 9.0), scaled = 1.0 - w * f, taus = tau * scaled;
    const PhaseFunction full = PhaseFunction::henyeyGreenstein(g);
    const double mu0 = std::cos(30.0 * kPi / 180.0);
    const Vec3d toSun(std::sin(30.0 * kPi / 180.0), mu0, 0.0);
    openvdb::GridPtrVec zeroed{density, J};
    for (const auto& m : sources) {
        auto z = openvdb::gridPtrCast<openvdb::FloatGrid>(m)->deepCopy();
        for (auto it = z->beginValueOn(); it; ++it) it.setValue(0.f);
        zeroed.push_back(z);
    }
    openvdb::GridPtrVec solved{density, J};
    solved.insert(solved.end(), sources.begin(), sources.end());
    RenderOptions o;
    o.cloud = co;
    const Vec3d centre(12.0 * vs, 0.5 * vs, 12.0 * vs);
    for (const double theta : {20.0, 110.0}) {
        // s: the direction of travel towards the eye, theta from the sunlight's (-toSun),
        // rotated about z.
        // (the sense of the rotation that keeps the view within 60 degrees of the vertical:
        // the ray then crosses the slab's top and bottom only).
        const Vec3d in = -toSun;
        Vec3d s;
        for (const double sense : {1.0, -1.0}) {
            const double t = sense * theta * kPi / 180.0, c = std::cos(t), sn = std::sin(t);
            s = Vec3d(in[0] * c - in[1] * sn, in[0] * sn + in[1] * c, 0.0);
            if (std::abs(s[1]) > 0.5) break;
        }
        const double mu = std::abs(s[1]);
        ASSERT_GT(mu, 0.5) << theta;
        // Far enough that the direction to the eye is the same from every voxel near the ray.
        const Vec3d eye = centre + s * 50.0;
        o.camera = Camera{eye, centre, Vec3d(0, 0, 1), 10.0};
        const double p = full.value(-toSun.dot(s));
        const bool below = s[1] < 0.0;
        // int_0^tau' e^(-t / mu0) e^(-(depth to the eye) / mu) dt, t the depth from the top.
        const double k = below ? 1.0 / mu0 - 1.0 / mu : 1.0 / mu0 + 1.0 / mu;
        const double integral = below ? std::exp(-taus / mu) * -std::expm1(-k * taus) / k
                                      : -std::expm1(-k * taus) / k;
        const double expected = kPi * w / scaled * p / (4.0 * kPi) * integral / mu;
        const Renderer alone(zeroed, o), all(solved, o);
        const Renderer::RayT ray(eye, -s);
        const double single = alone.radiance(ray)[0], total = all.radiance(ray)[0];
        EXPECT_NEAR(single, expected, 1e-4 * expected) << theta;
        EXPECT_GT(total, single) << theta;
        EXPECT_LT(total, 1.03 * single) << theta;
        // The truncated series would be far off: what the test tells apart.
        double series = 0.0;
        for (int l = 0; l <= 8; ++l) {
            series += (2 * l + 1) * (std::pow(g, l) - f) / (1.0 - f)
                * std::legendre(unsigned(l), -toSun.dot(s));
        }
        EXPECT_GT(std::abs(series * (1.0 - f) / p - 1.0), 0.1) << theta;
    }
}
