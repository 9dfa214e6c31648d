// GridIO: whole-file reads from memory, errors on malformed bytes, atomic writes, round trips.
#include "vdbrad/CrashGuard.h"
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
