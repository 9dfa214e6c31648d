#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/surface/RadiositySolverImpl.h"
#include "vdbrad/core/ProcessInfo.h"

#include "vdbrad/core/Denormals.h"
#include "vdbrad/core/Errors.h"
#include "vdbrad/core/Precision.h"
#include "vdbrad/core/TextFormat.h"
#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/distribute/SlabDistribution.h"
#include "vdbrad/glossy/GlossySurfaces.h"
#include "vdbrad/sweep/Enclosure.h"
#include "vdbrad/sweep/LeafOrder.h"
#include "vdbrad/sweep/LineSweep.h"
#include "vdbrad/sweep/RayCastVisibility.h"
#include "vdbrad/sweep/SweepSchedule.h"
#include "vdbrad/sweep/VisibilityCache.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <sstream>
#include <tuple>
#include <type_traits>

#include <unistd.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif

namespace vdbrad {

namespace {

// Iterate @a solver to its end (SolveControl), framed as one progress step unless the control
// reports each iteration, and note the direct light's cost.
void
runSolver(RadiositySolver& solver, openvdb::util::NullInterrupter* interrupt,
    const SolveControl& control)
{
    const bool framed = interrupt && !control.beforeIteration;
    if (framed) interrupt->start("solving radiosity");
    iterateSolve(solver, control, interrupt);
    if (framed) interrupt->end();
    if (control.note && solver.exactDirect()) {
        const DirectIrradiance& d = solver.directLight();
        std::ostringstream os;
        os.precision(3);
        os << "direct light: " << withCommas(size_t(d.rays)) << " shadow rays, "
           << withCommas(size_t(d.factors)) << " form factors, " << d.seconds << " s";
        control.note(os.str());
    }
}

// Spread::Slabs under mpirun: this rank solves its slab of @a scene (SlabDistribution.h),
// with the regions and the direct light found on the whole scene, and rank 0 gathers the
// slabs' radiosity into the whole scene's grid. @a owned: the scene, where the caller gave it
// up, so that the ranks other than 0 free it once their slab is set up.
openvdb::GridBase::Ptr
solveSlabs(const Scene& scene, Scene* owned, const RadiosityOptions& options,
    openvdb::util::NullInterrupter* interrupt, const SolveControl& control)
{
    const Distribution& ranks = *options.ranks;   // distributed: solveRadiosity() checked
    if (!control.checkpoint.empty() || !control.resume.empty()) {
        OPENVDB_THROW(openvdb::ValueError, "a solve spread over slabs keeps no checkpoints");
    }
    const SlabPartition partition(scene.voxels(), ranks.ranks());
    const std::vector<uint32_t> mine = partition.voxelsOf(scene.voxels(), ranks.rank());
    auto context = std::make_shared<RadiositySolver::SlabContext>();
    context->frame.box = scene.voxels().bbox();
    context->frame.voxels = scene.size();
    context->slabs = ranks.ranks();
    context->wide = solvesInDouble(scene.albedo(), options.precision);
    context->exact = usesExactDirect(options.direct, scene, bool(options.sun));
    {
        Regions whole = findRegions(scene.voxels(), scene.normals(), options.lines,
            kEnclosureBlocks);
        context->regions.cavities = whole.cavities;
        context->regions.analysed = whole.analysed;
        context->regions.region.resize(mine.size());
        for (size_t k = 0; k < mine.size(); ++k) {
            context->regions.region[k] = whole.region[mine[k]];
        }
        if (context->exact) {
            context->emitters = Emitters(scene);
            DirectLightOptions d;
            d.samples = options.directSamples;
            d.ranks = options.ranks;
            d.sun = options.sun;
            // Shared out between the ranks in blocks (Distribution.h) and combined.
            DirectIrradiance D = directIrradiance(scene, context->emitters, d,
                whole.cavities > 0 ? &whole.region : nullptr, interrupt);
            context->direct = D;
            context->direct.irradiance.resize(mine.size());
            for (size_t k = 0; k < mine.size(); ++k) {
                context->direct.irradiance[k] = D.irradiance[mine[k]];
            }
        }
    }
    const Scene slab = scene.subset(mine);
    if (owned && ranks.rank() != 0) *owned = Scene();
#ifdef __GLIBC__
    // What the set-up on the whole scene freed (many small blocks) back to the system: what a
    // rank holds while it solves is then its slab's share.
    ::malloc_trim(0);
#endif
    RadiositySolver solver(slab, options, context);
    runSolver(solver, interrupt, control);
    // What each rank holds with its slab's solver: what falls with the ranks.
    const double resident = residentBytes();
    const double most = ranks.maximum(resident), least = -ranks.maximum(-resident);

    // The slabs' radiosity, in slab order, to rank 0.
    const bool rgb = solver.isRgb();
    const void* data = rgb ? static_cast<const void*>(solver.rgb().data())
                           : static_cast<const void*>(solver.grey().data());
    const size_t width = rgb ? sizeof(openvdb::Vec3f) : sizeof(float);
    const std::vector<std::vector<char>> parts = ranks.gather(data, mine.size() * width, 0);
    if (ranks.rank() != 0) return nullptr;
    std::vector<float> grey(rgb ? 0 : scene.size());
    std::vector<openvdb::Vec3f> colour(rgb ? scene.size() : 0);
    char* whole = rgb ? reinterpret_cast<char*>(colour.data())
                      : reinterpret_cast<char*>(grey.data());
    for (int r = 0; r < ranks.ranks(); ++r) {
        const std::vector<uint32_t> voxels = partition.voxelsOf(scene.voxels(), r);
        const std::vector<char>& part = parts[size_t(r)];
        if (part.size() != voxels.size() * width) {
            OPENVDB_THROW(openvdb::RuntimeError, "rank " << r << " sent " << part.size()
                << " bytes for " << voxels.size() << " voxels");
        }
        for (size_t k = 0; k < voxels.size(); ++k) {
            std::memcpy(whole + size_t(voxels[k]) * width, part.data() + k * width, width);
        }
    }
    if (control.note) {
        std::ostringstream os;
        os.precision(3);
        os << "slabs: " << ranks.ranks() << " ranks, rank 0 held " << withCommas(mine.size())
           << " of " << withCommas(scene.size()) << " voxels";
        if (most > 0.0) {
            os << "; resident while solving: " << formatBytes(least) << " to "
               << formatBytes(most) << " per rank";
        }
        control.note(os.str());
    }
    return rgb ? makeRadiosityGrid(scene, colour, solver.stats())
               : makeRadiosityGrid(scene, grey, solver.stats());
}

} // namespace

openvdb::GridBase::Ptr
solveRadiosity(Scene&& scene, const RadiosityOptions& options,
    openvdb::util::NullInterrupter* interrupt, const SolveControl& control,
    openvdb::GridBase::Ptr* specular)
{
    if (options.spread == Spread::Slabs && options.ranks && options.ranks->distributed()) {
        if (specular) specular->reset();
        return solveSlabs(scene, &scene, options, interrupt, control);
    }
    return solveRadiosity(static_cast<const Scene&>(scene), options, interrupt, control,
        specular);
}

openvdb::GridBase::Ptr
solveRadiosity(const Scene& scene, const RadiosityOptions& options,
    openvdb::util::NullInterrupter* interrupt, const SolveControl& control,
    openvdb::GridBase::Ptr* specular)
{
    if (options.spread == Spread::Slabs && options.ranks && options.ranks->distributed()) {
        if (specular) specular->reset();
        return solveSlabs(scene, nullptr, options, interrupt, control);
    }
    RadiositySolver solver(scene, options);
    runSolver(solver, interrupt, control);
    if (control.note && solver.cachedDirections() > 0) {
        control.note("visibility cache: " + std::to_string(solver.cachedDirections()) + " of "
            + std::to_string(solver.directions().size()) + " directions kept ("
            + formatBytes(double(solver.cacheBytes())) + ")");
    }
    if (control.note && solver.glossy()) {
        std::ostringstream os;
        os.precision(3);
        os << "glossy: " << solver.glossy()->describe() << ", set up in "
           << solver.glossy()->setupSeconds() << " s";
        control.note(os.str());
    }
    if (specular) *specular = solver.specularGrid();
    return solver.grid();
}

} // namespace vdbrad
