// Malformed input, as files from other tools reach vdbrad in a render farm: every command that
// reads an input must answer bad bytes or bad values with exactly one line
// `vdbrad: error: FILE: ...` on stderr and exit status 1 (2 for a refused request on the command
// line), create no output (a previous output stays as it was) and leave the input unchanged.
// Every bad file is generated here; a few valid extremes (one voxel) must work.
#include "ToolTest.h"
#include "vdbrad/vdbrad.h"

#include <openvdb/tools/LevelSetSphere.h>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

#include <gtest/gtest.h>

#include <cmath>
#include <dirent.h>
#include <functional>
#include <random>
#include <set>

using namespace vdbrad;

namespace {

using test::exists;
using test::like;
using test::patch;
using test::slurp;
using Grids = openvdb::GridPtrVec;

// ---- inputs ---------------------------------------------------------------------------------

openvdb::math::Transform::Ptr
xform(double voxelSize, openvdb::Vec3d offset = openvdb::Vec3d(0.0))
{
    auto t = openvdb::math::Transform::createLinearTransform(voxelSize);
    t->postTranslate(offset);
    return t;
}

// A 4^3 block of fog at index @a origin.
openvdb::FloatGrid::Ptr
fog(float density = 2.f, double voxelSize = 0.1, openvdb::Coord origin = openvdb::Coord(0))
{
    auto g = openvdb::FloatGrid::create();
    g->setName("density");
    g->setGridClass(openvdb::GRID_FOG_VOLUME);
    g->setTransform(xform(voxelSize));
    for (int x = 0; x < 4; ++x) for (int y = 0; y < 4; ++y) for (int z = 0; z < 4; ++z) {
        g->tree().setValueOn(origin.offsetBy(x, y, z), density);
    }
    return g;
}

// A lit scene: surface, emission and a radiosity grid, so that every command gets past its
// own requirements and meets the one thing a case breaks.
Grids
scene(openvdb::Vec3SGrid::Ptr n = patch())
{
    return {n, like<openvdb::FloatGrid>(*n, "emission", 1.f),
        like<openvdb::FloatGrid>(*n, "radiosity", 1.f)};
}

std::string
bytesOf(const Grids& grids)
{
    VdbFile f;
    f.grids = grids;
    return serializeVdb(f);
}

// One byte of @a bytes changed, at random positions after the magic number.
std::string
mutate(std::string bytes, unsigned seed, int flips)
{
    std::mt19937 rng(seed);
    std::uniform_int_distribution<size_t> at(8, bytes.size() - 1);
    std::uniform_int_distribution<int> value(0, 255);
    for (int i = 0; i < flips; ++i) bytes[at(rng)] = char(value(rng));
    return bytes;
}

// ---- the commands that read input -------------------------------------------------------------

struct Command
{
    std::string name;
    std::string line;    // IN stands for the input, OUT for the output
    std::string output;  // "" when the command writes nothing
};

// The heavy commands run with the least work: malformed input must be refused before it.
const std::vector<Command>&
readers()
{
    static const std::vector<Command> all = {
        {"info", "vdbrad info IN", ""},
        {"surface", "vdbrad surface IN OUT --quiet", "out.vdb"},
        {"compareA", "vdbrad compare IN ref.vdb", ""},
        {"compareB", "vdbrad compare ref.vdb IN", ""},
        {"solve", "vdbrad solve IN OUT --quiet --directions 3 --iterations 1", "out.vdb"},
        {"solveCloud", "vdbrad solve-cloud IN OUT --quiet --directions 3 --iterations 1",
            "out.vdb"},
        {"render", "vdbrad render IN OUT --quiet --res 8x6", "out.exr"},
    };
    return all;
}

const Command&
reader(const std::string& name)
{
    for (const auto& c : readers()) if (c.name == name) return c;
    throw std::runtime_error("no command " + name);
}

std::string
replaceAll(std::string s, const std::string& from, const std::string& to)
{
    for (size_t p = s.find(from); p != std::string::npos; p = s.find(from, p + to.size())) {
        s.replace(p, from.size(), to);
    }
    return s;
}

std::set<std::string>
listDir(const std::string& dir)
{
    std::set<std::string> names;
    if (DIR* d = ::opendir(dir.c_str())) {
        while (dirent* e = ::readdir(d)) {
            const std::string name = e->d_name;
            if (name != ".stdout" && name != ".stderr") names.insert(name);   // the fixture's
        }
        ::closedir(d);
    }
    return names;
}

class MalformedTest : public test::ToolTest
{
protected:
    void writeBytes(const std::string& name, const std::string& bytes) const
    {
        std::ofstream(path(name), std::ios::binary) << bytes;
    }

