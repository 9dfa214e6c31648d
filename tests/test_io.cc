// GridIO: whole-file reads from memory, errors on malformed bytes, atomic writes, round trips;
// files as other tools write them (double, half and Vec3d grids, Houdini and Blender names).
#include "ToolTest.h"

#include "vdbrad/core/CrashGuard.h"
#include "vdbrad/vdbrad.h"

#include <openvdb/tools/LevelSetSphere.h>

#include <gtest/gtest.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <dirent.h>
#include <fstream>
#include <functional>
#include <iterator>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

using namespace vdbrad;

namespace {

class GridIOTest : public ::testing::Test
{
protected:
    static void SetUpTestSuite() { openvdb::initialize(); }

    std::string path(const std::string& name) const
    {
        return ::testing::TempDir() + "vdbrad_io_" + name;
    }

    static VdbFile sample()
    {
        VdbFile f;
        auto ls = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(8.f, {0, 0, 0}, 0.5f);
        ls->setName("surface");
        ls->insertMeta("houdini:note", openvdb::StringMetadata("keep me"));
        auto ids = openvdb::Int32Grid::create(-1);
        ids->setName("ids");
        ids->tree().setValueOn(openvdb::Coord(1, 2, 3), 42);
        auto vel = openvdb::Vec3SGrid::create();
        vel->setName("vel");
        vel->setVectorType(openvdb::VEC_CONTRAVARIANT_RELATIVE);
        vel->tree().setValueOn(openvdb::Coord(-5, 0, 9), openvdb::Vec3f(1, 2, 3));
        f.grids = {ls, ids, vel};
        f.metadata->insertMeta("creator", openvdb::StringMetadata("Houdini 20.0"));
        f.metadata->insertMeta("frame", openvdb::Int32Metadata(12));
        return f;
    }

    static size_t filesIn(const std::string& dir, const std::string& prefix)
    {
        size_t n = 0;
        if (DIR* d = ::opendir(dir.c_str())) {
            while (dirent* e = ::readdir(d)) {
                if (std::string(e->d_name).find(prefix) != std::string::npos) ++n;
            }
            ::closedir(d);
        }
        return n;
    }
};

} // namespace

TEST_F(GridIOTest, RoundTripKeepsGridsValuesAndMetadata)
{
    const VdbFile in = sample();
    writeVdbFile(in, path("roundtrip.vdb"));
    const VdbFile out = readVdbFile(path("roundtrip.vdb"));
    ASSERT_EQ(out.grids.size(), 3u);
    EXPECT_EQ(out.metadata->metaValue<std::string>("creator"), "Houdini 20.0");
    EXPECT_EQ(out.metadata->metaValue<int32_t>("frame"), 12);
    for (size_t i = 0; i < 3; ++i) {
        EXPECT_EQ(out.grids[i]->getName(), in.grids[i]->getName());
        EXPECT_EQ(out.grids[i]->valueType(), in.grids[i]->valueType());
        EXPECT_EQ(out.grids[i]->transform(), in.grids[i]->transform());
        EXPECT_EQ(out.grids[i]->getGridClass(), in.grids[i]->getGridClass());
        EXPECT_EQ(out.grids[i]->getVectorType(), in.grids[i]->getVectorType());
        EXPECT_EQ(out.grids[i]->activeVoxelCount(), in.grids[i]->activeVoxelCount());
        // Every metadata of the input survives (the writer adds file_* statistics of its own).
        for (auto m = in.grids[i]->beginMeta(); m != in.grids[i]->endMeta(); ++m) {
            ASSERT_TRUE((*out.grids[i])[m->first]) << m->first;
            EXPECT_EQ((*out.grids[i])[m->first]->str(), m->second->str()) << m->first;
        }
    }
    auto a = openvdb::gridPtrCast<openvdb::FloatGrid>(in.grids[0]);
    auto b = openvdb::gridPtrCast<openvdb::FloatGrid>(out.grids[0]);
    for (auto it = a->cbeginValueAll(); it; ++it) {
        ASSERT_EQ(b->tree().getValue(it.getCoord()), *it);
    }
    EXPECT_EQ(openvdb::gridPtrCast<openvdb::Int32Grid>(out.grids[1])->tree().getValue(
        openvdb::Coord(1, 2, 3)), 42);

    // Stream and file paths produce the same parse.
    std::ifstream s(path("roundtrip.vdb"), std::ios::binary);
    EXPECT_EQ(readVdbStream(s).grids.size(), 3u);
}

