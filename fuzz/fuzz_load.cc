// libFuzzer target: untrusted `.vdb` bytes through everything the tool does with an input before
// the heavy solve: parse (GridIO, with its crash guard), the scene contract, the Scene and the
// Cloud, a tiny solve and render of small inputs, and the pass-through write.
//
// Build by hand (clang 14, libFuzzer from Debian's libclang-rt-14-dev), e.g.:
//   SAN=fuzzer-no-link,address,signed-integer-overflow,float-cast-overflow,bounds,shift
//   clang++ -std=c++17 -O1 -g -fsanitize=$SAN -I. -Ibuild/generated -isystem /usr/include/Imath \
//       -c fuzz/fuzz_load.cc vdbrad/*.cc     (all but ImageIO, Mesh, MonteCarloSolver and
//       Voxelizer; full -fsanitize=undefined trips on oneTBB's concurrent_hash_map)
//   clang++ -fsanitize=fuzzer,address,... *.o -lopenvdb -ltbb -lImath-3_1 -o fuzz_load
//   VDBRAD=build/vdbrad fuzz/make_corpus.sh seeds/
//   ./fuzz_load -jobs=2 -workers=2 -max_len=4096 -timeout=30 corpus/ seeds/
// GridIO parses in a forked child (GridIO.h): crashes of OpenVDB's reader are reported as
// IoErrors, so they do not stop the fuzzer (libFuzzer may still leave a crash-* file for a child
// that an ASan report ended); what stops it is a crash in vdbrad's own code.
// Expected failures are the library's exceptions (openvdb::Exception, std::bad_alloc for an
// absurd but valid size); anything else escaping, a crash or a sanitizer report is a finding.
#include "vdbrad/CloudTransfer.h"
#include "vdbrad/RadiositySolver.h"
#include "vdbrad/vdbrad.h"

#include <cstddef>
#include <cstdint>
#include <string>

namespace {

// Inputs small enough to solve and render on every execution; larger ones stop after building.
constexpr size_t kMaxSolvedVoxels = 4096;

void
load(const std::string& bytes)
{
    using namespace vdbrad;
    const VdbFile file = parseVdb(bytes);
    // `vdbrad info`: the description of every grid, whatever its type.
    for (const auto& g : file.grids) {
        (void)g->evalActiveVoxelBoundingBox();
        (void)g->activeVoxelCount();
        (void)g->transform().voxelSize();
    }
    const GridRoles roles = identifyRoles(file.grids);
    if (roles.surface) {
        try {
            const Scene scene = buildScene(file.grids, SceneOptions());
            // `vdbrad surface`: the scene's grids plus the input's, serialised.
            (void)serializeVdb(withGrids(file, sceneToGrids(scene)));
            if (scene.size() <= kMaxSolvedVoxels) {
                RadiosityOptions o;
                o.directions = 3;
                o.maxIterations = 1;
                RadiositySolver solver(scene, o);
                solver.solve();
                RenderOptions r;
                r.width = r.height = 4;
                (void)renderImage(withGrids(file, {solver.grid()}).grids, r);
            }
        } catch (const openvdb::Exception&) {
        }
    }
    if (roles.density) {
        try {
            const Cloud cloud = buildCloud(file.grids);
            if (cloud.size() <= kMaxSolvedVoxels) {
                CloudTransferOptions o;
                o.directions = 3;
                o.maxIterations = 1;
                CloudTransfer transfer(cloud, o);
                transfer.solve();
                (void)serializeVdb(withGrids(file, {transfer.grid()}));
            }
        } catch (const openvdb::Exception&) {
        }
    }
}

} // namespace

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
