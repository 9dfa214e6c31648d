// Mesh: OBJ/MTL and PLY reading (exact points, windings, materials, every error path) and the
// sample meshes in samples/meshes.
#include "vdbrad/core/GridContract.h"
#include "vdbrad/mesh/Mesh.h"
#include "vdbrad/mesh/Voxelizer.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

using namespace vdbrad;
using openvdb::Vec3d;
using openvdb::Vec3f;
using openvdb::Vec3I;

namespace {

std::string
path(const std::string& name)
{
    return ::testing::TempDir() + "vdbrad_mesh_" + name;
}

std::string
write(const std::string& name, const std::string& bytes)
{
    const std::string p = path(name);
    std::ofstream f(p, std::ios::binary);
    f << bytes;
    return p;
}

/// The unit cube [0,1]^3: 8 corners, 6 quads counter-clockwise seen from outside.
const char* const kCubeVertices[] = {"0 0 0", "1 0 0", "1 1 0", "0 1 0",
                                     "0 0 1", "1 0 1", "1 1 1", "0 1 1"};
const int kCubeQuads[6][4] = {
    {0, 3, 2, 1}, {4, 5, 6, 7}, {0, 1, 5, 4}, {3, 7, 6, 2}, {0, 4, 7, 3}, {1, 2, 6, 5}};

std::string
cubeObj()
{
    std::ostringstream os;
    os << "# unit cube\n";
    for (const char* v : kCubeVertices) os << "v " << v << "\n";
    for (const auto& q : kCubeQuads) {
        os << "f " << q[0] + 1 << " " << q[1] + 1 << " " << q[2] + 1 << " " << q[3] + 1 << "\n";
    }
    return os.str();
}

Vec3d
normalOf(const TriangleMesh& m, size_t t)
{
    const Vec3d a(m.points[m.triangles[t][0]]), b(m.points[m.triangles[t][1]]),
        c(m.points[m.triangles[t][2]]);
    return (b - a).cross(c - a);
}

/// Signed volume (divergence theorem): positive for a closed mesh wound outwards.
double
signedVolume(const TriangleMesh& m)
{
    double v = 0;
    for (const Vec3I& t : m.triangles) {
        v += Vec3d(m.points[t[0]]).dot(Vec3d(m.points[t[1]]).cross(Vec3d(m.points[t[2]])));
    }
    return v / 6.0;
}

/// Every edge used exactly twice, once in each direction: closed with a consistent winding.
bool
watertight(const TriangleMesh& m)
{
    std::map<std::pair<uint32_t, uint32_t>, int> edges;
    for (const Vec3I& t : m.triangles) {
        for (int e = 0; e < 3; ++e) ++edges[{t[e], t[(e + 1) % 3]}];
    }
    for (const auto& [e, n] : edges) {
        if (n != 1 || edges.count({e.second, e.first}) == 0) return false;
    }
    return true;
}

void
expectSameMesh(const TriangleMesh& a, const TriangleMesh& b)
{
    ASSERT_EQ(a.points.size(), b.points.size());
    ASSERT_EQ(a.triangles.size(), b.triangles.size());
    for (size_t i = 0; i < a.points.size(); ++i) EXPECT_EQ(a.points[i], b.points[i]) << i;
    for (size_t i = 0; i < a.triangles.size(); ++i) EXPECT_EQ(a.triangles[i], b.triangles[i]) << i;
    EXPECT_EQ(a.triangleMaterials, b.triangleMaterials);
}

/// Expects @a f to throw @a E whose message contains @a text.
template<typename E, typename F>
void
expectThrowWith(F&& f, const std::string& text)
{
    try {
        f();
        ADD_FAILURE() << "no exception; expected one containing \"" << text << "\"";
    } catch (const E& e) {
        EXPECT_NE(std::string(e.what()).find(text), std::string::npos)
            << "message: " << e.what() << "\nexpected to contain: " << text;
    } catch (const std::exception& e) {
        ADD_FAILURE() << "wrong exception type: " << e.what();
    }
}

// ---- binary PLY writing ------------------------------------------------------------------------

struct Bytes
{
    bool big;
    std::string data;

    template<typename T> void put(T v)
    {
        char b[sizeof(T)];
        std::memcpy(b, &v, sizeof(T));
        const uint16_t one = 1;
        const bool hostLittle = *reinterpret_cast<const unsigned char*>(&one) == 1;
        if (big == hostLittle) std::reverse(b, b + sizeof(T));
        data.append(b, sizeof(T));
    }
};

/// The cube as PLY: float x y z, faces as a uchar-counted int list. @a extra adds an "edge"
/// element between vertices and faces and a float list on the faces, which must be skipped.
std::string
cubePly(const std::string& format, bool extra = false)
{
    std::ostringstream h;
    h << "ply\nformat " << format << " 1.0\ncomment made by test_mesh\nobj_info cube\n"
      << "element vertex 8\nproperty float x\nproperty float y\nproperty float z\n";
    if (extra) {
        h << "element edge 3\nproperty int vertex1\nproperty int32 vertex2\n"
          << "property list ushort double weights\nproperty uchar red\n";
    }
    h << "element face 6\nproperty list uchar int vertex_indices\n";
    if (extra) h << "property list int float texcoord\n";
    h << "end_header\n";
    if (format == "ascii") {
        for (const char* v : kCubeVertices) h << v << "\n";
        if (extra) h << "0 1 2 0.5 0.25 7\n1 2 0 255\n2 3 1 1.5 9\n";
        for (const auto& q : kCubeQuads) {
            h << "4 " << q[0] << " " << q[1] << " " << q[2] << " " << q[3];
            h << (extra ? " 2 0.5 0.5\n" : "\n");
        }
        return h.str();
    }
    Bytes b{format == "binary_big_endian", h.str()};
    for (const char* v : kCubeVertices) {
        std::istringstream in(v);
        float x, y, z;
        in >> x >> y >> z;
        b.put(x); b.put(y); b.put(z);
    }
    if (extra) {
        // vertex1, vertex2, a list of 0..2 doubles, red
        for (int e = 0; e < 3; ++e) {
            b.put(int32_t(e)); b.put(int32_t(e + 1));
            b.put(uint16_t(e));
            for (int k = 0; k < e; ++k) b.put(double(k) + 0.5);
            b.put(uint8_t(7 * e));
        }
    }
    for (const auto& q : kCubeQuads) {
        b.put(uint8_t(4));
        for (int k = 0; k < 4; ++k) b.put(int32_t(q[k]));
        if (extra) { b.put(int32_t(2)); b.put(0.5f); b.put(0.5f); }
    }
    return b.data;
}

} // namespace

