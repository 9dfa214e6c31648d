// libFuzzer target: untrusted `.vdb` bytes through everything the tool does with an input: parse
// (GridIO, with its crash guard), then Load.h (roles, Scene, Cloud, a tiny solve, render and
// write of small inputs).
//
// Run by scripts/fuzz.sh; by hand: VDBRAD_FUZZ_SEEDS=DIR build-hardening/fuzz/fuzz_load DIR.
// Seeds (Seeds.h): every canonical scene and cloud at 4 and 8 voxels, an explicit surface, a
// solved scene and cloud, and a level set, i.e. every kind of file the tool reads.
// GridIO parses in a forked child (GridIO.h): crashes of OpenVDB's reader are reported as
// IoErrors, so they do not stop the fuzzer; what stops it is a crash in vdbrad's own code. The
// fork makes each execution slow (tens per second), so fuzz_scene.cc covers the code after the
// parse at full speed.
#include "Load.h"
#include "Seeds.h"
#include "grids/CanonicalGrids.h"
#include "vdbrad/vdbrad.h"

#include <openvdb/tools/LevelSetSphere.h>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace {

void
load(const std::string& bytes)
{
    vdbrad::fuzz::useFile(vdbrad::parseVdb(bytes));
}

std::vector<std::string>
seeds()
{
    using namespace vdbrad;
    std::vector<std::string> out;
    auto add = [&](const openvdb::GridPtrVec& grids) {
        VdbFile f;
        f.grids = grids;
        out.push_back(serializeVdb(f));
    };
    for (const grids::Builder& b : grids::builders()) {
        // The step cloud's 32 columns need a multiple of 32 voxels.
        const std::vector<int> sizes = b.name == "step-cloud" ? std::vector<int>{32}
                                                               : std::vector<int>{4, 8};
        for (int res : sizes) {
            grids::BuildParams p;
            p.res = res;
            add(b.build(p));
        }
    }
    grids::BuildParams p;
    p.res = 8;
    const Scene cornell = buildScene(grids::makeCornell(p), SceneOptions());
    add(sceneToGrids(cornell));
    add({fuzz::tinySolve(cornell)});
    p.res = 4;
    add({fuzz::tinySolve(buildCloud(grids::makeSlab(p)))});
    auto sphere = openvdb::tools::createLevelSetSphere<openvdb::FloatGrid>(1.f, {0, 0, 0}, 0.25f);
    sphere->setName("surface");
    add({sphere});
    return out;
}

} // namespace

extern "C" int
LLVMFuzzerInitialize(int*, char***)
{
    vdbrad::fuzz::writeSeeds(seeds());
    return 0;
}

extern "C" int
LLVMFuzzerTestOneInput(const uint8_t* data, size_t size)
{
    try {
        load(std::string(reinterpret_cast<const char*>(data), size));
    } catch (const openvdb::Exception&) {
    } catch (const std::bad_alloc&) {
    }
    return 0;
}