TEST_F(GridIOTest, MalformedBytesGiveIoErrors)
{
    const std::string good = serializeVdb(sample());
    auto message = [](const std::string& bytes) {
        try {
            parseVdb(bytes);
        } catch (const openvdb::IoError& e) {
            return errorMessage(e);
        }
        return std::string("no error");
    };
    EXPECT_EQ(message(""), "empty file");
    EXPECT_EQ(message("hello world, not a vdb"), "not a VDB file (bad magic number)");
    EXPECT_EQ(message(good.substr(0, 4)), "not a VDB file (bad magic number)");
    // Truncation anywhere (inside the header, the metadata, the grid descriptors, the voxel data)
    // must be an IoError, never a silent "0 grids" or a partial read.
    std::vector<size_t> cuts;
    for (size_t c = 8; c < 700; ++c) cuts.push_back(c);   // header, metadata, descriptors
    for (size_t k = 1; k < 64; ++k) cuts.push_back(good.size() * k / 64);
    for (size_t c = good.size() - 64; c < good.size(); ++c) cuts.push_back(c);
    for (size_t cut : cuts) {
        EXPECT_THROW(parseVdb(good.substr(0, cut)), openvdb::IoError) << "cut at " << cut;
    }
    EXPECT_EQ(parseVdb(good).grids.size(), 3u);
}

// The crash guard on work that returns, throws, crashes, spins or hangs: every outcome is one
// IoError naming what happened (or success), within the limits, and the parent goes on.
TEST_F(GridIOTest, GuardReportsHowTheChildEnded)
{
    auto outcome = [](const std::function<void()>& work, unsigned wall) {
        try {
            return std::string(runGuarded(work, 0, wall) ? "done" : "unavailable");
        } catch (const openvdb::IoError& e) {
            return errorMessage(e);
        }
    };
    EXPECT_EQ(outcome([] {}, 0), "done");
    EXPECT_EQ(outcome([] { OPENVDB_THROW(openvdb::IoError, "bad sizes"); }, 0), "bad sizes");
    EXPECT_EQ(outcome([] { std::raise(SIGSEGV); }, 0),
        "corrupt VDB data (the OpenVDB reader crashed on it: Segmentation fault)");
    EXPECT_EQ(outcome([] { std::abort(); }, 0),
        "corrupt VDB data (the OpenVDB reader crashed on it: Aborted)");
    // A deadlock spends no CPU time: only the wall-clock limit ends it (1 s here), after a
    // second try (the first hang may be a fork race). No wall time is asserted (how long the
    // guard waits is measured by benchmarks/bench_guard.cc): that the call returns at all, with
    // the deadline's message, after exactly two children that could only end by being killed
    // (each pauses for ever; the check below finds none left), is the property.
    const std::string tries = ::testing::TempDir() + "vdbrad_io_hung_tries";
    std::remove(tries.c_str());
    EXPECT_EQ(outcome([&] {
        if (std::FILE* f = std::fopen(tries.c_str(), "a")) {   // one byte per child
            std::fputc('x', f);
            std::fclose(f);
        }
        for (;;) ::pause();
    }, 1), "corrupt VDB data (the OpenVDB reader did not finish within 1 s, twice; it may have "
        "deadlocked)");
    std::ifstream triesFile(tries);
    const std::string started((std::istreambuf_iterator<char>(triesFile)),
        std::istreambuf_iterator<char>());
    EXPECT_EQ(started, "xx") << "one child per try, two tries";
    std::remove(tries.c_str());
    // A child that hangs only the first time (a lock inherited across fork) is given a second
    // chance: success, after one wall-clock limit.
    const std::string flag = ::testing::TempDir() + "vdbrad_io_hung_once";
    std::remove(flag.c_str());
    EXPECT_EQ(outcome([&] {
        if (std::FILE* f = std::fopen(flag.c_str(), "wx")) {   // the first child only
            std::fclose(f);
            for (;;) ::pause();
        }
    }, 1), "done");
    std::remove(flag.c_str());
    // Nothing is left behind: no zombie or running child.
    EXPECT_EQ(::waitpid(-1, nullptr, WNOHANG), -1);
    EXPECT_EQ(errno, ECHILD);
}