// ---- OBJ ---------------------------------------------------------------------------------------

TEST(ObjTest, CubeOfQuadsGivesTwelveOutwardTrianglesWithExactPoints)
{
    const TriangleMesh m = readObj(write("cube.obj", cubeObj()));
    ASSERT_EQ(m.points.size(), 8u);
    ASSERT_EQ(m.triangles.size(), 12u);   // 6 quads, 2 triangles each
    EXPECT_EQ(m.points[0], Vec3f(0, 0, 0));
    EXPECT_EQ(m.points[6], Vec3f(1, 1, 1));
    EXPECT_EQ(m.points[3], Vec3f(0, 1, 0));
    // First quad 1 4 3 2 (0-based 0 3 2 1) fans into (0,3,2), (0,2,1); it is the z = 0 face,
    // wound clockwise seen from +z, so its normal is exactly -z.
    EXPECT_EQ(m.triangles[0], Vec3I(0, 3, 2));
    EXPECT_EQ(m.triangles[1], Vec3I(0, 2, 1));
    EXPECT_EQ(normalOf(m, 0), Vec3d(0, 0, -1));
    EXPECT_EQ(normalOf(m, 11), Vec3d(1, 0, 0));   // last quad: x = 1
    for (size_t t = 0; t < m.triangles.size(); ++t) {
        const Vec3I& tri = m.triangles[t];
        const Vec3d centroid =
            (Vec3d(m.points[tri[0]]) + Vec3d(m.points[tri[1]]) + Vec3d(m.points[tri[2]])) / 3.0;
        EXPECT_GT(normalOf(m, t).dot(centroid - Vec3d(0.5)), 0.0) << "triangle " << t;
    }
    EXPECT_DOUBLE_EQ(signedVolume(m), 1.0);
    EXPECT_TRUE(watertight(m));
    EXPECT_FALSE(m.hasMaterials());
    EXPECT_TRUE(m.triangleMaterials.empty());
}

TEST(ObjTest, NegativeIndicesCountBackFromTheLastVertexSoFar)
{
    const TriangleMesh m = readObj(write("negative.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nf -3 -2 -1\nv 5 5 5\nf -4 -1 -2\nf 1 -1 2\n"));
    ASSERT_EQ(m.triangles.size(), 3u);
    EXPECT_EQ(m.triangles[0], Vec3I(0, 1, 2));
    EXPECT_EQ(m.triangles[1], Vec3I(0, 3, 2));   // -1 is now vertex 4 (0-based 3)
    EXPECT_EQ(m.triangles[2], Vec3I(0, 3, 1));
}

TEST(ObjTest, TexcoordAndNormalFormsUseOnlyTheVertexIndex)
{
    const TriangleMesh m = readObj(write("forms.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 0 1\nvn 0 0 1\n"
        "f 1/1 2/2 3/3\nf 2//1 4//1 3//1\nf 1/3/1 2/2/1 4/1/1\nf -4/-3/-1 -3/-2/-1 -2/-1/-1\n"));
    ASSERT_EQ(m.triangles.size(), 4u);
    EXPECT_EQ(m.triangles[0], Vec3I(0, 1, 2));
    EXPECT_EQ(m.triangles[1], Vec3I(1, 3, 2));
    EXPECT_EQ(m.triangles[2], Vec3I(0, 1, 3));
    EXPECT_EQ(m.triangles[3], Vec3I(0, 1, 2));
}

TEST(ObjTest, PolygonsAreFanTriangulatedAndDegenerateTrianglesKept)
{
    const TriangleMesh m = readObj(write("pentagon.obj",
        "v 0 0 0\nv 2 0 0\nv 3 1 0\nv 1 2 0\nv -1 1 0\nf 1 2 3 4 5\nf 1 1 2\n"));
    ASSERT_EQ(m.triangles.size(), 4u);
    EXPECT_EQ(m.triangles[0], Vec3I(0, 1, 2));
    EXPECT_EQ(m.triangles[1], Vec3I(0, 2, 3));
    EXPECT_EQ(m.triangles[2], Vec3I(0, 3, 4));
    EXPECT_EQ(m.triangles[3], Vec3I(0, 0, 1));   // zero area: the voxelizer skips it
    for (int t = 0; t < 3; ++t) EXPECT_GT(normalOf(m, t).z(), 0.0);
}

TEST(ObjTest, SyntaxVariantsAndIgnoredStatements)
{
    // CRLF, tabs, a w coordinate, vertex colours, a continued face, comments anywhere, and
    // statements that carry nothing for the voxelizer.
    const std::string text =
        "# exported\r\n\r\nmtllib\tnone_loaded.mtl\r\no thing\r\ng group1 group2\r\ns off\r\n"
        "v\t0 0 0 1.0\r\nv 1.5 0 0 0.2 0.3 0.4\r\nv 0 +2 -0 # comment\r\nv 1e0 1E0 .5\r\n"
        "vp 0.5\r\ncstype bezier\r\nl 1 2\r\np 3\r\nusemtl whatever\r\n"
        "f 1 2 \\\r\n 3\r\nf 2 4 3 # comment\r\nfoo bar 1 2 3\r\n";
    std::istringstream in(text);
    // No folder: mtllib is skipped and usemtl ignored.
    const TriangleMesh m = readObj(in, "variants.obj", "");
    ASSERT_EQ(m.points.size(), 4u);
    EXPECT_EQ(m.points[1], Vec3f(1.5f, 0, 0));
    EXPECT_EQ(m.points[2], Vec3f(0, 2, 0));
    EXPECT_EQ(m.points[3], Vec3f(1, 1, 0.5f));
    ASSERT_EQ(m.triangles.size(), 2u);
    EXPECT_EQ(m.triangles[0], Vec3I(0, 1, 2));
    EXPECT_EQ(m.triangles[1], Vec3I(1, 3, 2));
    EXPECT_TRUE(m.triangleMaterials.empty());
}

