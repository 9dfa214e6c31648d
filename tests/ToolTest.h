// A fixture for tests that drive the `vdbrad` tool as a user does: a scratch folder per test and
// bash command lines in it, where `vdbrad` is the tool under test (VDBRAD_CLI_PATH).
#pragma once

#include <openvdb/openvdb.h>

#include <gtest/gtest.h>

#include <cstdlib>
#include <fstream>
#include <iterator>
#include <sstream>
#include <string>
#include <sys/stat.h>
#include <sys/wait.h>
#include <vector>

namespace vdbrad {
namespace test {

struct ToolResult
{
    int status = -1;
    std::string out, err;
    std::vector<std::string> errLines() const
    {
        std::vector<std::string> lines;
        std::istringstream is(err);
        for (std::string l; std::getline(is, l);) lines.push_back(l);
        return lines;
    }
};

inline std::string
slurp(const std::string& path)
{
    std::ifstream in(path, std::ios::binary);
    return std::string((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
}

inline bool
exists(const std::string& path)
{
    struct stat st;
    return ::stat(path.c_str(), &st) == 0;
}

// ---- small inputs shared by the tool tests ------------------------------------------------------

// A 6 x 6 patch of surface voxels facing +y, at index @a origin.
inline openvdb::Vec3SGrid::Ptr
patch(openvdb::Vec3f n = openvdb::Vec3f(0, 1, 0), double voxelSize = 0.1,
    openvdb::Coord origin = openvdb::Coord(0))
{
    auto g = openvdb::Vec3SGrid::create();
    g->setName("normal");
    g->setTransform(openvdb::math::Transform::createLinearTransform(voxelSize));
    for (int x = 0; x < 6; ++x) {
        for (int z = 0; z < 6; ++z) g->tree().setValueOn(origin.offsetBy(x, 0, z), n);
    }
    return g;
}

// A grid named @a name on @a ref's transform and active voxels, every value @a v.
template<typename GridT>
inline typename GridT::Ptr
like(const openvdb::GridBase& ref, const std::string& name, typename GridT::ValueType v)
{
    auto g = GridT::create();
    g->setName(name);
    g->setTransform(ref.transform().copy());
    const auto* r = dynamic_cast<const openvdb::Vec3SGrid*>(&ref);
    const auto* f = dynamic_cast<const openvdb::FloatGrid*>(&ref);
    if (r) {
        for (auto it = r->cbeginValueOn(); it; ++it) g->tree().setValueOn(it.getCoord(), v);
    }
    if (f) {
        for (auto it = f->cbeginValueOn(); it; ++it) g->tree().setValueOn(it.getCoord(), v);
    }
    return g;
}

class ToolTest : public ::testing::Test
{
protected:
    static void SetUpTestSuite() { openvdb::initialize(); }

    void SetUp() override
    {
        const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
        mDir = ::testing::TempDir() + "vdbrad_" + info->test_suite_name() + "_" + info->name()
            + "/";
        std::system(("rm -rf '" + mDir + "' && mkdir -p '" + mDir + "'").c_str());
    }

    std::string path(const std::string& name) const { return mDir + name; }

    void writeText(const std::string& name, const std::string& text) const
    {
        std::ofstream(path(name)) << text;
    }

    /// Run a bash command line in the test's folder, standard input closed.
    ToolResult sh(const std::string& cmd) const
    {
        const std::string out = mDir + ".stdout", err = mDir + ".stderr";
        const std::string full = "cd '" + mDir + "' && vdbrad() { '" VDBRAD_CLI_PATH "' \"$@\"; }; "
            + "{ " + cmd + "\n} > '" + out + "' 2> '" + err + "' < /dev/null";
        ToolResult r;
        const int status = std::system(("bash -c " + quote(full)).c_str());
        r.status = WIFEXITED(status) ? WEXITSTATUS(status) : -1;
        r.out = slurp(out);
        r.err = slurp(err);
        return r;
    }

    static std::string quote(const std::string& s)
    {
        std::string q = "'";
        for (char c : s) q += c == '\'' ? std::string("'\\''") : std::string(1, c);
        return q + "'";
    }

    std::string mDir;
};

} // namespace test
} // namespace vdbrad