TEST_F(GridIOTest, AtomicWriteNeverLeavesPartialFiles)
{
    const std::string target = path("atomic.vdb");
    writeFileAtomic(target, "old contents");
    // A failing write (missing folder) throws and leaves nothing behind.
    EXPECT_THROW(writeFileAtomic(path("missing/dir/x.vdb"), "x"), openvdb::IoError);
    // Replacing works and leaves no temporary file in the folder.
    writeVdbFile(sample(), target);
    EXPECT_EQ(readVdbFile(target).grids.size(), 3u);
    EXPECT_EQ(filesIn(::testing::TempDir(), ".vdbrad_io_atomic.vdb.vdbrad-"), 0u);
    struct stat st;
    ASSERT_EQ(::stat(target.c_str(), &st), 0);
    EXPECT_TRUE(st.st_mode & S_IRGRP) << "output must not keep mkstemp's 0600 mode";
    EXPECT_THROW(readVdbFile(path("does-not-exist.vdb")), openvdb::IoError);
    EXPECT_THROW(readVdbFile(::testing::TempDir()), openvdb::IoError);
}

TEST_F(GridIOTest, WithGridsReplacesByNameAndKeepsTheRest)
{
    const VdbFile in = sample();
    auto replacement = openvdb::Int32Grid::create(0);
    replacement->setName("ids");
    auto added = openvdb::FloatGrid::create();
    added->setName("radiosity");
    const VdbFile out = withGrids(in, {replacement, added});
    ASSERT_EQ(out.grids.size(), 4u);
    EXPECT_EQ(out.grids[1], replacement);
    EXPECT_EQ(out.grids[0], in.grids[0]);
    EXPECT_EQ(out.grids[3], added);
    EXPECT_EQ(out.metadata->metaValue<std::string>("creator"), "Houdini 20.0");
}


// ---- files as other tools write them ------------------------------------------------------------

namespace {

class ForeignGridsTest : public test::ToolTest
{
protected:
    // A small fog volume: densities k / 8 (exact in half, float and double), an RGB albedo.
    static openvdb::FloatGrid::Ptr fog()
    {
        auto d = openvdb::FloatGrid::create(0.f);
        d->setName("density");
        d->setGridClass(openvdb::GRID_FOG_VOLUME);
        d->setTransform(openvdb::math::Transform::createLinearTransform(0.5));
        for (int x = 0; x < 10; ++x) {
            for (int y = 0; y < 10; ++y) {
                for (int z = 0; z < 10; ++z) {
                    d->tree().setValueOn({x, y, z}, float(1 + (x * 7 + y * 3 + z) % 13) / 8.f);
                }
            }
        }
        return d;
    }

    // @a from in double precision, every value, active or not (OpenVDB's value-converting tree
    // copy for scalars; vectors one voxel at a time).
    static openvdb::DoubleGrid::Ptr doubled(const openvdb::FloatGrid& from, const std::string& name)
    {
        auto to = openvdb::DoubleGrid::create(std::make_shared<openvdb::DoubleTree>(from.tree()));
        to->setName(name);
        to->setGridClass(from.getGridClass());
        to->setTransform(from.transform().copy());
        return to;
    }
    static openvdb::Vec3DGrid::Ptr doubled(const openvdb::Vec3SGrid& from, const std::string& name)
    {
        auto to = openvdb::Vec3DGrid::create(openvdb::Vec3d(from.background()));
        to->setName(name);
        to->setTransform(from.transform().copy());
        for (auto it = from.cbeginValueOn(); it; ++it) {
            to->tree().setValueOn(it.getCoord(), openvdb::Vec3d(*it));
        }
        return to;
    }

