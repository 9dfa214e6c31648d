// The mesh-to-picture pipeline through the `vdbrad` tool: voxelize, solve, render, as a user
// runs them (pipes, Debian's vdb_tool and exrheader), and the errors each step gives.
#include "ToolTest.h"
#include "vdbrad/mesh/Mesh.h"
#include "vdbrad/mesh/Voxelizer.h"
#include "vdbrad/render/ImageIO.h"
#include "vdbrad/vdbrad.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <sstream>

using namespace vdbrad;

namespace {

using Result = test::ToolResult;
using test::exists;
using test::slurp;

class PipelineTest : public test::ToolTest
{
};

// A closed unit cube [o, o + 1]^3 with outward faces, an emitting material on its top face.
std::string
cubeObj(double o)
{
    std::ostringstream os;
    os << "mtllib cube.mtl\n";
    for (int i = 0; i < 8; ++i) {
        os << "v " << (i & 1 ? o + 1 : o) << " " << (i & 2 ? o + 1 : o) << " "
           << (i & 4 ? o + 1 : o) << "\n";
    }
    os << "usemtl grey\n"
          "f 1 5 7 3\nf 2 4 8 6\nf 1 2 6 5\nf 1 3 4 2\nf 5 6 8 7\n"
          "usemtl lamp\n"
          "f 3 7 8 4\n";
    return os.str();
}

const char* kCubeMtl = "newmtl grey\nKd 0.5 0.5 0.5\nnewmtl lamp\nKd 0.5 0.5 0.5\nKe 2 2 2\n";

TEST_F(PipelineTest, VoxelizeWritesTheSceneOfAMesh)
{
    // Voxel size 1/16, cube shifted by 0.3 voxel: the 17^3 - 15^3 shell (see test_voxelizer).
    // The top face's 17 x 17 voxels emit 2: every voxel holding part of the lamp's face,
    // including its rim, which a side face is as close to (emission_area says how much of the
    // face each holds).
    const double h = 1.0 / 16;
    writeText("cube.obj", cubeObj(0.3 * h));
    writeText("cube.mtl", kCubeMtl);
    const Result r = sh("vdbrad voxelize cube.obj cube.vdb --voxel-size 0.0625 && "
                        "vdbrad info cube.vdb");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("1,538 surface voxels from normal grid 'normal'"), std::string::npos)
        << r.out;
    EXPECT_NE(r.out.find("emission:  grey grid, values in [0, 2], 289 non-zero voxels"),
        std::string::npos) << r.out;
    EXPECT_NE(r.err.find("1,538 surface voxels, voxel size 0.0625, 26-separating"),
        std::string::npos) << r.err;
    // The same as the library call.
    const VdbFile file = readVdbFile(path("cube.vdb"));
    VoxelizeOptions o;
    o.voxelSize = h;
    const openvdb::GridPtrVec direct = voxelizeMesh(readMesh(path("cube.obj")), o);
    ASSERT_EQ(file.grids.size(), direct.size());
    for (size_t g = 0; g < direct.size(); ++g) {
        EXPECT_EQ(file.grids[g]->getName(), direct[g]->getName());
        EXPECT_EQ(file.grids[g]->activeVoxelCount(), direct[g]->activeVoxelCount());
    }
}

TEST_F(PipelineTest, VoxelizeErrorsGiveOneLineAndNoOutput)
{
    writeText("cube.obj", cubeObj(0.0));
    writeText("cube.mtl", kCubeMtl);
    writeText("bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 9\n");
    struct Case { std::string args, message; int status; };
    const std::vector<Case> cases = {
        {"missing.obj out.vdb", "missing.obj", 1},
        {"bad.obj out.vdb", "bad.obj:4", 1},
        {"cube.obj out.vdb --res 0", "--res must be in [1, 16384]", 2},
        {"cube.obj out.vdb --res 64 --voxel-size 0.1", "not both", 2},
        {"cube.obj out.vdb --separation 18", "--separation must be 6 or 26", 2},
        {"cube.obj out.vdb --voxel-size 1e-7", "above the limit", 1},
        {"cube.obj nowhere/out.vdb", "does not exist", 1},
        {"- out.vdb", "the mesh must be a file", 2},
    };
    for (const Case& c : cases) {
        const Result r = sh("vdbrad voxelize " + c.args);
        EXPECT_EQ(r.status, c.status) << c.args << "\n" << r.err;
        // One error line, the last (a progress line may precede it).
        EXPECT_EQ(r.err.find("error"), r.err.rfind("error")) << c.args << "\n" << r.err;
        const size_t last = r.err.rfind('\n', r.err.size() - 2);
        EXPECT_EQ(r.err.find("vdbrad: error: "), last == std::string::npos ? 0 : last + 1)
            << r.err;
        EXPECT_NE(r.err.find(c.message), std::string::npos) << c.args << "\n" << r.err;
        EXPECT_FALSE(exists(path("out.vdb"))) << c.args;
    }
}

