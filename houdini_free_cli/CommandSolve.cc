// `vdbrad solve`: the radiosity of a surface scene, by the line sweeps (RadiositySolver) or a
// reference: ray marching along the same lines, or Monte Carlo rays (MonteCarloSolver).
#include "Commands.h"
#include "Progress.h"
#include "SolveSupport.h"
#include "ToolSupport.h"

#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/reference/MonteCarloSolver.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/vdbrad.h"

#include <algorithm>
#include <iostream>
#include <utility>

namespace vdbrad {
namespace cli {

namespace {

// --visibility-cache: bytes, or -1 for auto (half of what --max-memory leaves to the solve).
double
visibilityCacheOption(const Arguments& a)
{
    const std::string text = a.getString("visibility-cache");
    return text == "auto" ? -1.0 : parseBytes("visibility-cache", text, true);
}

} // namespace

int
runSolve(const Arguments& a)
{
    const std::string in = a.positional()[0], out = a.positional()[1];
    const SceneOptions sceneOpts = sceneOptions(a);
    RadiosityOptions o;
    o.ranks = &job();
    o.directions = a.getInt("directions");
    o.maxIterations = a.getInt("iterations");
    o.tolerance = a.getFloat("tolerance");
    o.occlusionDepth = float(a.getFloat("occlusion-depth"));
    const std::string method = a.getString("method");
    if (method == "sweep") o.visibility = Visibility::Sweep;
    else if (method == "raycast") o.visibility = Visibility::RayCast;
    MonteCarloOptions mc;
    mc.samples = a.getInt("samples");
    mc.maxIterations = o.maxIterations;
    mc.tolerance = o.tolerance;
    const int gather = a.getInt("gather");
    if (gather > 0 && method != "montecarlo") {
        throw UsageError("--gather applies only to --method montecarlo");
    }
    o.update = choice<UpdateScheme>(a, "update", {{"jacobi", UpdateScheme::Jacobi},
        {"inplace", UpdateScheme::InPlace}, {"progressive", UpdateScheme::Progressive}});
    o.accelerate = accelerationFromString(a.getString("accelerate"));
    o.andersonDepth = a.getInt("anderson-depth");
    if (o.accelerate != Acceleration::None) {
        if (o.update == UpdateScheme::Progressive) {
            throw UsageError("--accelerate needs --update jacobi or inplace, not progressive");
        }
        if (method == "montecarlo") {
            throw UsageError("--accelerate does not apply to --method montecarlo");
        }
    }
    o.lines = choice<LineType>(a, "lines",
        {{"naive", LineType::Naive}, {"standard", LineType::Standard}});
    o.precision = precisionFromString(a.getString("precision"));
    o.direct = choice<DirectMode>(a, "direct", {{"auto", DirectMode::Auto},
        {"exact", DirectMode::Exact}, {"sweep", DirectMode::Sweep}});
    o.directSamples = a.getInt("direct-samples");
    o.glossy.model = brdfModelFromName(a.getString("brdf"));
    o.glossy.controlPoints = a.getInt("control-points");
    if (a.getInt("harmonics") > 0) {
        if (a.has("control-points") || a.has("glossy-rotation")) {
            throw UsageError("--harmonics replaces the control points: drop --control-points "
                             "and --glossy-rotation");
        }
        o.glossy.basis = GlossyBasis::Harmonics;
        o.glossy.harmonicOrder = a.getInt("harmonics");
    }
    o.glossy.rotation = choice<ControlPoints::RotationKind>(a, "glossy-rotation",
        {{"resampled", ControlPoints::RotationKind::Resampled},
            {"continuous", ControlPoints::RotationKind::Continuous},
            {"permutation", ControlPoints::RotationKind::Permutation}});
    if (method == "montecarlo" && (a.has("direct") || a.has("direct-samples"))) {
        throw UsageError("--direct and --direct-samples do not apply to --method montecarlo");
    }
    if (method == "montecarlo" && o.precision != Precision::Auto) {
        throw UsageError("--precision does not apply to --method montecarlo");
    }
    const double cache = visibilityCacheOption(a);
    if (a.has("visibility-cache") && method != "sweep") {
        throw UsageError("--visibility-cache applies only to --method sweep");
    }
    if (method == "montecarlo" && (a.has("checkpoint") || a.has("resume"))) {
        throw UsageError("--checkpoint and --resume do not apply to --method montecarlo");
    }
    o.spread = a.getString("distribute") == "slabs" ? Spread::Slabs : Spread::Directions;
    const bool slabs = o.spread == Spread::Slabs && job().distributed();
    if (o.spread == Spread::Slabs) {
        // What the slab passes do not carry (RadiosityOptions::spread).
        if (method != "sweep") throw UsageError("--distribute slabs needs --method sweep");
        if (o.lines != LineType::Naive) throw UsageError("--distribute slabs needs naive lines");
        if (o.accelerate != Acceleration::None) {
            throw UsageError("--distribute slabs does not take --accelerate");
        }
        if (a.has("checkpoint") || a.has("resume")) {
            throw UsageError("--distribute slabs keeps no checkpoints (--checkpoint, --resume)");
        }
        if (a.has("visibility-cache") && cache != 0.0) {
            throw UsageError("--distribute slabs uses no --visibility-cache (a replay reads "
                             "other ranks' voxels)");
        }
    }
    SolveSession session(a, in, out);
    const VdbFile& file = session.file();
    const std::string& label = session.label();
    describeReading(a, label, file, sceneOpts.surface, names::kDensity);
    ProgressInterrupter& progress = session.progress();
    Scene scene = forFile(label, [&] {
        return buildScene(file.grids, sceneOpts, &progress);
    });
    if (!scene.hasEmission()) warn(label, "nothing emits: the scene is dark");
    if (scene.raisedRoughness() > 0) {
        warn(label, std::to_string(scene.raisedRoughness()) + " glossy voxels have a roughness "
            "below 0.1, raised to 0.1 (control points resolve no sharper lobe)");
    }
    if (scene.isGlossy() && o.spread == Spread::Slabs) {
        throw UserError(label + ": glossy surfaces (a `specular` grid) are not solved with "
            "--distribute slabs");
    }
    if (scene.isGlossy() && method != "sweep") {
        throw UserError(label + ": glossy surfaces (a `specular` grid) are solved by the line "
            "sweeps only (--method sweep)");
    }
    if (scene.isGlossy() && o.accelerate != Acceleration::None) {
        warn(label, "glossy surfaces are not Anderson-accelerated: solving without it");
        o.accelerate = Acceleration::None;
    }
    if (scene.isGlossy() && o.update == UpdateScheme::Progressive) {
        throw UserError(label + ": glossy surfaces need --update inplace or jacobi");
    }
    if (findGrid(file.grids, names::kDensity)) {
        warn(label, "the fog ('density') is not part of this solve: `vdbrad solve-cloud` solves "
            "the surfaces and the fog together");
    }
    session.releaseInput();
    if (method == "montecarlo") {
        mc.gather = gather;
        session.finish(solveMonteCarlo(scene, mc, &progress, session.control("")), out,
            mc.maxIterations);
        return 0;
    }
    const double held = heldBytes(double(fileBytes(file) + scene.memUsage()));
    // Auto: half of what the limit leaves once the solve has what it needs without a cache.
    o.visibilityCache = slabs ? 0 : cache >= 0.0 ? size_t(std::min(cache, 1e18))
        : RadiositySolver::visibilityCacheFor(scene, o, workerThreads(), memoryLimit(a) - held);
    const std::string memory = checkMemory(a, label, held,
        double(RadiositySolver::memoryEstimate(scene, o, workerThreads())));
    openvdb::GridBase::Ptr specular;
    // Given up: with slabs, the ranks other than 0 free it once their slab is set up.
    openvdb::GridBase::Ptr radiosity = solveRadiosity(std::move(scene), o, &progress,
        session.control(memory), &specular);
    openvdb::GridPtrVec results{radiosity};
    if (specular) results.push_back(specular);
    session.finish(results, out, o.maxIterations);
    return 0;
}

} // namespace cli
} // namespace vdbrad