    static openvdb::Vec3SGrid::Ptr colour(const openvdb::FloatGrid& ref, const std::string& name)
    {
        auto c = openvdb::Vec3SGrid::create();
        c->setName(name);
        c->setTransform(ref.transform().copy());
        for (auto it = ref.cbeginValueOn(); it; ++it) {
            const openvdb::Coord p = it.getCoord();
            c->tree().setValueOn(p, openvdb::Vec3f(0.875f, 0.5f + 0.0625f * float(p.x() % 4),
                0.75f));
        }
        return c;
    }

    void write(const std::string& name, const openvdb::GridPtrVec& grids) const
    {
        VdbFile f;
        f.grids = grids;
        writeVdbFile(f, path(name));
    }

    // Every value of grid @a name in @a file, as RGB, in the order of the active voxels.
    std::vector<openvdb::Vec3f> values(const std::string& file, const std::string& name) const
    {
        const VdbFile f = readVdbFile(path(file));
        const auto g = findGrid(f.grids, name);
        std::vector<openvdb::Vec3f> v;
        if (!g) return v;
        if (auto s = openvdb::gridConstPtrCast<openvdb::FloatGrid>(g)) {
            for (auto it = s->cbeginValueOn(); it; ++it) v.emplace_back(*it);
        } else if (auto c = openvdb::gridConstPtrCast<openvdb::Vec3SGrid>(g)) {
            for (auto it = c->cbeginValueOn(); it; ++it) v.push_back(*it);
        }
        return v;
    }

    // The one error line of a failed command, which wrote nothing.
    void expectRefused(const test::ToolResult& r, const std::string& what) const
    {
        EXPECT_EQ(r.status, 1) << r.err;
        ASSERT_EQ(r.errLines().size(), 1u) << r.err;
        EXPECT_EQ(r.errLines()[0].rfind("vdbrad: error: ", 0), 0u) << r.err;
        EXPECT_NE(r.err.find(what), std::string::npos) << r.err;
        EXPECT_FALSE(test::exists(path("out.vdb")));
    }

    const std::string mOptions = " --directions 40 --sun 30,20 --tolerance 1e-6 --quiet";
};

} // namespace

// A simulator's double density and a half-precision file hold the float file's values (k / 8 is
// exact in all three): the solve must give its answer bit for bit. Houdini's `Cd` and Blender's
// `color` are the albedo when there is no `albedo` grid, Vec3d as well as Vec3f.
TEST_F(ForeignGridsTest, DoubleAndHalfFogVolumesSolveToTheFloatFilesAnswer)
{
    const auto density = fog();
    const auto albedo = colour(*density, "albedo");
    write("float.vdb", {density, albedo});
    write("double.vdb", {doubled(*density, "density"),
        doubled(*albedo, "Cd")});
    auto half = density->deepCopy();
    half->setSaveFloatAsHalf(true);
    auto halfAlbedo = colour(*density, "color");
    halfAlbedo->setSaveFloatAsHalf(true);
    write("half.vdb", {half, halfAlbedo});
    EXPECT_TRUE(readVdbFile(path("half.vdb")).grids[0]->saveFloatAsHalf());

    ASSERT_EQ(sh("vdbrad solve-cloud float.vdb float_out.vdb" + mOptions).status, 0);
    const auto reference = values("float_out.vdb", "mean_intensity");
    ASSERT_EQ(reference.size(), 1000u);
    float lo = 1e30f, hi = 0.f;
    for (const auto& v : reference) { lo = std::min(lo, v[1]); hi = std::max(hi, v[1]); }
    EXPECT_GT(lo, 0.f);
    EXPECT_LT(lo, 0.9f * hi);   // a real solve: the light varies through the cloud

    for (const std::string in : {"double", "half"}) {
        SCOPED_TRACE(in);
        const auto r = sh("vdbrad solve-cloud " + in + ".vdb " + in + "_out.vdb"
            + mOptions + " --verbose");
        ASSERT_EQ(r.status, 0) << r.err;
        EXPECT_EQ(values(in + "_out.vdb", "mean_intensity"), reference);
        if (in == "double") {
            EXPECT_NE(r.err.find("grid 'density': double values read as float"),
                std::string::npos) << r.err;
            EXPECT_NE(r.err.find("grid 'Cd' taken as the albedo"), std::string::npos) << r.err;
            EXPECT_NE(r.err.find("grid 'Cd': vec3d values read as vec3s"), std::string::npos)
                << r.err;
            // The input's grids pass through at their own precision.
            const VdbFile out = readVdbFile(path("double_out.vdb"));
            EXPECT_TRUE(findGrid(out.grids, "density")->isType<openvdb::DoubleGrid>());
            EXPECT_TRUE(findGrid(out.grids, "Cd")->isType<openvdb::Vec3DGrid>());
        } else {
            EXPECT_NE(r.err.find("grid 'density': stored as half floats"), std::string::npos)
                << r.err;
            EXPECT_NE(r.err.find("grid 'color' taken as the albedo"), std::string::npos) << r.err;
        }
    }
    // Without --verbose nothing is said.
    const auto quiet = sh("vdbrad solve-cloud double.vdb q.vdb" + mOptions);
    EXPECT_EQ(quiet.status, 0);
    EXPECT_EQ(quiet.err, "");
}