TEST_F(PipelineTest, LevelSetFromVdbToolMeshToLevelSetSolves)
{
    ASSERT_EQ(std::system("command -v vdb_tool > /dev/null"), 0) << "vdb_tool not installed";
    // Debian's vdb_tool turns a closed mesh (a tilted cube) into a level set. Give every surface
    // voxel emission 1 (an emission grid whose background is 1): a convex solid sees nothing of
    // itself, so every radiosity must stay E = 1, whatever the albedo, but for the steps of the
    // digital surface along the tilted edges (measured: at most 1.004 at albedo 0.9).
    std::ostringstream obj;
    const double c = std::cos(0.6), s = std::sin(0.6);
    for (int i = 0; i < 8; ++i) {
        const double x = i & 1 ? 0.5 : -0.5, y = i & 2 ? 0.5 : -0.5, z = i & 4 ? 0.5 : -0.5;
        obj << "v " << c * x - s * y << " " << s * x + c * y << " " << z + 0.1 * x << "\n";
    }
    obj << "f 1 5 7 3\nf 2 4 8 6\nf 1 2 6 5\nf 3 7 8 4\nf 1 3 4 2\nf 5 6 8 7\n";
    writeText("solid.obj", obj.str());
    Result r = sh("vdb_tool -quiet -read solid.obj -mesh2ls voxel=0.02 -write ls.vdb");
    ASSERT_EQ(r.status, 0) << r.err;
    VdbFile file = readVdbFile(path("ls.vdb"));
    ASSERT_EQ(file.grids.size(), 1u);
    EXPECT_EQ(file.grids[0]->getGridClass(), openvdb::GRID_LEVEL_SET);
    openvdb::FloatGrid::Ptr emission = openvdb::FloatGrid::create(1.f);
    emission->setName("emission");
    emission->setTransform(file.grids[0]->transform().copy());
    file.grids.push_back(emission);
    writeVdbFile(file, path("lit_ls.vdb"));
    r = sh("vdbrad solve lit_ls.vdb - --albedo 0.9 --quiet | vdbrad info -");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("from level set 'mesh2ls_solid'"), std::string::npos) << r.out;
    const size_t at = r.out.find("radiosity: float, values in [");
    ASSERT_NE(at, std::string::npos) << r.out;
    double lo = 0, hi = 0;
    ASSERT_EQ(std::sscanf(r.out.c_str() + at, "radiosity: float, values in [%lf, %lf]", &lo, &hi), 2);
    EXPECT_EQ(lo, 1.0);
    EXPECT_LE(hi, 1.01);
}