    /// A solved reference for `compare`.
    void writeReference() const { writeBytes("ref.vdb", bytesOf(scene())); }

    /// Run @a c on the file @a input (already written) and check the refusal: status @a status,
    /// one line `vdbrad: error: INPUT: ...` containing @a what, a previous output untouched, no
    /// new file, the input unchanged. An empty @a what accepts any message.
    void expectRefused(const Command& c, const std::string& input, const std::string& what,
        const std::string& context = "", int status = 1) const
    {
        SCOPED_TRACE(c.name + " " + context);
        const std::string before = slurp(path(input));
        const std::string precious = "a previous output, not to be touched\n";
        if (!c.output.empty()) writeText(c.output, precious);
        const std::set<std::string> files = listDir(mDir);
        const std::string cmd = replaceAll(replaceAll(c.line, "IN", input), "OUT", c.output);
        const test::ToolResult r = sh(cmd);
        EXPECT_EQ(r.status, status) << cmd << "\n" << r.err;
        const auto lines = r.errLines();
        ASSERT_EQ(lines.size(), 1u) << cmd << "\n" << r.err;
        // "FILE: " or, for text formats, "FILE:LINE: ".
        const std::string prefix = "vdbrad: error: " + input + ":";
        EXPECT_EQ(lines[0].rfind(prefix, 0), 0u) << cmd << "\n" << lines[0];
        EXPECT_NE(lines[0].find(what), std::string::npos) << "expected '" << what << "' in\n"
                                                          << lines[0];
        if (!c.output.empty()) {
            EXPECT_EQ(slurp(path(c.output)), precious) << cmd;
        }
        EXPECT_EQ(listDir(mDir), files) << cmd << ": files created or removed";
        EXPECT_EQ(slurp(path(input)), before) << cmd << ": input changed";
    }

    /// Run @a c on @a input and expect success with a non-empty output, input unchanged.
    void expectWorks(const Command& c, const std::string& input) const
    {
        SCOPED_TRACE(c.name);
        const std::string before = slurp(path(input));
        if (!c.output.empty()) std::remove(path(c.output).c_str());
        const std::string cmd = replaceAll(replaceAll(c.line, "IN", input), "OUT", c.output);
        const test::ToolResult r = sh(cmd);
        EXPECT_EQ(r.status, 0) << cmd << "\n" << r.err;
        for (const auto& l : r.errLines()) EXPECT_EQ(l.find("error"), std::string::npos) << l;
        if (!c.output.empty()) {
            EXPECT_GT(slurp(path(c.output)).size(), 0u) << cmd;
        }
        EXPECT_EQ(slurp(path(input)), before) << cmd << ": input changed";
    }