// A double level set (or Vec3d normals) gives the float file's scene: same voxels, same bits.
TEST_F(ForeignGridsTest, DoubleLevelSetsAndVec3dNormalsGiveTheFloatScene)
{
    auto ls = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(2.f, {0, 0, 0}, 0.25f);
    ls->setName("surface");
    auto emission = openvdb::FloatGrid::create(0.f);
    emission->setName("emission");
    emission->setTransform(ls->transform().copy());
    for (int x = -9; x <= 9; ++x) {
        for (int y = 5; y <= 9; ++y) {
            for (int z = -9; z <= 9; ++z) emission->tree().setValueOn({x, y, z}, 2.f);
        }
    }
    write("float.vdb", {ls, emission});
    write("double.vdb", {doubled(*ls, "surface"), emission});
    const std::string opts = " --directions 40 --quiet";
    ASSERT_EQ(sh("vdbrad solve float.vdb float_out.vdb" + opts).status, 0);
    const auto r = sh("vdbrad solve double.vdb double_out.vdb --verbose" + opts);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.err.find("grid 'surface': double values read as float"), std::string::npos);
    const auto reference = values("float_out.vdb", "radiosity");
    ASSERT_GT(reference.size(), 500u);
    EXPECT_EQ(values("double_out.vdb", "radiosity"), reference);

    // Normal grids: `vdbrad surface` writes the float scene; its normals as Vec3d solve alike.
    ASSERT_EQ(sh("vdbrad surface float.vdb voxels.vdb --quiet").status, 0);
    VdbFile voxels = readVdbFile(path("voxels.vdb"));
    for (auto& g : voxels.grids) {
        if (g->getName() == "normal") {
            g = doubled(*openvdb::gridPtrCast<openvdb::Vec3SGrid>(g), "normal");
        }
    }
    writeVdbFile(voxels, path("voxels_d.vdb"));
    ASSERT_EQ(sh("vdbrad solve voxels.vdb voxels_out.vdb" + opts).status, 0);
    ASSERT_EQ(sh("vdbrad solve voxels_d.vdb voxels_d_out.vdb" + opts).status, 0);
    EXPECT_EQ(values("voxels_d_out.vdb", "radiosity"), values("voxels_out.vdb", "radiosity"));
    // `info` says how it read them.
    const auto info = sh("vdbrad info voxels_d.vdb");
    EXPECT_EQ(info.status, 0) << info.err;
    EXPECT_NE(info.out.find("read:      grid 'normal': vec3d values read as vec3s"),
        std::string::npos) << info.out;
}