TEST_F(PipelineTest, CornellMeshChainShowsColourBleeding)
{
    // The README's chain on the sample Cornell box: voxelize | solve | render, over pipes.
    const std::string mesh = std::string(VDBRAD_SOURCE_DIR) + "/samples/meshes/cornell_box.obj";
    const Result r = sh("vdbrad voxelize '" + mesh + "' - --res 48 --quiet | vdbrad solve - - "
        "--directions 300 --tolerance 1e-3 --quiet | tee lit.vdb | vdbrad render - box.exr "
        "--res 160x120 --exr-type float --png box.png --quiet --mesh '" + mesh + "'");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(r.err, "");
    if (std::system("command -v exrheader > /dev/null") == 0) {
        const Result h = sh("exrheader box.exr");
        EXPECT_EQ(h.status, 0) << h.err;
        EXPECT_NE(h.out.find("dataWindow (type box2i): (0 0) - (159 119)"), std::string::npos)
            << h.out;
        EXPECT_NE(h.out.find("32-bit floating-point"), std::string::npos) << h.out;
    } else {
        ADD_FAILURE() << "exrheader (Debian package openexr) is not installed";
    }
    EXPECT_EQ(slurp(path("box.png")).substr(1, 3), "PNG");

    // Which pixels show the ceiling, and where: the default camera's rays, met with the
    // ceiling's plane (y = 0.5488 m; the red wall is at x = 0.556, the green one at x = 0).
    const VdbFile lit = readVdbFile(path("lit.vdb"));
    RenderOptions o;
    o.width = 160;
    o.height = 120;
    const Renderer renderer(lit.grids, o);
    const Image image = decodeExr(slurp(path("box.exr")));
    ASSERT_EQ(image.width, 160);
    ASSERT_EQ(image.height, 120);
    openvdb::Vec3d nearRed(0.0), nearGreen(0.0);
    int redCount = 0, greenCount = 0;
    for (int y = 0; y < image.height; ++y) {
        for (int x = 0; x < image.width; ++x) {
            const auto ray = renderer.primaryRay(x + 0.5, y + 0.5);
            if (!(ray.dir()[1] > 0.0)) continue;
            const openvdb::Vec3d p = ray(( 0.5488 - ray.eye()[1]) / ray.dir()[1]);
            // Ceiling pixels only: in front of the back wall, clear of the light and the rims.
            if (p[2] < 0.05 || p[2] > 0.5 || (p[0] > 0.18 && p[0] < 0.38)) continue;
            const openvdb::Vec3f c = image.at(x, y);
            if (p[0] > 0.42 && p[0] < 0.54) { nearRed += openvdb::Vec3d(c); ++redCount; }
            if (p[0] > 0.016 && p[0] < 0.136) { nearGreen += openvdb::Vec3d(c); ++greenCount; }
        }
    }
    ASSERT_GT(redCount, 100);
    ASSERT_GT(greenCount, 100);
    // The white ceiling (albedo 0.73 grey) takes the colour of the wall beside it: redder than
    // green near the red wall, greener than red near the green wall, and each side redder
    // (greener) than the other.
    const double redness = nearRed[0] / nearRed[1], greenness = nearGreen[1] / nearGreen[0];
    std::printf("ceiling R/G near the red wall %.3f, G/R near the green wall %.3f\n", redness,
        greenness);
    EXPECT_GT(redness, 1.05) << nearRed;
    EXPECT_GT(greenness, 1.05) << nearGreen;
    EXPECT_GT(redness, nearGreen[0] / nearGreen[1] * 1.1);
    EXPECT_GT(greenness, nearRed[1] / nearRed[0] * 1.1);
}

TEST_F(PipelineTest, RenderErrorsGiveOneLineAndKeepOutputs)
{
    const std::string mesh = std::string(VDBRAD_SOURCE_DIR) + "/samples/meshes/cornell_box.obj";
    Result r = sh("vdbrad voxelize '" + mesh + "' scene.vdb --res 16 --quiet && vdbrad solve "
        "scene.vdb lit.vdb --directions 50 --quiet");
    ASSERT_EQ(r.status, 0) << r.err;
    writeText("out.exr", "keep");
    writeText("out.png", "keep");
    writeText("far.obj", "v 5 0 0\nv 6 0 0\nv 5 1 0\nf 1 2 3\n");
    struct Case { std::string args, message; int status; };
    const std::vector<Case> cases = {
        {"missing.vdb out.exr", "missing.vdb", 1},
        {"scene.vdb out.exr", "no radiosity grid", 1},
        {"lit.vdb out.exr --res 0x10", "--res must be WIDTHxHEIGHT", 2},
        {"lit.vdb out.exr --res 640", "--res must be WIDTHxHEIGHT", 2},
        {"lit.vdb out.exr --camera 1,2,3", "--camera needs 10", 2},
        {"lit.vdb out.exr --camera 0,0,0,0,x,0,0,1,0,40", "'x' is not a number", 2},
        {"lit.vdb out.exr --camera 0,0,0,0,0,0,0,1,0,40", "lit.vdb", 1},
        {"lit.vdb out.exr --camera 0,0,-1,0,0,0,0,1,0,180", "field of view", 2},
        {"lit.vdb out.exr --aa 0", "--aa must be in [1, 16]", 2},
        {"lit.vdb out.exr --exr-type double", "--exr-type must be half or float", 2},
        {"lit.vdb out.exr --png -", "--png needs a file name", 2},
        {"lit.vdb out.exr --background 1,1", "--background needs 3", 2},
        {"lit.vdb nowhere/out.exr", "does not exist", 1},
        {"lit.vdb out.exr --mesh missing.obj", "missing.obj: cannot open", 1},
        {"lit.vdb out.exr --mesh -", "--mesh must be a file", 2},
        {"lit.vdb out.exr --mesh far.obj", "is not within the surface's voxels", 1},
    };
    for (const Case& c : cases) {
        const bool png = c.args.find("--png") != std::string::npos;
        r = sh("vdbrad render " + c.args + (png ? "" : " --png out.png") + " --overwrite");
        EXPECT_EQ(r.status, c.status) << c.args << "\n" << r.err;
        EXPECT_EQ(r.err.find("error"), r.err.rfind("error")) << c.args << "\n" << r.err;
        EXPECT_EQ(r.err.rfind("vdbrad: error: ", 0), 0u) << c.args << "\n" << r.err;
        EXPECT_NE(r.err.find(c.message), std::string::npos) << c.args << "\n" << r.err;
        EXPECT_TRUE(slurp(path("out.exr")) == "keep") << c.args;
        EXPECT_TRUE(slurp(path("out.png")) == "keep") << c.args;
    }
    // And the same command without the mistake replaces both.
    r = sh("vdbrad render lit.vdb out.exr --png out.png --res 32x24 --quiet");
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(decodeExr(slurp(path("out.exr"))).width, 32);
}