    /// Either a clean success or a clean refusal (randomly corrupted bytes may still be valid).
    void expectSuccessOrRefusal(const Command& c, const std::string& input,
        const std::string& context) const
    {
        SCOPED_TRACE(c.name + " " + context);
        const std::string before = slurp(path(input));
        const std::string precious = "a previous output, not to be touched\n";
        if (!c.output.empty()) writeText(c.output, precious);
        const std::string cmd = replaceAll(replaceAll(c.line, "IN", input), "OUT", c.output);
        const test::ToolResult r = sh(cmd);
        ASSERT_TRUE(r.status == 0 || r.status == 1) << cmd << " exited " << r.status << "\n"
                                                    << r.err;
        if (r.status == 1) {
            // Warnings may precede the error only on success; a refusal is one line.
            ASSERT_EQ(r.errLines().size(), 1u) << r.err;
            EXPECT_EQ(r.err.rfind("vdbrad: error: " + input + ": ", 0), 0u) << r.err;
            if (!c.output.empty()) {
                EXPECT_EQ(slurp(path(c.output)), precious);
            }
        }
        EXPECT_EQ(slurp(path(input)), before) << cmd << ": input changed";
    }
};

// ---- bytes: every command that reads a `.vdb` file ------------------------------------------

class MalformedBytesTest : public MalformedTest, public ::testing::WithParamInterface<Command>
{
};

void
PrintTo(const Command& c, std::ostream* os)
{
    *os << c.name;
}

std::string
commandName(const ::testing::TestParamInfo<Command>& info)
{
    return info.param.name;
}

INSTANTIATE_TEST_SUITE_P(Readers, MalformedBytesTest, ::testing::ValuesIn(readers()), commandName);

TEST_P(MalformedBytesTest, NotAVdbFile)
{
    writeReference();
    writeText("bad.vdb", "# a Wavefront OBJ, not a VDB\nv 0 0 0\n");
    expectRefused(GetParam(), "bad.vdb", "not a VDB file");
}

TEST_P(MalformedBytesTest, EmptyFile)
{
    writeReference();
    writeText("bad.vdb", "");
    expectRefused(GetParam(), "bad.vdb", "empty file");
}

TEST_P(MalformedBytesTest, TruncatedAtManyOffsets)
{
    writeReference();
    const std::string good = bytesOf(GetParam().name == "solveCloud" ? Grids{fog()} : scene());
    // Inside the header and metadata, the grid descriptors, and the voxel data.
    for (size_t cut : {size_t(4), size_t(9), size_t(20), size_t(60), size_t(150), size_t(300),
             good.size() / 3, good.size() / 2, good.size() - 100, good.size() - 1}) {
        writeBytes("bad.vdb", good.substr(0, cut));
        expectRefused(GetParam(), "bad.vdb", cut < 8 ? "not a VDB file" : "", "cut at "
            + std::to_string(cut));
    }
}

TEST_P(MalformedBytesTest, FlippedHeaderBytes)
{
    writeReference();
    const std::string good = bytesOf(scene());
    // The file format version (bytes 8-11): from the future, which OpenVDB 10 would read as its
    // own with a warning, and from the past, before the formats it reads.
    std::string future = good;
    future[8] = future[9] = future[10] = char(0x7f);
    writeBytes("bad.vdb", future);
    expectRefused(GetParam(), "bad.vdb", "unsupported VDB file format version 8355711",
        "file version");
    std::string zero = good;
    zero[8] = zero[9] = zero[10] = zero[11] = 0;
    writeBytes("bad.vdb", zero);
    expectRefused(GetParam(), "bad.vdb", "unsupported VDB file format version 0", "version 0");
    // Every other header byte (library version, offsets flag, UUID, metadata count) flipped.
    for (size_t at = 12; at < 64; at += 3) {
        std::string flipped = good;
        flipped[at] = char(~flipped[at]);
        writeBytes("bad.vdb", flipped);
        expectSuccessOrRefusal(GetParam(), "bad.vdb", "byte " + std::to_string(at));
    }
}

TEST_P(MalformedBytesTest, RandomMutationsNeverCrash)
{
    writeReference();
    const std::string good = bytesOf(GetParam().name == "solveCloud" ? Grids{fog()} : scene());
    for (unsigned seed = 1; seed <= 24; ++seed) {
        writeBytes("bad.vdb", mutate(good, seed, 1 + int(seed % 4)));
        expectSuccessOrRefusal(GetParam(), "bad.vdb", "seed " + std::to_string(seed));
    }
}

TEST_P(MalformedBytesTest, UnknownGridType)
{
    writeReference();
    // A grid type this OpenVDB does not register (a newer version's, a plugin's): same length,
    // so only the type name changes.
    std::string bytes = bytesOf(scene());
    const std::string from = "Tree_vec3s_5_4_3", to = "Tree_vec3q_5_4_3";
    const size_t at = bytes.find(from);
    ASSERT_NE(at, std::string::npos);
    bytes.replace(at, from.size(), to);
    writeBytes("bad.vdb", bytes);
    expectRefused(GetParam(), "bad.vdb", "Tree_vec3q_5_4_3");
}

// ---- values: each case on the commands that use the broken grid ----------------------------

struct ValueCase
{
    std::string name;
    std::function<Grids()> grids;
    std::string what;                  // in the error line
    std::vector<std::string> commands; // readers() names
};

const std::vector<std::string> kSceneReaders = {"info", "surface", "solve", "render"};
const std::vector<std::string> kCloudReaders = {"info", "solveCloud", "render"};

template<typename GridT>
Grids
sceneWith(const std::string& name, typename GridT::ValueType v, Grids extra = {})
{
    Grids g = scene();
    g.push_back(like<GridT>(*g[0], name, v));
    for (auto& e : extra) g.push_back(e);
    return g;
}

// The scene with voxel (2, 0, 3) of @a name set to @a v.
template<typename GridT>
Grids
sceneWithOne(const std::string& name, typename GridT::ValueType good,
    typename GridT::ValueType bad)
{
    Grids g = scene();
    auto a = like<GridT>(*g[0], name, good);
    a->tree().setValueOn({2, 0, 3}, bad);
    if (name == "emission") g[1] = a;
    else g.push_back(a);
    return g;
}

Grids
cloudWith(openvdb::GridBase::Ptr albedo)
{
    return {fog(), albedo};
}

const float kNaN = std::numeric_limits<float>::quiet_NaN();
const float kInf = std::numeric_limits<float>::infinity();

std::vector<ValueCase>
valueCases()
{
    using FG = openvdb::FloatGrid;
    using VG = openvdb::Vec3SGrid;
    const openvdb::Vec3f grey(0.5f);
    return {
        {"NaNNormal", [] { auto n = patch(); n->tree().setValue({1, 0, 1}, {kNaN, 0, 0});
            return scene(n); }, "normal at voxel (1, 0, 1) is", kSceneReaders},
        {"InfNormal", [] { auto n = patch(); n->tree().setValue({1, 0, 1}, {0, kInf, 0});
            return scene(n); }, "(not finite)", kSceneReaders},
        {"ZeroLengthNormal", [] { auto n = patch(); n->tree().setValue({5, 0, 5}, {0, 0, 0});
            return scene(n); }, "(zero length)", kSceneReaders},
        {"NaNAlbedo", [] { return sceneWithOne<FG>("albedo", 0.5f, kNaN); },
            "albedo at voxel (2, 0, 3) is nan", kSceneReaders},
        {"InfRgbAlbedo", [=] { return sceneWithOne<VG>("albedo", grey, {0.5f, kInf, 0.5f}); },
            "albedo at voxel (2, 0, 3) is inf", kSceneReaders},
        {"NegativeAlbedo", [] { return sceneWithOne<FG>("albedo", 0.5f, -0.25f); },
            "outside [0, 1]", kSceneReaders},
        {"AlbedoAboveOne", [=] { return sceneWithOne<VG>("albedo", grey, {0.5f, 0.5f, 1.5f}); },
            "is 1.5, outside [0, 1]", kSceneReaders},
        {"NaNEmission", [] { return sceneWithOne<FG>("emission", 1.f, kNaN); },
            "emission at voxel (2, 0, 3) is nan", kSceneReaders},
        {"InfEmission", [] { return sceneWithOne<FG>("emission", 1.f, kInf); },
            "emission at voxel (2, 0, 3) is inf", kSceneReaders},
        {"NegativeRgbEmission", [] { return sceneWithOne<VG>("emission", openvdb::Vec3f(1.f),
            {1.f, -1.f, 1.f}); }, "is -1, outside [0, inf)", kSceneReaders},
        {"NaNRadiosity", [] { Grids g = scene();
            auto r = like<FG>(*g[0], "radiosity", 1.f);
            r->tree().setValueOn({2, 0, 3}, kNaN);
            g[2] = r;
            return g; }, "radiosity at voxel (2, 0, 3) is nan", {"render", "compareA", "compareB"}},
        {"AlbedoOnAnotherVoxelSize", [] { Grids g = scene();
            auto a = like<FG>(*g[0], "albedo", 0.5f);
            a->setTransform(xform(0.2));
            g.push_back(a);
            return g; }, "grid 'albedo' is not on the same transform as 'normal'", kSceneReaders},
        {"EmissionShiftedHalfAVoxel", [] { Grids g = scene();
            g[1]->setTransform(xform(0.1, {0.05, 0.0, 0.0}));
            return g; }, "grid 'emission' is not on the same transform", kSceneReaders},
        {"NonCubicVoxels", [] { auto n = patch();
            n->setTransform(openvdb::math::Transform::Ptr(new openvdb::math::Transform(
                openvdb::math::MapBase::Ptr(new openvdb::math::ScaleMap({0.1, 0.2, 0.1})))));
            return scene(n); }, "non-cubic voxels", kSceneReaders},
        {"NoSurfaceVoxels", [] { auto n = openvdb::Vec3SGrid::create(); n->setName("normal");
            return Grids{n, like<FG>(*patch(), "radiosity", 1.f)}; },
            "surface grid 'normal' has no active voxels", kSceneReaders},
        {"LevelSetWithoutZeroCrossing", [] {
            auto ls = openvdb::tools::createLevelSetSphere<FG>(4.f, {0, 0, 0}, 1.f);
            for (auto it = ls->tree().beginValueAll(); it; ++it) it.setValue(std::abs(*it) + 1.f);
            return Grids{ls, like<FG>(*patch(), "radiosity", 1.f)}; },
            "has no zero crossing", kSceneReaders},
        {"WrongSurfaceType", [] { auto n = like<openvdb::Int64Grid>(*patch(), "normal", 1);
            return Grids{n}; }, "grid 'normal' (normal) has type int64, expected vec3s",
            kSceneReaders},
        {"NaNDensity", [] { auto d = fog(); d->tree().setValueOn({1, 2, 3}, kNaN);
            return Grids{d}; }, "density at voxel (1, 2, 3) is nan", kCloudReaders},
        {"InfDensity", [] { auto d = fog(); d->tree().setValueOn({1, 2, 3}, kInf);
            return Grids{d}; }, "density at voxel (1, 2, 3) is inf", kCloudReaders},
        {"NegativeDensity", [] { return Grids{fog(-1.f)}; }, "is -1, outside [0, inf)",
            kCloudReaders},
        {"NaNCloudAlbedo", [] { auto a = like<FG>(*fog(), "albedo", 0.9f);
            a->tree().setValueOn({0, 0, 0}, kNaN);
            return cloudWith(a); }, "albedo at voxel (0, 0, 0) is nan", kCloudReaders},
        {"CloudAlbedoAboveOne", [] { return cloudWith(like<FG>(*fog(), "albedo", 1.01f)); },
            "outside [0, 1]", kCloudReaders},
        {"CloudAlbedoOnAnotherTransform", [] { auto a = like<FG>(*fog(), "albedo", 0.9f);
            a->setTransform(xform(0.1, {1.0, 0.0, 0.0}));
            return cloudWith(a); }, "grid 'albedo' is not on the same transform as 'density'",
            kCloudReaders},
        {"NoDensityVoxels", [] { auto d = openvdb::FloatGrid::create(); d->setName("density");
            return Grids{d}; }, "density grid 'density' has no active voxels", kCloudReaders},
        {"DensityOfWrongType", [=] { return Grids{like<VG>(*fog(), "density", grey)}; },
            "grid 'density' (density) has type vec3s, expected float", kCloudReaders},
    };
}

void
PrintTo(const ValueCase& c, std::ostream* os)
{
    *os << c.name;
}

class MalformedValuesTest : public MalformedTest,
                            public ::testing::WithParamInterface<ValueCase>
{
};

INSTANTIATE_TEST_SUITE_P(Cases, MalformedValuesTest, ::testing::ValuesIn(valueCases()),
    [](const ::testing::TestParamInfo<ValueCase>& info) { return info.param.name; });

TEST_P(MalformedValuesTest, RefusedByEveryCommandThatUsesIt)
{
    writeReference();
    writeBytes("bad.vdb", bytesOf(GetParam().grids()));
    for (const std::string& c : GetParam().commands) {
        expectRefused(reader(c), "bad.vdb", GetParam().what);
    }
}

// ---- extremes: valid inputs at the edges must work, absurd ones be refused ---------------------

TEST_F(MalformedTest, OneVoxelWorksEverywhere)
{
    auto n = openvdb::Vec3SGrid::create();
    n->setName("normal");
    n->setTransform(xform(0.1));
    n->tree().setValueOn({3, -2, 7}, openvdb::Vec3f(0, 0, -1));
    writeBytes("one.vdb", bytesOf(scene(n)));
    for (const char* c : {"info", "surface", "solve", "render", "compareA"}) {
        writeReference();
        if (std::string(c) == "compareA") writeBytes("ref.vdb", bytesOf(scene(n)));
        expectWorks(reader(c), "one.vdb");
    }
    auto d = openvdb::FloatGrid::create();
    d->setName("density");
    d->setTransform(xform(0.1));
    d->tree().setValueOn({-5, 0, 5}, 3.f);
    writeBytes("one.vdb", bytesOf({d}));
    for (const char* c : {"info", "solveCloud", "render"}) expectWorks(reader(c), "one.vdb");
}

TEST_F(MalformedTest, CoordinatesNearTheIndexLimitsWork)
{
    const int far = (1 << 30) - 64;
    for (const openvdb::Coord origin : {openvdb::Coord(far, far, far),
             openvdb::Coord(-far, -far, -far), openvdb::Coord(far, -far, 0)}) {
        SCOPED_TRACE(origin);
        writeBytes("far.vdb", bytesOf(scene(patch(openvdb::Vec3f(0, 1, 0), 0.1, origin))));
        for (const char* c : {"info", "surface", "solve", "render"}) {
            expectWorks(reader(c), "far.vdb");
        }
        writeBytes("far.vdb", bytesOf({fog(2.f, 0.1, origin)}));
        for (const char* c : {"info", "solveCloud", "render"}) expectWorks(reader(c), "far.vdb");
    }
}

// The bytes of the uniform scale map of voxel size @a s, as OpenVDB writes it: scale, voxel size,
// inverse scale, inverse scale squared, inverse twice the scale, each a Vec3d.
std::string
scaleMapBytes(double s)
{
    std::string out;
    for (double v : {s, s, 1.0 / s, 1.0 / (s * s), 0.5 / s}) {
        for (int k = 0; k < 3; ++k) out.append(reinterpret_cast<const char*>(&v), sizeof(v));
    }
    return out;
}

// @a grids written with voxel size 0.125, then every grid's scale map patched to @a size: files
// can hold voxel sizes that OpenVDB's API refuses to build (|det| too small, zero, negative).
std::string
bytesWithVoxelSize(const Grids& grids, double size)
{
    for (const auto& g : grids) g->setTransform(xform(0.125));
    return replaceAll(bytesOf(grids), scaleMapBytes(0.125), scaleMapBytes(size));
}

TEST_F(MalformedTest, AbsurdVoxelSizes)
{
    // The method works in index space: a voxel of 1e30 world units is only a scale.
    for (double size : {1e30}) {
        SCOPED_TRACE(size);
        writeBytes("scaled.vdb", bytesWithVoxelSize(scene(), size));
        ASSERT_EQ(readVdbFile(path("scaled.vdb")).grids[0]->voxelSize()[0], size);
        for (const char* c : {"info", "surface", "solve", "render"}) {
            expectWorks(reader(c), "scaled.vdb");
        }
        writeBytes("scaled.vdb", bytesWithVoxelSize({fog()}, size));
        for (const char* c : {"info", "solveCloud", "render"}) {
            expectWorks(reader(c), "scaled.vdb");
        }
    }
    // Not a positive finite number, or so small that OpenVDB's maps call it singular.
    for (double size : {0.0, -0.125, double(kNaN), double(kInf), 1e-30}) {
        writeBytes("bad.vdb", bytesWithVoxelSize(scene(), size));
        for (const char* c : {"info", "surface", "solve", "render"}) {
            expectRefused(reader(c), "bad.vdb", "has voxel size", std::to_string(size));
        }
    }
}

TEST_F(MalformedTest, HugeActiveTilesAreRefusedBeforeAllocating)
{
    // A few hundred bytes on disk, 4096^3 active voxels once densified.
    const openvdb::CoordBBox huge(openvdb::Coord(0), openvdb::Coord(4095));
    auto n = openvdb::Vec3SGrid::create();
    n->setName("normal");
    n->setTransform(xform(0.1));
    n->tree().fill(huge, openvdb::Vec3f(0, 1, 0), true);
    auto d = openvdb::FloatGrid::create();
    d->setName("density");
    d->setTransform(xform(0.1));
    d->tree().fill(huge, 1.f, true);
    writeReference();
    writeBytes("bad.vdb", bytesOf({n, like<openvdb::FloatGrid>(*patch(), "radiosity", 1.f)}));
    for (const char* c : {"info", "surface", "solve", "render"}) {
        expectRefused(reader(c), "bad.vdb", "too many voxels: 68719476736");
    }
    writeBytes("bad.vdb", bytesOf({d}));
    for (const char* c : {"info", "solveCloud", "render"}) {
        expectRefused(reader(c), "bad.vdb", "too many voxels: 68719476736");
    }
    auto r = openvdb::FloatGrid::create();
    r->setName("radiosity");
    r->tree().fill(huge, 1.f, true);
    writeBytes("bad.vdb", bytesOf({patch(), r}));
    for (const char* c : {"compareA", "compareB"}) {
        expectRefused(reader(c), "bad.vdb", "too many voxels: 68719476736");
    }
    // A level set's active voxels are densified to find its boundary: refused before that (this
    // one was found by fuzz/fuzz_scene.cc; it used to allocate without bound).
    auto ls = openvdb::FloatGrid::create(0.3f);
    ls->setName("surface");
    ls->setGridClass(openvdb::GRID_LEVEL_SET);
    ls->setTransform(xform(0.1));
    ls->tree().fill(huge, -0.3f, true);
    writeBytes("bad.vdb", bytesOf({ls}));
    for (const char* c : {"surface", "solve"}) {
        expectRefused(reader(c), "bad.vdb", "too many voxels: 68719476736");
    }
}

TEST_F(MalformedTest, HugeRequestsOnTheCommandLineAreRefused)
{
    // A usage error names no file: status 2, one line, the previous output kept.
    writeText("out.vdb", "old");
    test::ToolResult r = sh("vdbrad make cornell out.vdb --res 1000000");
    EXPECT_EQ(r.status, 2);
    ASSERT_EQ(r.errLines().size(), 1u) << r.err;
    EXPECT_EQ(r.errLines()[0], "vdbrad: error: --res must be in [1, 4096], got 1000000");
    EXPECT_EQ(slurp(path("out.vdb")), "old");
    // A mesh voxelized at a voxel size that would give billions of voxels.
    writeText("tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    const Command voxelize{"voxelize", "vdbrad voxelize IN OUT --quiet --voxel-size 1e-7",
        "out.vdb"};
    expectRefused(voxelize, "tri.obj", "surface voxels at voxel size 1e-07, above the limit");
}

// ---- meshes: `vdbrad voxelize` -----------------------------------------------------------------

struct MeshCase
{
    std::string name, file, text, what;
    std::string options = "--res 16";
};

void
PrintTo(const MeshCase& c, std::ostream* os)
{
    *os << c.name;
}

class MalformedMeshTest : public MalformedTest, public ::testing::WithParamInterface<MeshCase>
{
};

INSTANTIATE_TEST_SUITE_P(Cases, MalformedMeshTest, ::testing::Values(
    MeshCase{"VdbBytesAsObj", "bad.obj", "VDB \x0a\x01\x02 binary junk\n", "no triangles"},
    MeshCase{"EmptyObj", "bad.obj", "", "no triangles"},
    MeshCase{"EmptyPly", "bad.ply", "", "not a PLY file"},
    MeshCase{"TruncatedBinaryPly", "bad.ply", "ply\nformat binary_little_endian 1.0\n"
        "element vertex 3\nproperty float x\nproperty float y\nproperty float z\n"
        "element face 1\nproperty list uchar int vertex_indices\nend_header\n"
        "\x01\x02\x03\x04\x05\x06", "truncated: expected 3 vertices"},
    MeshCase{"NaNVertex", "bad.obj", "v 0 0 0\nv nan 0 0\nv 0 1 0\nf 1 2 3\n",
        "bad.obj:2: vertex coordinate nan is not a finite float"},
    MeshCase{"InfVertex", "bad.obj", "v 0 0 0\nv 1e39 0 0\nv 0 1 0\nf 1 2 3\n",
        "vertex coordinate 1e+39 is not a finite float"},
    MeshCase{"FaceIndexOutOfRange", "bad.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
        "face index 4"},
    MeshCase{"OnlyDegenerateTriangles", "bad.obj", "v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\n",
        ""},
    MeshCase{"CoordinatesBeyondTheIndexRange", "bad.obj",
        "v 0 0 0\nv 1e30 0 0\nv 0 1 0\nf 1 2 3\n", "outside the index range", "--voxel-size 1"}),
    [](const ::testing::TestParamInfo<MeshCase>& info) { return info.param.name; });

TEST_P(MalformedMeshTest, VoxelizeRefusesIt)
{
    writeBytes(GetParam().file, GetParam().text);
    const Command voxelize{"voxelize", "vdbrad voxelize IN OUT --quiet " + GetParam().options,
        "out.vdb"};
    expectRefused(voxelize, GetParam().file, GetParam().what);
}

TEST_F(MalformedTest, OneTriangleVoxelizes)
{
    writeText("tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    const Command voxelize{"voxelize", "vdbrad voxelize IN OUT --quiet --res 16", "out.vdb"};
    expectWorks(voxelize, "tri.obj");
}

// ---- the parser itself, without the tool: many mutations, from many threads ---------------------

TEST_F(MalformedTest, ParserSurvivesThousandsOfMutationsFromManyThreads)
{
    // Each parse forks a checking child (GridIO.h): it must report every mutation as parsed or
    // as an IoError, never crash or hang, also when TBB workers parse at the same time (the
    // child then forks from a worker thread while the others hold TBB's and malloc's state).
    const std::string surface = bytesOf(scene()), cloud = bytesOf({fog()});
    const unsigned n = 1000;
    std::vector<std::string> outcome(n);
    using Range = tbb::blocked_range<unsigned>;
    tbb::parallel_for(Range(0, n), [&](const Range& r) {
        for (unsigned seed = r.begin(); seed != r.end(); ++seed) {
            const std::string bytes = mutate(seed % 2 ? surface : cloud, seed, 1 + int(seed % 8));
            try {
                const VdbFile f = parseVdb(bytes);
                outcome[seed] = "parsed";
            } catch (const openvdb::IoError& e) {
                outcome[seed] = errorMessage(e);
            }
        }
    });
    size_t parsed = 0;
    std::string crashed;
    for (unsigned seed = 0; seed < n; ++seed) {
        ASSERT_FALSE(outcome[seed].empty());
        parsed += outcome[seed] == "parsed";
        if (outcome[seed].find("the OpenVDB reader crashed on it") != std::string::npos) {
            crashed += " " + std::to_string(seed);
        }
    }
    EXPECT_GT(parsed, 0u);
    EXPECT_LT(parsed, n);
    std::cout << n << " mutations: " << parsed << " parsed; crashed the reader in the checking "
              "child:" << crashed << "\n";
}

TEST_F(MalformedTest, ReaderCrashIsReportedNotInherited)
{
    // Mutation 45 of the scene (found by the test above) makes OpenVDB 10's reader crash. Every
    // command must report it as one error line, like any corrupt file.
    writeReference();
    writeBytes("bad.vdb", mutate(bytesOf(scene()), 45, 6));
    if (OPENVDB_LIBRARY_MAJOR_VERSION_NUMBER != 10) GTEST_SKIP() << "a crash of OpenVDB 10";
    for (const auto& c : readers()) {
        expectRefused(c, "bad.vdb", "corrupt VDB data (the OpenVDB reader crashed on it: ");
    }
}

TEST_F(MalformedTest, InfoGivesOneErrorLineForABadSurfaceAndABadCloud)
{
    auto n = patch();
    n->tree().setValue({1, 0, 1}, openvdb::Vec3f(kNaN, 0, 0));
    auto d = fog();
    d->tree().setValueOn({1, 2, 3}, -1.f);
    writeBytes("bad.vdb", bytesOf({n, d}));
    expectRefused(reader("info"), "bad.vdb", "normal at voxel (1, 0, 1) is");
    const test::ToolResult r = sh("vdbrad info bad.vdb");
    EXPECT_NE(r.out.find("  cloud:     error: density at voxel (1, 2, 3) is -1"),
        std::string::npos) << r.out;
}

} // namespace