// Simulators name their fields freely: --density picks one, and without it the error names the
// fog volumes there are. A fog volume stored as active tiles is the same medium as its voxels.
TEST_F(ForeignGridsTest, DensityByNameAndFogVolumesStoredAsTiles)
{
    auto smoke = fog();
    smoke->setName("smoke");
    write("smoke.vdb", {smoke});
    expectRefused(sh("vdbrad solve-cloud smoke.vdb out.vdb" + mOptions),
        "no cloud: expected a float grid named 'density' (the file's fog volumes: 'smoke'; "
        "choose one with --density NAME)");
    const auto info = sh("vdbrad info smoke.vdb --density smoke");
    EXPECT_EQ(info.status, 0) << info.err;
    EXPECT_NE(info.out.find("1,000 medium voxels from 'smoke'"), std::string::npos) << info.out;
    ASSERT_EQ(sh("vdbrad solve-cloud smoke.vdb out.vdb --density smoke" + mOptions).status, 0);
    EXPECT_EQ(values("out.vdb", "mean_intensity").size(), 1000u);

    // Two 8^3 tiles of density 0.5 beside each other, against the same voxels one by one.
    auto tiles = openvdb::FloatGrid::create(0.f);
    tiles->setName("density");
    tiles->setTransform(openvdb::math::Transform::createLinearTransform(0.25));
    tiles->tree().addTile(1, openvdb::Coord(0, 0, 0), 0.5f, true);
    tiles->tree().addTile(1, openvdb::Coord(8, 0, 0), 0.5f, true);
    EXPECT_EQ(tiles->tree().leafCount(), 0u);
    auto dense = tiles->deepCopy();
    dense->tree().voxelizeActiveTiles();
    write("tiles.vdb", {tiles});
    write("dense.vdb", {dense});
    ASSERT_EQ(sh("vdbrad solve-cloud tiles.vdb t.vdb --directions 40 --quiet").status, 0);
    ASSERT_EQ(sh("vdbrad solve-cloud dense.vdb d.vdb --directions 40 --quiet").status, 0);
    const auto t = values("t.vdb", "mean_intensity");
    EXPECT_EQ(t.size(), 1024u);
    EXPECT_EQ(t, values("d.vdb", "mean_intensity"));
}

// What the solvers cannot take is one line naming the grid, exit 1, no output.
TEST_F(ForeignGridsTest, UnusableGridsAreRefusedInOneLine)
{
    auto stretched = fog();
    openvdb::math::Mat4d scale = openvdb::math::Mat4d::identity();
    scale.preScale(openvdb::Vec3d(0.5, 0.5, 1.0));
    stretched->setTransform(openvdb::math::Transform::createLinearTransform(scale));
    write("stretched.vdb", {stretched});
    expectRefused(sh("vdbrad solve-cloud stretched.vdb out.vdb" + mOptions),
        "grid 'density' has non-cubic voxels");

    auto huge = doubled(*fog(), "density");
    huge->tree().setValueOn({3, 4, 5}, 1e300);
    write("huge.vdb", {huge});
    expectRefused(sh("vdbrad solve-cloud huge.vdb out.vdb" + mOptions),
        "grid 'density' holds 1e+300 at (3, 4, 5), beyond single precision");

    auto ints = openvdb::Int32Grid::create(0);
    ints->setName("density");
    ints->tree().setValueOn({0, 0, 0}, 1);
    write("ints.vdb", {ints});
    expectRefused(sh("vdbrad solve-cloud ints.vdb out.vdb" + mOptions),
        "grid 'density' (density) has type int32, expected float or double");

    auto bright = fog();
    write("bright.vdb", {bright, test::like<openvdb::Vec3DGrid>(*bright, "Cd",
        openvdb::Vec3d(0.5, 1.5, 0.5))});
    expectRefused(sh("vdbrad solve-cloud bright.vdb out.vdb" + mOptions), "albedo");
}