TEST(ObjTest, PositiveIndicesMayReferToLaterVertices)
{
    const TriangleMesh m = readObj(write("forward.obj", "f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"));
    ASSERT_EQ(m.triangles.size(), 1u);
    EXPECT_EQ(m.triangles[0], Vec3I(0, 1, 2));
}

TEST(ObjTest, MtlColoursAndEmissionPerTriangle)
{
    write("colours.mtl",
        "# materials\nnewmtl red\nKa 0 0 0\nKd 0.8 0.1 0.05\nNs 10\nillum 2\nmap_Kd red.png\n\n"
        "newmtl lamp\r\nKd 0.73 0.73 0.73\r\nKe 17 12 4\r\n"
        "newmtl grey\nKD 0.25\n"
        "newmtl plain\n");
    const TriangleMesh m = readObj(write("colours.obj",
        "mtllib vdbrad_mesh_colours.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
        "f 1 2 3\nusemtl red\nf 2 4 3\nf 1 2 4\nusemtl lamp\nf 1 2 3 4\n"
        "usemtl grey\nf 3 2 1\nusemtl plain\nf 4 2 1\n"));
    ASSERT_EQ(m.materials.size(), 4u);
    EXPECT_EQ(m.materials[0].name, "red");
    EXPECT_EQ(m.materials[0].albedo, Vec3f(0.8f, 0.1f, 0.05f));
    EXPECT_EQ(m.materials[0].emission, Vec3f(0.f));
    EXPECT_EQ(m.materials[1].name, "lamp");
    EXPECT_EQ(m.materials[1].albedo, Vec3f(0.73f));
    EXPECT_EQ(m.materials[1].emission, Vec3f(17.f, 12.f, 4.f));
    EXPECT_EQ(m.materials[2].albedo, Vec3f(0.25f));   // one Kd value is grey
    EXPECT_EQ(m.materials[3].albedo, Vec3f(0.5f));    // no Kd: vdbrad's default albedo
    // Before any usemtl: -1; the quad under "lamp" gives two triangles.
    EXPECT_EQ(m.triangleMaterials, (std::vector<int32_t>{-1, 0, 0, 1, 1, 2, 3}));
}