TEST_F(PipelineTest, CumulusSolvesConservesEnergyAndRenders)
{
    // The procedural cumulus (conservative, optical diameter 20) through solve-cloud and render.
    const Result r = sh("vdbrad make cumulus - --res 24 --quiet | vdbrad solve-cloud - lit.vdb "
        "--sun 30,45 --directions 111 --tolerance 1e-6 --quiet && vdbrad render lit.vdb c.exr "
        "--res 64x48 --exr-type float --background 0.2,0.3,0.5 --quiet");
    ASSERT_EQ(r.status, 0) << r.err;
    const VdbFile lit = readVdbFile(path("lit.vdb"));
    openvdb::GridBase::ConstPtr J = findGrid(lit.grids, "mean_intensity");
    ASSERT_TRUE(J);
    EXPECT_EQ(J->activeVoxelCount(), findGrid(lit.grids, "density")->activeVoxelCount());
    const double R = J->metaValue<float>("vdbrad:albedo");
    const double T = J->metaValue<float>("vdbrad:transmittance");
    const double A = J->metaValue<float>("vdbrad:absorptance");
    EXPECT_NEAR(R + T + A, 1.0, 1e-4);   // the energy balance
    EXPECT_EQ(A, 0.0);                   // albedo 1: nothing absorbed
    EXPECT_GT(R, 0.05);
    EXPECT_GT(J->metaValue<int>("vdbrad:iterations"), 1);
    // The cloud hides the background where it is thick and glows where lit: the image differs
    // from the plain background, and every pixel is finite and non-negative.
    const Image image = decodeExr(slurp(path("c.exr")));
    int changed = 0;
    for (const openvdb::Vec3f& c : image.pixels) {
        ASSERT_TRUE(std::isfinite(c[0]) && c[0] >= 0.f);
        if (std::abs(c[2] - 0.5f) > 0.01f) ++changed;
    }
    EXPECT_GT(changed, 200);
}

TEST_F(PipelineTest, SolveCloudErrorsGiveOneLine)
{
    Result r = sh("vdbrad make cumulus c.vdb --res 8 --quiet && vdbrad make cornell s.vdb --res 8 "
        "--quiet");
    ASSERT_EQ(r.status, 0) << r.err;
    struct Case { std::string args, message; int status; };
    const std::vector<Case> cases = {
        {"s.vdb out.vdb", "density", 1},
        {"c.vdb out.vdb --sun 95,0", "zenith angle must be in [0, 89.9]", 2},
        {"c.vdb out.vdb --sun 30", "--sun needs 2", 2},
        {"c.vdb out.vdb --up w", "--up must be x, y or z", 2},
        {"c.vdb out.vdb --albedo 1.5", "--albedo must be in [0, 1]", 2},
        {"c.vdb out.vdb --extinction-scale 0", "--extinction-scale must be > 0", 2},
        {"c.vdb out.vdb --directions 0", "--directions must be auto or a count in [1, ", 2},
        {"c.vdb out.vdb --output-name ''", "--output-name must not be empty", 2},
        {"c.vdb out.vdb --g 1", "--g must be in (-1, 1)", 2},
        {"c.vdb out.vdb --legendre 0.5,0.2", "chi_0 = 1", 2},
        {"c.vdb out.vdb --legendre 1,x", "'x' is not a number", 2},
        {"c.vdb out.vdb --g 0.5 --legendre 1,0.5", "give one of --g", 2},
        {"c.vdb out.vdb --phase-order 40", "--phase-order must be auto or an order in [0, 32]", 2},
    };
    for (const Case& c : cases) {
        r = sh("vdbrad solve-cloud " + c.args);
        EXPECT_EQ(r.status, c.status) << c.args << "\n" << r.err;
        EXPECT_EQ(r.errLines().size(), 1u) << c.args << "\n" << r.err;
        EXPECT_NE(r.err.find(c.message), std::string::npos) << c.args << "\n" << r.err;
        EXPECT_FALSE(exists(path("out.vdb"))) << c.args;
    }
}

} // namespace