// A fire as Blender and Houdini write it: `density` and `flame`. The flame is read as the
// medium's emission (radiance per world unit), so a solve with no sun is lit by it; a colour
// gives an RGB solve whose channels are the grey one's times the colour; the render of the
// solved file emits as the solve did (its settings are in the result's metadata); flame where
// there is no density is named in a warning; a named emission grid that is missing is refused.
TEST_F(ForeignGridsTest, FlameGridsEmitLight)
{
    const auto density = fog();
    auto flame = openvdb::FloatGrid::create(0.f);
    flame->setName("flame");
    flame->setTransform(density->transform().copy());
    for (int x = 3; x < 7; ++x) {
        for (int y = 0; y < 4; ++y) {
            for (int z = 3; z < 7; ++z) flame->tree().setValueOn({x, y, z}, 2.f);
        }
    }
    write("fire.vdb", {density, flame});
    const std::string opts = " --directions 40 --irradiance 0 --tolerance 1e-7 --quiet";
    const auto grey = sh("vdbrad solve-cloud fire.vdb grey.vdb" + opts);
    ASSERT_EQ(grey.status, 0) << grey.err;
    const auto J = values("grey.vdb", "mean_intensity");
    ASSERT_EQ(J.size(), 1000u);
    float hottest = 0.f, coldest = 1e30f;
    for (const auto& v : J) { hottest = std::max(hottest, v[0]); coldest = std::min(coldest, v[0]); }
    EXPECT_GT(coldest, 0.f);                 // every voxel sees the fire
    EXPECT_GT(hottest, 20.f * coldest);      // and the fire is brightest

    const auto rgb = sh("vdbrad solve-cloud fire.vdb rgb.vdb --emission-color 1,0.5,0.25" + opts);
    ASSERT_EQ(rgb.status, 0) << rgb.err;
    const auto C = values("rgb.vdb", "mean_intensity");
    ASSERT_EQ(C.size(), J.size());
    for (size_t i = 0; i < J.size(); ++i) {
        for (int c = 0; c < 3; ++c) {
            const float k = c == 0 ? 1.f : (c == 1 ? 0.5f : 0.25f);
            ASSERT_NEAR(C[i][c], k * J[i][0], 1e-6f * J[i][0]) << i << " " << c;
        }
    }
    const VdbFile solved = readVdbFile(path("rgb.vdb"));
    const auto result = findGrid(solved.grids, "mean_intensity");
    EXPECT_EQ(result->metaValue<std::string>("vdbrad:emission"), "flame");
    EXPECT_EQ(result->metaValue<openvdb::Vec3f>("vdbrad:emission_color"),
        openvdb::Vec3f(1.f, 0.5f, 0.25f));
    // Rendered, the fire shows in its colour without any option repeated (the image is the grey
    // one times the colour), and brighter than the scattered light alone (flame left out).
    const auto lit = sh("vdbrad render grey.vdb lit.exr --res 32x32 --png lit.png --quiet");
    EXPECT_EQ(lit.status, 0) << lit.err;
    RenderOptions ro;
    ro.width = ro.height = 32;
    auto sum = [&](const openvdb::GridPtrVec& grids) {
        openvdb::Vec3d total(0.0);
        for (const auto& p : renderImage(grids, ro).pixels) total += openvdb::Vec3d(p);
        return total;
    };
    const openvdb::Vec3d orange = sum(solved.grids);
    VdbFile plain = readVdbFile(path("grey.vdb"));
    const openvdb::Vec3d white = sum(plain.grids);
    EXPECT_NEAR(orange[1], 0.5 * white[1], 1e-5 * white[1]);
    EXPECT_NEAR(orange[2], 0.25 * white[2], 1e-5 * white[2]);
    plain.grids.erase(std::remove_if(plain.grids.begin(), plain.grids.end(),
        [](const openvdb::GridBase::Ptr& g) { return g->getName() == "flame"; }),
        plain.grids.end());
    for (auto& g : plain.grids) g->removeMeta("vdbrad:emission");   // as solved without fire
    const openvdb::Vec3d scattered = sum(plain.grids);
    EXPECT_GT(white[0], 1.1 * scattered[0]);   // measured 1.20 (a conservative fog: J is most of it)
    std::printf("fire rendered: %.4g with its emission, %.4g scattered light alone\n", white[0],
        scattered[0]);

    // Flame outside the smoke emits nothing here, and is said so.
    auto spill = flame->deepCopy();
    spill->tree().setValueOn({20, 0, 0}, 5.f);
    write("spill.vdb", {density, spill});
    const auto warned = sh("vdbrad solve-cloud spill.vdb spill_out.vdb --directions 40 "
        "--irradiance 0");
    EXPECT_EQ(warned.status, 0) << warned.err;
    EXPECT_NE(warned.err.find("vdbrad: warning: spill.vdb: 1 voxels of 'flame' emit where "
        "'density' is 0 or inactive"), std::string::npos) << warned.err;
    expectRefused(sh("vdbrad solve-cloud fire.vdb out.vdb --emission heat" + opts),
        "no emission grid named 'heat'");
    expectRefused(sh("vdbrad solve-cloud fire.vdb out.vdb --emission-color 1,-1,1" + opts),
        "emission scale and colour must be >= 0");
}