TEST(ObjTest, GlossyMaterialsFromKsNsAndPr)
{
    // Ks: the lobe's reflectance (grey or RGB); Ns: the Phong exponent -> roughness
    // sqrt(sqrt(2 / (Ns + 2))); Pr (PBR roughness) wins over Ns in either order.
    write("glossy.mtl",
        "newmtl shiny\nKd 0.2\nKs 0.5 0.6 0.7\nNs 30\n"
        "newmtl pbr\nPr 0.3\nKs 0.4\nNs 1000\n"
        "newmtl plain\nKd 0.7\n"
        "newmtl hot\nKd 0.8\nKs 0.5\n");
    const TriangleMesh m = readObj(write("glossy.obj",
        "mtllib vdbrad_mesh_glossy.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
        "usemtl shiny\nf 1 2 3\nusemtl pbr\nf 1 2 3\nusemtl plain\nf 1 2 3\n"
        "usemtl hot\nf 1 2 3\n"));
    ASSERT_EQ(m.materials.size(), 4u);
    EXPECT_TRUE(m.hasSpecular());
    EXPECT_EQ(m.materials[0].specular, Vec3f(0.5f, 0.6f, 0.7f));
    EXPECT_NEAR(m.materials[0].roughness, 0.5f, 1e-6f);
    EXPECT_EQ(m.materials[1].specular, Vec3f(0.4f));
    EXPECT_NEAR(m.materials[1].roughness, 0.3f, 1e-6f);
    EXPECT_EQ(m.materials[2].specular, Vec3f(0.f));
    EXPECT_NEAR(m.materials[0].reflectance(), 0.9f, 1e-6f);
    // Kd + Ks = 1.3: the voxelizer scales both by 1 / 1.3.
    EXPECT_NEAR(m.materials[3].reflectance(), 1.3f, 1e-6f);
    VoxelizeOptions o;
    o.resolution = 8;
    const openvdb::GridPtrVec grids = voxelizeMesh(m, o);
    auto find = [&](const char* name) { return findGrid(grids, name); };
    ASSERT_TRUE(find("specular") && find("roughness"));
    EXPECT_EQ(find("specular")->valueType(), "vec3s");   // shiny's Ks is not grey
    o.specular = false;
    const openvdb::GridPtrVec diffuse = voxelizeMesh(m, o);
    EXPECT_FALSE(findGrid(diffuse, "specular"));
    EXPECT_FALSE(findGrid(diffuse, "roughness"));
    // Ks outside [0, 1], Pr outside [0, 1], Ns negative or missing: errors naming the line.
    for (const char* bad : {"Ks 1.5", "Pr 2", "Ns -1", "Ns"}) {
        write("bad.mtl", std::string("newmtl x\n") + bad + "\n");
        try {
            readObj(write("bad.obj", "mtllib vdbrad_mesh_bad.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                "f 1 2 3\n"));
            ADD_FAILURE() << bad;
        } catch (const openvdb::ValueError& e) {
            EXPECT_NE(std::string(e.what()).find("bad.mtl:2"), std::string::npos) << e.what();
        }
    }
}

TEST(ObjTest, SeveralLibrariesOnOneLineFirstDefinitionWins)
{
    write("libA.mtl", "newmtl a\nKd 1 0 0\nnewmtl shared\nKd 0.1 0.2 0.3\n");
    write("libB.mtl", "newmtl b\nKd 0 1 0\nnewmtl shared\nKd 0.9 0.9 0.9\nKe 5\n");
    const TriangleMesh m = readObj(write("twolibs.obj",
        "mtllib vdbrad_mesh_libA.mtl vdbrad_mesh_libB.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
        "usemtl b\nf 1 2 3\nusemtl shared\nf 1 2 3\nusemtl a\nf 1 2 3\n"));
    ASSERT_EQ(m.materials.size(), 3u);
    EXPECT_EQ(m.materials[m.triangleMaterials[0]].albedo, Vec3f(0, 1, 0));
    EXPECT_EQ(m.materials[m.triangleMaterials[1]].albedo, Vec3f(0.1f, 0.2f, 0.3f));
    EXPECT_EQ(m.materials[m.triangleMaterials[1]].emission, Vec3f(0.f));
    EXPECT_EQ(m.materials[m.triangleMaterials[2]].albedo, Vec3f(1, 0, 0));
}

TEST(ObjTest, UsemtlWithoutLibraryMeansNoMaterial)
{
    const TriangleMesh m =
        readObj(write("nolib.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl red\nf 1 2 3\n"));
    EXPECT_FALSE(m.hasMaterials());
    EXPECT_TRUE(m.triangleMaterials.empty());
}

TEST(ObjTest, UnknownMaterialIsAnErrorNamingIt)
{
    write("known.mtl", "newmtl white\nKd 1 1 1\n");
    const std::string p = write("unknown.obj",
        "mtllib vdbrad_mesh_known.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\nusemtl blue\nf 1 2 3\n");
    expectThrowWith<openvdb::ValueError>([&] { readObj(p); },
        p + ":5: unknown material 'blue'");
}

TEST(ObjTest, IndexOutOfRangeNamesFileAndLine)
{
    const std::string p = write("range.obj", "v 0 0 0\nv 1 0 0\n\nv 0 1 0\nf 1 2 9\n");
    expectThrowWith<openvdb::ValueError>([&] { readObj(p); },
        p + ":5: face index 9 out of range [1, 3]");
    const std::string q = write("range2.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 -4 2\n");
    expectThrowWith<openvdb::ValueError>([&] { readObj(q); },
        q + ":4: face index -4 out of range [-3, -1]");
    const std::string z = write("zero.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n");
    expectThrowWith<openvdb::ValueError>([&] { readObj(z); }, z + ":4: face index 0");
}

TEST(ObjTest, MalformedContentErrors)
{
    const std::string nan = write("nan.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n");
    expectThrowWith<openvdb::ValueError>([&] { readObj(nan); }, nan + ":2: vertex coordinate");
    const std::string big = write("big.obj", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n");
    expectThrowWith<openvdb::ValueError>([&] { readObj(big); },
        big + ":2: vertex coordinate 1e+39 is not a finite float");
    const std::string word = write("word.obj", "v 0 0 0\nv 1 zero 0\n");
    expectThrowWith<openvdb::ValueError>([&] { readObj(word); },
        word + ":2: bad vertex coordinate 'zero'");
    const std::string two = write("two.obj", "v 0 0 0\nv 1 0\n");
    expectThrowWith<openvdb::ValueError>([&] { readObj(two); }, two + ":2: vertex needs 3");
    const std::string line = write("line.obj", "v 0 0 0\nv 1 0 0\nf 1 2\n");
    expectThrowWith<openvdb::ValueError>([&] { readObj(line); }, line + ":3: face with 2");
    const std::string empty = write("empty.obj", "# nothing\nv 0 0 0\n");
    expectThrowWith<openvdb::ValueError>([&] { readObj(empty); }, empty + ": no triangles");
}

TEST(ObjTest, BadMaterialValuesNameFileLineAndValue)
{
    write("bright.mtl", "newmtl a\nKd 0.5 1.2 0.5\n");
    const std::string p = write("bright.obj", "mtllib vdbrad_mesh_bright.mtl\n");
    expectThrowWith<openvdb::ValueError>([&] { readObj(p); },
        path("bright.mtl") + ":2: Kd value 1.2 outside [0, 1]");
    write("dark.mtl", "newmtl a\n\nKe 1 -0.5 0\n");
    const std::string q = write("dark.obj", "mtllib vdbrad_mesh_dark.mtl\n");
    expectThrowWith<openvdb::ValueError>([&] { readObj(q); },
        path("dark.mtl") + ":3: Ke value -0.5 is negative");
    write("inf.mtl", "newmtl a\nKe inf 0 0\n");
    const std::string r = write("inf.obj", "mtllib vdbrad_mesh_inf.mtl\n");
    expectThrowWith<openvdb::ValueError>([&] { readObj(r); }, "inf.mtl:2: Ke value inf");
    write("xyz.mtl", "newmtl a\nKd xyz 0.1 0.1 0.1\n");
    const std::string s = write("xyz.obj", "mtllib vdbrad_mesh_xyz.mtl\n");
    expectThrowWith<openvdb::ValueError>([&] { readObj(s); }, "got 'xyz'");
}

TEST(ObjTest, MissingObjIsAnIoErrorMissingMtlAWarning)
{
    expectThrowWith<openvdb::IoError>([] { readObj(path("does_not_exist.obj")); },
        "does_not_exist.obj");
    expectThrowWith<openvdb::IoError>([] { readObj(::testing::TempDir()); }, "directory");
    // As Blender: the mesh loads, its usemtl names become plain materials (albedo 0.5, no
    // emission), one warning naming the library.
    const std::string p = write("nomtl.obj", "mtllib missing.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
        "usemtl light\nf 1 2 3\nusemtl wall\nf 1 3 2\nusemtl light\nf 2 3 1\n");
    const TriangleMesh m = readObj(p);
    EXPECT_EQ(m.warnings, std::vector<std::string>{p + ":1: material library 'missing.mtl' not "
        "found: its materials get albedo 0.5 and no emission"});
    ASSERT_EQ(m.materials.size(), 2u);
    EXPECT_EQ(m.materials[0].name, "light");
    EXPECT_EQ(m.materials[1].name, "wall");
    for (const Material& mat : m.materials) {
        EXPECT_EQ(mat.albedo, Vec3f(0.5f));
        EXPECT_EQ(mat.emission, Vec3f(0.f));
    }
    EXPECT_EQ(m.triangleMaterials, (std::vector<int32_t>{0, 1, 0}));
    // Another library on the line is still read; a name it lacks is then a plain material too.
    write("present.mtl", "newmtl wall\nKd 0.25\n");
    const TriangleMesh both = readObj(write("halfmtl.obj",
        "mtllib vdbrad_mesh_present.mtl gone.mtl\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
        "usemtl wall\nf 1 2 3\nusemtl light\nf 1 3 2\n"));
    EXPECT_EQ(both.warnings.size(), 1u);
    ASSERT_EQ(both.materials.size(), 2u);
    EXPECT_EQ(both.materials[0].albedo, Vec3f(0.25f));
    EXPECT_EQ(both.materials[1].name, "light");
}

TEST(ObjTest, MtllibIsFoundAsWrittenThenByItsFileName)
{
    const std::string dir = ::testing::TempDir() + "vdbrad_mesh_mtllib";
    ASSERT_EQ(std::system(("rm -rf '" + dir + "' && mkdir -p '" + dir + "/mat'").c_str()), 0);
    std::ofstream(dir + "/mat/a.mtl") << "newmtl red\nKd 1 0 0\n";
    std::ofstream(dir + "/b.mtl") << "newmtl lamp\nKe 17 12 4\n";
    const std::string tri = "v 0 0 0\nv 1 0 0\nv 0 1 0\n";
    auto obj = [&](const std::string& name, const std::string& text) {
        const std::string p = dir + "/" + name;
        std::ofstream(p) << text;
        return p;
    };
    // As written (a sub-folder; Windows backslashes): no warning.
    for (const char* lib : {"mat/a.mtl", ".\\mat\\a.mtl"}) {
        const TriangleMesh m = readObj(obj("written.obj", std::string("mtllib ") + lib + "\n"
            + tri + "usemtl red\nf 1 2 3\n"));
        EXPECT_TRUE(m.warnings.empty()) << lib;
        EXPECT_EQ(m.materials.at(0).albedo, Vec3f(1, 0, 0)) << lib;
    }
    // A folder that is not there (relative, absolute, Windows drive): the file name in the
    // OBJ's folder, one warning per library however often it is named. Ke above 1 is kept.
    for (const std::string lib : {"CornellBox/b.mtl", "/home/someone/scenes/b.mtl",
             "C:\\Users\\someone\\b.mtl"}) {
        const std::string p = obj("byname.obj", "mtllib " + lib + "\n" + tri
            + "usemtl lamp\nf 1 2 3\nmtllib " + lib + "\n");
        const TriangleMesh m = readObj(p);
        EXPECT_EQ(m.warnings, std::vector<std::string>{p + ":1: material library '" + lib
            + "' not found as written; using 'b.mtl' beside the OBJ"});
        ASSERT_EQ(m.materials.size(), 1u);
        EXPECT_EQ(m.materials[0].emission, Vec3f(17, 12, 4));
    }
    // A name with spaces is taken whole when such a file exists, by its file name too.
    std::ofstream(dir + "/my room.mtl") << "newmtl red\nKd 1 0 0\n";
    const TriangleMesh spaced = readObj(obj("spaced.obj",
        "mtllib exports/my room.mtl\n" + tri + "usemtl red\nf 1 2 3\n"));
    EXPECT_EQ(spaced.warnings.size(), 1u);
    EXPECT_EQ(spaced.materials.size(), 1u);
}

TEST(ObjTest, ObjectsAndGroupsAreNumberedByTheirFirstFace)
{
    // `o` and `g` both name the faces that follow; faces before either are in "default"; ids
    // count from 0 in order of each name's first face; a name seen again keeps its id; a name
    // with no face gets none.
    const TriangleMesh m = readObj(write("groups.obj",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\n"
        "o Light Panel\nf 1 2 4\ng unused\no walls\nf 2 4 3 1\n"
        "g\nf 1 3 2\no Light Panel\nf 3 2 1\n"));
    EXPECT_EQ(m.groups, (std::vector<std::string>{"default", "Light Panel", "walls"}));
    EXPECT_EQ(m.triangleGroups, (std::vector<int32_t>{0, 1, 2, 2, 0, 1}));
    // No `o` or `g`: no groups at all.
    const TriangleMesh plain = readObj(write("nogroups.obj", cubeObj()));
    EXPECT_FALSE(plain.hasGroups());
    EXPECT_TRUE(plain.triangleGroups.empty());
}

TEST(ObjTest, ConcavePolygonsAreEarClippedConvexOnesFanned)
{
    // An L-shaped floor (area 3) as one hexagon from the corner (2, 0): its fan would lay a
    // backwards triangle over the missing square. Ear clipping gives 4 triangles, all facing
    // +z, covering the L exactly.
    const TriangleMesh m = readObj(write("ell.obj",
        "v 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nv 0 0 0\no floor\nf 1 2 3 4 5 6\n"));
    ASSERT_EQ(m.triangles.size(), 4u);
    double area = 0.0;
    for (size_t t = 0; t < 4; ++t) {
        const Vec3d n = normalOf(m, t);
        EXPECT_GE(n.z(), 0.0) << t;
        EXPECT_EQ(n.x(), 0.0);
        EXPECT_EQ(n.y(), 0.0);
        area += 0.5 * n.z();
        // Inside the L: no centroid in the missing square [1, 2]^2.
        const Vec3d c = (Vec3d(m.points[m.triangles[t][0]]) + Vec3d(m.points[m.triangles[t][1]])
            + Vec3d(m.points[m.triangles[t][2]])) / 3.0;
        EXPECT_FALSE(c.x() > 1.0 && c.y() > 1.0) << t;
    }
    EXPECT_DOUBLE_EQ(area, 3.0);
    EXPECT_EQ(m.triangleGroups, (std::vector<int32_t>(4, 0)));
    // A dart (arrowhead quad, area 1.5) whose fan diagonal runs outside it, wound either way:
    // 2 triangles of the quad's orientation and area.
    for (const char* f : {"f 1 2 3 4\n", "f 1 4 3 2\n"}) {
        const TriangleMesh dart = readObj(write("dart.obj",
            std::string("v -1 -1 0\nv 0 0.5 0\nv 1 -1 0\nv 0 2 0\n") + f));
        ASSERT_EQ(dart.triangles.size(), 2u);
        const double sign = f[4] == '2' ? 1.0 : -1.0;   // 1 2 3 4 runs counter-clockwise
        EXPECT_GE(sign * normalOf(dart, 1).z(), 0.0);
        EXPECT_DOUBLE_EQ(0.5 * sign * (normalOf(dart, 0).z() + normalOf(dart, 1).z()), 1.5);
    }
}

// ---- PLY ---------------------------------------------------------------------------------------

TEST(PlyTest, AsciiAndBothBinaryByteOrdersGiveTheObjCube)
{
    const TriangleMesh obj = readObj(write("ref.obj", cubeObj()));
    const TriangleMesh ascii = readPly(write("cube_a.ply", cubePly("ascii")));
    const TriangleMesh little = readPly(write("cube_le.ply", cubePly("binary_little_endian")));
    const TriangleMesh big = readPly(write("cube_be.ply", cubePly("binary_big_endian")));
    // The two binary files differ byte for byte but hold the same numbers.
    EXPECT_NE(cubePly("binary_little_endian"), cubePly("binary_big_endian"));
    ASSERT_EQ(ascii.triangles.size(), 12u);
    expectSameMesh(ascii, obj);
    expectSameMesh(little, obj);
    expectSameMesh(big, obj);
    EXPECT_DOUBLE_EQ(signedVolume(big), 1.0);
    EXPECT_FALSE(big.hasMaterials());
}

TEST(PlyTest, OtherElementsAndPropertiesAreSkipped)
{
    const TriangleMesh obj = readObj(write("ref2.obj", cubeObj()));
    for (const char* format : {"ascii", "binary_little_endian", "binary_big_endian"}) {
        SCOPED_TRACE(format);
        const TriangleMesh m = readPly(write("extra.ply", cubePly(format, true)));
        expectSameMesh(m, obj);
    }
}

TEST(PlyTest, VertexColoursBecomeDeduplicatedMaterials)
{
    // Three separate triangles: all red; red + two blue; all red again.
    std::ostringstream p;
    p << "ply\r\nformat ascii 1.0\r\nelement vertex 9\r\nproperty double x\r\n"
      << "property double y\r\nproperty double z\r\nproperty uchar red\r\n"
      << "property uchar green\r\nproperty uchar blue\r\n"
      << "property uchar alpha\r\nelement face 3\r\nproperty list uint8 uint32 vertex_index\r\n"
      << "end_header\r\n";
    const char* colours[9] = {"255 0 0", "255 0 0", "255 0 0", "255 0 0", "0 0 255", "0 0 255",
                              "255 0 0", "255 0 0", "255 0 0"};
    for (int i = 0; i < 9; ++i) p << i << " 0 " << (i % 3 == 2) << " " << colours[i] << " 255\n";
    p << "3 0 1 2\n3 3 4 5\n3 6 7 8\n";
    const TriangleMesh m = readPly(write("vcol.ply", p.str()));
    ASSERT_EQ(m.triangles.size(), 3u);
    ASSERT_EQ(m.materials.size(), 2u);
    EXPECT_EQ(m.triangleMaterials, (std::vector<int32_t>{0, 1, 0}));
    EXPECT_EQ(m.materials[0].name, "rgb(255,0,0)");
    EXPECT_EQ(m.materials[0].albedo, Vec3f(1, 0, 0));
    EXPECT_EQ(m.materials[0].emission, Vec3f(0.f));
    // The mean of (255,0,0), (0,0,255), (0,0,255).
    EXPECT_EQ(m.materials[1].name, "rgb(85,0,170)");
    EXPECT_FLOAT_EQ(m.materials[1].albedo[0], 1.f / 3.f);
    EXPECT_FLOAT_EQ(m.materials[1].albedo[2], 2.f / 3.f);
}

TEST(PlyTest, FaceColoursInFloatAreUsedAsIs)
{
    Bytes b{false,
        "ply\nformat binary_little_endian 1.0\nelement vertex 4\nproperty float x\n"
        "property float y\nproperty float z\nelement face 2\n"
        "property list uchar int vertex_indices\nproperty float red\nproperty float green\n"
        "property float blue\nend_header\n"};
    for (int i = 0; i < 4; ++i) { b.put(float(i & 1)); b.put(float(i >> 1)); b.put(0.f); }
    b.put(uint8_t(3)); b.put(0); b.put(1); b.put(3); b.put(0.25f); b.put(0.5f); b.put(1.f);
    b.put(uint8_t(3)); b.put(0); b.put(3); b.put(2); b.put(0.25f); b.put(0.5f); b.put(1.f);
    const TriangleMesh m = readPly(write("fcol.ply", b.data));
    ASSERT_EQ(m.materials.size(), 1u);
    EXPECT_EQ(m.materials[0].albedo, Vec3f(0.25f, 0.5f, 1.f));
    EXPECT_EQ(m.materials[0].name, "rgb(63.75,127.5,255)");
    EXPECT_EQ(m.triangleMaterials, (std::vector<int32_t>{0, 0}));
}

TEST(PlyTest, PolygonsAreTriangulatedAsInObjFiles)
{
    // The L-shaped hexagon and a convex pentagon, faces before vertices (legal PLY), ascii and
    // binary: the triangles of the OBJ reader, the L ear-clipped, the pentagon fanned, with
    // per-face colours kept on each polygon's triangles.
    const char* const corners[] = {"2 0 0", "2 1 0", "1 1 0", "1 2 0", "0 2 0", "0 0 0",
        "3 0 0", "5 0 0", "6 1 0", "4 2 0", "2 1 1"};
    const std::vector<std::vector<int>> faces = {{0, 1, 2, 3, 4, 5}, {6, 7, 8, 9, 10}};
    std::ostringstream obj;
    for (const char* c : corners) obj << "v " << c << "\n";
    for (const auto& f : faces) {
        obj << "f";
        for (int k : f) obj << " " << k + 1;
        obj << "\n";
    }
    const TriangleMesh ref = readObj(write("polys.obj", obj.str()));
    ASSERT_EQ(ref.triangles.size(), 7u);
    EXPECT_EQ(ref.triangles[4], Vec3I(6, 7, 8));   // the pentagon's fan
    std::ostringstream ascii;
    const std::string header = std::string("element face 2\nproperty list uchar int vertex_indices\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\n")
        + "element vertex 11\nproperty float x\nproperty float y\nproperty float z\nend_header\n";
    ascii << "ply\nformat ascii 1.0\n" << header;
    Bytes b{true, "ply\nformat binary_big_endian 1.0\n" + header};
    for (size_t i = 0; i < faces.size(); ++i) {
        ascii << faces[i].size();
        b.put(uint8_t(faces[i].size()));
        for (int k : faces[i]) {
            ascii << " " << k;
            b.put(int32_t(k));
        }
        ascii << (i ? " 0 0 255\n" : " 255 0 0\n");
        for (uint8_t c : i ? std::array<uint8_t, 3>{0, 0, 255} : std::array<uint8_t, 3>{255, 0, 0}) {
            b.put(c);
        }
    }
    for (const char* c : corners) {
        ascii << c << "\n";
        std::istringstream in(c);
        float x, y, z;
        in >> x >> y >> z;
        b.put(x); b.put(y); b.put(z);
    }
    for (const std::string& data : {ascii.str(), b.data}) {
        const TriangleMesh m = readPly(write("polys.ply", data));
        ASSERT_EQ(m.triangles, ref.triangles);
        EXPECT_EQ(m.triangleMaterials, (std::vector<int32_t>{0, 0, 0, 0, 1, 1, 1}));
        EXPECT_EQ(m.points, ref.points);
    }
    // Degenerate and invalid faces: errors naming the face (and line, in ascii).
    std::string two = ascii.str();
    two.replace(two.find("6 0 1 2 3 4 5"), 13, "2 0 1");
    expectThrowWith<openvdb::ValueError>([&] { readPly(write("twoface.ply", two)); },
        ":13: face 0 has 2 vertices (at least 3 needed)");
    std::string negative = ascii.str();
    negative.replace(negative.find("5 6 7 8 9 10"), 12, "5 6 7 -8 9 10");
    expectThrowWith<openvdb::ValueError>([&] { readPly(write("negface.ply", negative)); },
        ":14: face 1: vertex index -8 out of range [0, 10]");
    std::string fraction = ascii.str();
    fraction.replace(fraction.find("list uchar int"), 14, "list uchar float");
    expectThrowWith<openvdb::ValueError>([&] { readPly(write("fracface.ply", fraction)); },
        ":3: face vertex indices are not of an integer type");
}

TEST(PlyTest, ColourOutsideItsRangeIsAValueError)
{
    const std::string p = write("bright.ply",
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n"
        "property float z\nproperty float red\nproperty float green\nproperty float blue\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "0 0 0 1 1 1\n1 0 0 0.5 1.5 0\n0 1 0 0 0 0\n3 0 1 2\n");
    expectThrowWith<openvdb::ValueError>([&] { readPly(p); },
        p + ":14: vertex 1: colour value 1.5 outside [0, 1]");
}

TEST(PlyTest, TruncatedBinaryIsAnIoErrorSayingHowFarItGot)
{
    std::string full = cubePly("binary_little_endian");
    const size_t header = full.find("end_header\n") + 11;
    // 5 whole vertices (12 bytes each) and part of the sixth.
    const std::string p = write("trunc.ply", full.substr(0, header + 5 * 12 + 7));
    expectThrowWith<openvdb::IoError>([&] { readPly(p); },
        p + ": truncated: expected 8 vertices, file ends after 5");
    // All vertices and two faces (1 + 4*4 bytes each).
    const std::string q = write("trunc2.ply", full.substr(0, header + 8 * 12 + 2 * 17 + 3));
    expectThrowWith<openvdb::IoError>([&] { readPly(q); },
        "truncated: expected 6 faces, file ends after 2");
}

TEST(PlyTest, AbsurdCountsAreRefusedBeforeAllocating)
{
    // 2^40 vertices of 12 bytes would be 13 TB; the file holds a few dozen bytes.
    std::string text = cubePly("binary_little_endian");
    const std::string huge = "element vertex 1099511627776";
    text.replace(text.find("element vertex 8"), 16, huge);
    const std::string p = write("huge.ply", text);
    expectThrowWith<openvdb::ValueError>([&] { readPly(p); },
        p + ":5: header claims 1099511627776 vertices");
    // Likewise a face count, in ASCII; and a count that does not fit 64 bits.
    std::string faces = cubePly("ascii");
    faces.replace(faces.find("element face 6"), 14, "element face 4000000000");
    expectThrowWith<openvdb::ValueError>([&] { readPly(write("huge2.ply", faces)); },
        "header claims 4000000000 faces");
    std::string overflow = cubePly("ascii");
    overflow.replace(overflow.find("element face 6"), 14, "element face 99999999999999999999");
    expectThrowWith<openvdb::ValueError>([&] { readPly(write("huge3.ply", overflow)); },
        "bad count");
    // A list length of 2^32 - 1 in the data runs out of bytes, not memory.
    Bytes b{true,
        "ply\nformat binary_big_endian 1.0\nelement vertex 3\nproperty float x\n"
        "property float y\nproperty float z\nelement face 1\n"
        "property list uint int vertex_indices\nend_header\n"};
    for (int i = 0; i < 9; ++i) b.put(float(i == 1 || i == 5));
    b.put(uint32_t(0xffffffffu)); b.put(0); b.put(1); b.put(2);
    expectThrowWith<openvdb::IoError>([&] { readPly(write("longlist.ply", b.data)); },
        "truncated: expected 1 faces, file ends after 0");
}

TEST(PlyTest, NonFiniteCoordinatesAndBadIndicesAreValueErrors)
{
    Bytes b{false,
        "ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n"
        "property float y\nproperty float z\nelement face 1\n"
        "property list uchar int vertex_indices\nend_header\n"};
    b.put(0.f); b.put(0.f); b.put(0.f);
    b.put(1.f); b.put(std::numeric_limits<float>::quiet_NaN()); b.put(0.f);
    b.put(0.f); b.put(1.f); b.put(0.f);
    b.put(uint8_t(3)); b.put(0); b.put(1); b.put(2);
    const std::string p = write("nan.ply", b.data);
    expectThrowWith<openvdb::ValueError>([&] { readPly(p); }, p + ": vertex 1: coordinates");

    std::string text = cubePly("ascii");
    text.replace(text.find("4 1 2 6 5"), 9, "4 1 2 6 8");
    const std::string q = write("badindex.ply", text);
    // Header (11 lines) + 8 vertex lines + 6th face line.
    expectThrowWith<openvdb::ValueError>([&] { readPly(q); },
        q + ":25: face 5: vertex index 8 out of range [0, 7]");
    std::string inf = cubePly("ascii");
    inf.replace(inf.find("\n1 1 1\n"), 7, "\n1 inf 1\n");
    expectThrowWith<openvdb::ValueError>([&] { readPly(write("inf.ply", inf)); },
        "vertex 6: coordinates (1, inf, 1) are not finite floats");
}

TEST(PlyTest, MalformedHeadersAndTextAreValueErrors)
{
    const std::string body = cubePly("ascii");
    auto edited = [&](const std::string& from, const std::string& to) {
        std::string t = body;
        t.replace(t.find(from), from.size(), to);
        return write("malformed.ply", t);
    };
    expectThrowWith<openvdb::ValueError>([&] { readPly(edited("ply\n", "plx\n")); },
        "not a PLY file");
    expectThrowWith<openvdb::ValueError>([&] { readPly(edited("ascii", "binary_middle")); },
        ":2: unknown format 'binary_middle'");
    expectThrowWith<openvdb::ValueError>(
        [&] { readPly(edited("property float y", "property quad y")); },
        ":7: unknown property type 'quad'");
    expectThrowWith<openvdb::ValueError>([&] { readPly(edited("end_header\n", "")); },
        ":11: unexpected header line '0 0 0'");
    expectThrowWith<openvdb::ValueError>(
        [&] { readPly(write("noend.ply", body.substr(0, body.find("end_header")))); },
        "no end_header");
    expectThrowWith<openvdb::ValueError>([&] { readPly(edited("property float z\n", "")); },
        "vertex element lacks x, y or z");
    expectThrowWith<openvdb::ValueError>([&] { readPly(edited("\n0 1 1\n", "\n0 1 1 3\n")); },
        ":19: 1 more values than the header's properties");
    expectThrowWith<openvdb::ValueError>([&] { readPly(edited("\n0 1 1\n", "\n0 one 1\n")); },
        ":19: bad number 'one'");
    expectThrowWith<openvdb::ValueError>([&] { readPly(edited("\n4 0 3 2 1\n", "\n2 0 3\n")); },
        "face 0 has 2 vertices");
    expectThrowWith<openvdb::IoError>(
        [&] { readPly(edited("4 1 2 6 5\n", "")); }, "expected 6 faces, file ends after 5");
}

TEST(ReadMeshTest, ChoosesTheReaderByMagicThenExtension)
{
    // PLY bytes behind a .obj name are still PLY; an upper-case extension is fine.
    const TriangleMesh a = readMesh(write("really_ply.obj", cubePly("binary_big_endian")));
    const TriangleMesh b = readMesh(write("upper.OBJ", cubeObj()));
    expectSameMesh(a, b);
    EXPECT_EQ(readMesh(write("lower.Ply", cubePly("ascii"))).triangles.size(), 12u);
    const std::string stl = write("cube.stl", "solid cube\nendsolid\n");
    expectThrowWith<openvdb::ValueError>([&] { readMesh(stl); },
        stl + ": unknown mesh format (supported: Wavefront .obj, .ply)");
    expectThrowWith<openvdb::IoError>([] { readMesh(path("missing.ply")); }, "missing.ply");
}

// ---- the sample meshes -------------------------------------------------------------------------

TEST(SampleMeshTest, CornellBoxMatchesTheGridScene)
{
    const TriangleMesh m = readMesh(VDBRAD_SOURCE_DIR "/samples/meshes/cornell_box.obj");
    std::map<std::string, int32_t> id;
    for (size_t i = 0; i < m.materials.size(); ++i) id[m.materials[i].name] = int32_t(i);
    ASSERT_EQ(id.size(), 4u);
    ASSERT_TRUE(id.count("white") && id.count("red") && id.count("green") && id.count("light"));
    // The colours grids/CanonicalGrids.cc uses.
    EXPECT_EQ(m.materials[id["white"]].albedo, Vec3f(0.73f));
    EXPECT_EQ(m.materials[id["red"]].albedo, Vec3f(0.63f, 0.065f, 0.05f));
    EXPECT_EQ(m.materials[id["green"]].albedo, Vec3f(0.14f, 0.45f, 0.091f));
    EXPECT_EQ(m.materials[id["light"]].emission, Vec3f(1.f));
    EXPECT_EQ(m.materials[id["light"]].albedo, Vec3f(0.73f));
    Vec3f lo(1e9f), hi(-1e9f);
    for (const Vec3f& p : m.points) {
        lo = openvdb::math::minComponent(lo, p);
        hi = openvdb::math::maxComponent(hi, p);
    }
    EXPECT_EQ(lo, Vec3f(0.f));
    EXPECT_EQ(hi, Vec3f(0.556f, 0.5488f, 0.5592f));
    ASSERT_EQ(m.triangleMaterials.size(), m.triangles.size());
    double lightArea = 0;
    for (size_t t = 0; t < m.triangles.size(); ++t) {
        const Vec3d n = normalOf(m, t);
        const Vec3f& a = m.points[m.triangles[t][0]];
        const int32_t mat = m.triangleMaterials[t];
        // Red on the x = X wall facing -x, green on x = 0 facing +x, as the grid builder has it.
        if (mat == id["red"]) { EXPECT_FLOAT_EQ(a.x(), 0.556f); EXPECT_LT(n.x(), 0); }
        if (mat == id["green"]) { EXPECT_EQ(a.x(), 0.f); EXPECT_GT(n.x(), 0); }
        if (mat == id["light"]) {
            EXPECT_LT(n.y(), 0);
            EXPECT_FLOAT_EQ(a.y(), 0.5478f);
            lightArea += 0.5 * n.length();
        }
    }
    EXPECT_NEAR(lightArea, 0.130 * 0.105, 1e-7);
}

TEST(SampleMeshTest, FurnishedRoomLoadsWithColouredAndEmittingMaterials)
{
    const TriangleMesh m = readMesh(VDBRAD_SOURCE_DIR "/samples/meshes/furnished_room.obj");
    EXPECT_GT(m.triangles.size(), 500u);
    ASSERT_EQ(m.triangleMaterials.size(), m.triangles.size());
    int emitters = 0, coloured = 0;
    for (const Material& mat : m.materials) {
        if (mat.emission != Vec3f(0.f)) ++emitters;
        if (mat.albedo[0] != mat.albedo[1] || mat.albedo[1] != mat.albedo[2]) ++coloured;
    }
    EXPECT_EQ(emitters, 2);   // ceiling panel and window
    EXPECT_GE(coloured, 4);
    for (int32_t mat : m.triangleMaterials) EXPECT_GE(mat, 0);
}
