#include "vdbrad/request/SurfaceRequest.h"

#include "vdbrad/request/SharedOptions.h"

#include "vdbrad/core/Errors.h"
#include "vdbrad/core/GridContract.h"
#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/glossy/Brdf.h"
#include "vdbrad/glossy/ControlPoints.h"
#include "vdbrad/render/ImageIO.h"
#include "vdbrad/scene/Sky.h"
#include "vdbrad/sweep/Acceleration.h"
#include "vdbrad/sweep/DirectionSet.h"

#include <openvdb/Exceptions.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <optional>
#include <sstream>
#include <utility>

namespace vdbrad {

namespace {

// Cost of one voxel and direction pair per iteration on one core of the CI machine
// (docs/performance.md: 2.9-3.3 ns diffuse); glossy voxels carry a distribution each (~10x).
constexpr double kDiffuseSeconds = 3.3e-9, kGlossySeconds = 3.3e-8;

std::vector<OptionSpec>
solverOptions()
{
    return {
        options::directions(),
        OptionSpec{"iterations", OptionType::Int, "200", "50", "iteration cap"}.atLeast(1),
        OptionSpec{"tolerance", OptionType::Float, "1e-5", "1e-4",
            "stop when max|B' - B| / max|B'| falls below this"}.atLeast(0),
        OptionSpec{"update", OptionType::String, "inplace", "jacobi",
            "inplace (B updated after each half of the directions; fewer iterations), "
            "jacobi (thesis eq. 4.11) or progressive (shoots the unshot radiosity: "
            "iteration k = k bounces)"}.oneOf({"jacobi", "inplace", "progressive"}),
        OptionSpec{"method", OptionType::String, "sweep", "raycast",
            "sweep (the line sweeps), raycast (reference: marches every receiver's line "
            "through the tree; same lines and rule, far slower) or montecarlo "
            "(reference: cosine-weighted continuous rays; also writes radiosity_stderr; "
            "ignores --directions, --lines, --update)"}
            .oneOf({"sweep", "raycast", "montecarlo"}),
        OptionSpec{"samples", OptionType::Int, "256", "4096",
            "rays per voxel for --method montecarlo (stored: 4 bytes each)"}.within(1, 1000000),
        OptionSpec{"gather", OptionType::Int, "0", "4096",
            "--method montecarlo: a final gather of this many fresh rays per voxel from "
            "the solved --samples pass (not stored: a low-noise reference in the memory "
            "of --samples; 256 samples are enough), 0 for none"}.within(0, 1000000),
        OptionSpec{"lines", OptionType::String, "naive", "standard",
            "digital lines: naive (26-connected) or standard (6-connected)"}
            .oneOf({"naive", "standard"}),
        OptionSpec{"occlusion-depth", OptionType::Float, "1", "1.5",
            "voxels: a receiver this far behind the wall voxel before it is hidden"}.above(0),
        OptionSpec{"precision", OptionType::String, "auto", "double",
            "the solver's state (auto: double when an albedo exceeds 0.999, where float "
            "rounding, amplified by 1 / (1 - albedo), would show)"}
            .oneOf({toString(Precision::Auto), toString(Precision::Float),
                toString(Precision::Double)}),
        {"visibility-cache", OptionType::String, "auto", "2G",
            "memory for remembering what each voxel sees along each direction (~1.2 "
            "bytes per voxel and direction, ~0.8 where it is short of all of them), so "
            "that iterations after the first replay "
            "it instead of sweeping (3-4x faster, same result): a size (K, M, G, T), 0 "
            "for none, or auto: half of what --max-memory leaves"},
        OptionSpec{"distribute", OptionType::String, "directions", "slabs",
            "under mpirun: directions (every rank holds the scene and sweeps its share "
            "of the directions) or slabs (every rank holds one slab of the scene along x "
            "and sweeps every direction over it, passing line fronts to its neighbours: "
            "memory per rank falls with the ranks; one thread per rank, naive lines, "
            "diffuse scenes, no cache, checkpoints or --accelerate); the same result"}
            .oneOf({"directions", "slabs"}),
        OptionSpec{"direct", OptionType::String, "auto", "exact",
            "light straight from the emitters: exact (integrated over the emitters' "
            "surfaces with shadow rays: no stripes; the sweeps carry the reflected light), "
            "sweep (through the directions, like every bounce) or auto (exact unless "
            "more than half of the surface emits)"}.oneOf({"auto", "exact", "sweep"}),
        OptionSpec{"direct-samples", OptionType::Int, "16", "64",
            "shadow rays per voxel for exact direct light (4x more where they disagree: "
            "penumbrae)"}.within(1, 65536),
        OptionSpec{"brdf", OptionType::String, "phong", "ggx",
            "glossy voxels' lobe (files with a `specular` grid): phong (normalised), "
            "blinn-phong or ggx"}.oneOf({"phong", "blinn-phong", "ggx"}),
        OptionSpec{"control-points", OptionType::Int, "162", "642",
            "points of each glossy voxel's radiance distribution: 12, 42, 162, 642 or "
            "2562 (finer lobes, more memory: ~110 bytes per point and glossy voxel in RGB)"}
            .oneOf({"12", "42", "162", "642", "2562"}),
        OptionSpec{"harmonics", OptionType::Int, "0", "8",
            "instead of control points, real spherical harmonics of this order carry "
            "the glossy distributions ((L+1)^2 coefficients; the thesis' alternative, "
            "slower and ringing: for comparisons; 0: control points)"}.within(0, 32),
        OptionSpec{"glossy-rotation", OptionType::String, "resampled", "permutation",
            "how lobes are turned to each normal: resampled, continuous or permutation "
            "(the thesis' two)"}.oneOf({"resampled", "continuous", "permutation"}),
        options::accelerate(),
        options::andersonDepth(),
    };
}

std::vector<OptionSpec>
lightOptions()
{
    std::vector<OptionSpec> o = options::sky();
    o.insert(o.begin() + 3, OptionSpec{"ground-albedo", OptionType::Float, "0.2", "0.3",
        "--sky-model clear: the ground below the horizon reflects the sky's and the sun's "
        "light with this albedo"}.within(0, 1));
    for (OptionSpec spec : std::vector<OptionSpec>{
        {"sun", OptionType::String, "", "40,30",
            "a sun: zenith angle from the --up axis, in [0, 90), and azimuth from the first "
            "horizontal axis towards the second (up y: x then z), degrees, as for solve-cloud; "
            "its first collision computed exactly with shadow rays (a soft shadow from its "
            "disk), its reflections carried by the sweeps"},
        {"irradiance", OptionType::String, "1", "3",
            "--sun: irradiance on a plane normal to the beam (grey, or linear r,g,b)"},
        OptionSpec{"sun-diameter", OptionType::Float, "0.53", "2",
            "--sun: the disk's angular diameter, degrees (the penumbra's width)"}.within(0, 10),
        options::up()}) {
        o.push_back(std::move(spec));
    }
    return o;
}

// --sun and what comes with it; none without --sun.
std::optional<Sun>
sunOf(const Request& r, const std::string& method, DirectMode direct)
{
    if (!r.has("sun")) {
        for (const char* name : {"irradiance", "sun-diameter"}) {
            if (r.has(name)) r.fail(r.spell(name) + " needs " + r.spell("sun"));
        }
        return std::nullopt;
    }
    const std::vector<double> angles = r.numbers("sun", 2, "zenith,azimuth in degrees");
    Sun sun;
    sun.zenith = angles[0];
    sun.azimuth = angles[1];
    if (!(sun.zenith >= 0.0 && sun.zenith < 90.0)) {
        r.fail(r.spell("sun") + ": the zenith angle must be in [0, 90) degrees");
    }
    sun.up = r.choice<int>("up", {{"x", 0}, {"y", 1}, {"z", 2}});
    sun.irradiance = r.colour("irradiance");
    sun.diameter = r.getFloat("sun-diameter");
    if (method == "montecarlo") {
        r.fail(r.spell("sun") + " does not apply to " + r.spell("method") + " montecarlo");
    }
    if (direct == DirectMode::Sweep) {
        r.fail(r.spell("sun") + " is computed exactly: it needs " + r.spell("direct")
            + " exact or auto");
    }
    return sun;
}

// The light options, and the metadata naming them on a solved file (solvedLight()).
const char* const kLightOptions[] = {"sky", "sky-model", "turbidity", "ground-albedo",
    "environment", "environment-rotation", "sun", "irradiance", "sun-diameter", "up"};
const char* const kLightMeta = "vdbrad:light";

} // namespace

void
recordLight(const Request& r, openvdb::GridBase& grid)
{
    std::string text;
    for (const char* name : kLightOptions) {
        if (!r.find(name) || !r.has(name)) continue;
        // solve-cloud's own: its ground layer's albedo, the vertical axis of its default sun.
        if (std::string(name) == "ground-albedo" && r.getString("sky-model") != "clear") continue;
        if (std::string(name) == "up" && !r.has("sun") && !r.has("environment")) continue;
        std::string value = r.getString(name);
        // The map from wherever the picture is made.
        if (std::string(name) == "environment") value = std::filesystem::absolute(value).string();
        text += std::string(name) + "=" + value + "\n";
    }
    if (!text.empty()) grid.insertMeta(kLightMeta, openvdb::StringMetadata(text));
}

namespace {

// The light from outside the scene: --sky, --sky-model, --environment, --sun; the map's sun,
// if it has one, becomes the solve's.
void
lightOf(const Request& r, const std::string& method, RadiosityOptions& o)
{
    o.sun = sunOf(r, method, o.direct);
    if (r.has("ground-albedo") && r.getString("sky-model") != "clear") {
        r.fail(r.spell("ground-albedo") + " needs " + r.spell("sky-model") + " clear");
    }
    if (r.has("up") && !r.has("sun") && !r.has("environment")) {
        r.fail(r.spell("up") + " needs " + r.spell("sun") + " or " + r.spell("environment"));
    }
    o.sky = options::skyOf(r, o.sun, r.getFloat("ground-albedo"),
        r.choice<int>("up", {{"x", 0}, {"y", 1}, {"z", 2}}));
    if (o.sky.empty()) return;
    if (method == "montecarlo") {
        r.fail("a sky does not apply to " + r.spell("method") + " montecarlo");
    }
    if (const auto& sun = o.sky.sun()) {
        if (o.sun) {
            r.fail(r.spell("environment") + " holds a sun (" + o.sky.describe() + "); "
                + r.spell("sun") + " would add a second");
        }
        if (o.direct == DirectMode::Sweep) {
            r.fail(r.spell("environment") + " holds a sun, computed exactly: it needs "
                + r.spell("direct") + " exact or auto");
        }
        o.sun = *sun;
    }
}

// The glossy settings of @a r: --brdf, --control-points or --harmonics, --glossy-rotation.
GlossyOptions
glossyOptions(const Request& r)
{
    GlossyOptions g;
    g.model = brdfModelFromName(r.getString("brdf"));
    g.controlPoints = r.getInt("control-points");
    if (r.getInt("harmonics") > 0) {
        if (r.has("control-points") || r.has("glossy-rotation")) {
            r.fail(r.spell("harmonics") + " replaces the control points: drop "
                + r.spell("control-points") + " and " + r.spell("glossy-rotation"));
        }
        g.basis = GlossyBasis::Harmonics;
        g.harmonicOrder = r.getInt("harmonics");
    }
    g.rotation = r.choice<ControlPoints::RotationKind>("glossy-rotation",
        {{"resampled", ControlPoints::RotationKind::Resampled},
            {"continuous", ControlPoints::RotationKind::Continuous},
            {"permutation", ControlPoints::RotationKind::Permutation}});
    return g;
}

// What --method montecarlo does not take.
void
checkMonteCarlo(const Request& r, const RadiosityOptions& o)
{
    const std::string mc = r.spell("method") + " montecarlo";
    if (o.accelerate != Acceleration::None) r.fail(r.spell("accelerate") + " does not apply to " + mc);
    if (r.has("direct") || r.has("direct-samples")) {
        r.fail(r.spell("direct") + " and " + r.spell("direct-samples") + " do not apply to " + mc);
    }
    if (o.precision != Precision::Auto) r.fail(r.spell("precision") + " does not apply to " + mc);
    if (r.has("checkpoint") || r.has("resume")) {
        r.fail(r.spell("checkpoint") + " and " + r.spell("resume") + " do not apply to " + mc);
    }
}

// What the slab passes do not carry (RadiosityOptions::spread).
void
checkSlabs(const Request& r, const RadiosityOptions& o, const std::string& method, double cache)
{
    const std::string slabs = r.spell("distribute") + " slabs";
    if (method != "sweep") r.fail(slabs + " needs " + r.spell("method") + " sweep");
    if (o.lines != LineType::Naive) r.fail(slabs + " needs naive lines");
    if (o.accelerate != Acceleration::None) r.fail(slabs + " does not take " + r.spell("accelerate"));
    if (r.has("checkpoint") || r.has("resume")) {
        r.fail(slabs + " keeps no checkpoints (" + r.spell("checkpoint") + ", "
            + r.spell("resume") + ")");
    }
    if (r.has("visibility-cache") && cache != 0.0) {
        r.fail(slabs + " uses no " + r.spell("visibility-cache") + " (a replay reads other "
            "ranks' voxels)");
    }
}

} // namespace

const std::vector<OptionSpec>&
surfaceSolveOptions()
{
    static const std::vector<OptionSpec> table = concat(concat(concat(concat(options::scene(),
        solverOptions()), lightOptions()), options::checkpoints()), options::resources());
    return table;
}

SurfaceSolve::SurfaceSolve(const Request& r, const Distribution* ranks)
    : mRequest(r)
    , mRanks(ranks)
    , mSceneOptions(options::sceneOptions(r))
    , mMethod(r.getString("method"))
{
    RadiosityOptions& o = mOptions;
    o.ranks = ranks;
    o.directions = r.getInt("directions");
    o.maxIterations = r.getInt("iterations");
    o.tolerance = r.getFloat("tolerance");
    o.occlusionDepth = float(r.getFloat("occlusion-depth"));
    o.visibility = mMethod == "raycast" ? Visibility::RayCast : Visibility::Sweep;
    mMonteCarlo.samples = r.getInt("samples");
    mMonteCarlo.maxIterations = o.maxIterations;
    mMonteCarlo.tolerance = o.tolerance;
    mMonteCarlo.gather = r.getInt("gather");
    if (mMonteCarlo.gather > 0 && mMethod != "montecarlo") {
        r.fail(r.spell("gather") + " applies only to " + r.spell("method") + " montecarlo");
    }
    o.update = r.choice<UpdateScheme>("update", {{"jacobi", UpdateScheme::Jacobi},
        {"inplace", UpdateScheme::InPlace}, {"progressive", UpdateScheme::Progressive}});
    o.accelerate = accelerationFromString(r.getString("accelerate"));
    o.andersonDepth = r.getInt("anderson-depth");
    if (o.accelerate != Acceleration::None && o.update == UpdateScheme::Progressive) {
        r.fail(r.spell("accelerate") + " needs " + r.spell("update")
            + " jacobi or inplace, not progressive");
    }
    o.lines = r.choice<LineType>("lines", {{"naive", LineType::Naive},
        {"standard", LineType::Standard}});
    o.precision = precisionFromString(r.getString("precision"));
    o.direct = r.choice<DirectMode>("direct", {{"auto", DirectMode::Auto},
        {"exact", DirectMode::Exact}, {"sweep", DirectMode::Sweep}});
    o.directSamples = r.getInt("direct-samples");
    lightOf(r, mMethod, o);
    o.glossy = glossyOptions(r);
    if (mMethod == "montecarlo") checkMonteCarlo(r, o);
    const std::string cache = r.getString("visibility-cache");
    mCache = cache == "auto" ? -1.0 : r.bytes("visibility-cache", true);
    if (r.has("visibility-cache") && mMethod != "sweep") {
        r.fail(r.spell("visibility-cache") + " applies only to " + r.spell("method") + " sweep");
    }
    o.spread = r.getString("distribute") == "slabs" ? Spread::Slabs : Spread::Directions;
    if (o.spread == Spread::Slabs) checkSlabs(r, o, mMethod, mCache);
    SolveControl probe;
    options::setCheckpoints(r, 0, probe);
    memoryLimit(r, ranks);   // a bad --max-memory fails before any work
}

void
SurfaceSolve::read(const openvdb::GridPtrVec& grids,
    openvdb::util::NullInterrupter* interrupt)
{
    const Request& r = mRequest;
    mScene = buildScene(grids, mSceneOptions, interrupt);
    for (const auto& g : grids) mInputBytes += double(g->memUsage());
    mRead = true;
    // Unlit, the answer is 0 everywhere: refused before any time is spent on it.
    const bool sunlit = mOptions.sun && mOptions.sun->irradiance.length() > 0.0;
    const bool skylit = !mOptions.sky.empty()
        && (mOptions.sky.kind() != Sky::Kind::Uniform
            || mOptions.sky.radiance(openvdb::Vec3d(0, 0, 1)).length() > 0.0);
    if (!mScene.hasEmission() && !sunlit && !skylit) {
        OPENVDB_THROW(openvdb::ValueError, "nothing lights the scene: no voxel emits (an "
            "`emission` grid, MTL Ke) and there is no " + r.spell("sun") + ", "
            + r.spell("sky") + " or " + r.spell("environment"));
    }
    if (mScene.raisedRoughness() > 0) {
        mWarnings.push_back(std::to_string(mScene.raisedRoughness()) + " glossy voxels have a "
            "roughness below 0.1, raised to 0.1 (control points resolve no sharper lobe)");
    }
    if (mScene.isGlossy()) {
        if (mOptions.spread == Spread::Slabs) {
            OPENVDB_THROW(openvdb::ValueError, "glossy surfaces (a `specular` grid) are not "
                "solved with " + r.spell("distribute") + " slabs");
        }
        if (mMethod != "sweep") {
            OPENVDB_THROW(openvdb::ValueError, "glossy surfaces (a `specular` grid) are solved "
                "by the line sweeps only (" + r.spell("method") + " sweep)");
        }
        if (mOptions.accelerate != Acceleration::None) {
            mWarnings.push_back("glossy surfaces are not Anderson-accelerated: solving without it");
            mOptions.accelerate = Acceleration::None;
        }
        if (mOptions.update == UpdateScheme::Progressive) {
            OPENVDB_THROW(openvdb::ValueError, "glossy surfaces need " + r.spell("update")
                + " inplace or jacobi");
        }
    }
    if (findGrid(grids, names::kDensity)) {
        mWarnings.push_back("the fog ('density') is not part of this solve: "
            + options::spellCommand(r, "solve-cloud") + " solves the surfaces and the fog "
            "together");
    }
}

const SolvePlan&
SurfaceSolve::plan()
{
    if (!mRead) throw std::logic_error("SurfaceSolve::plan() before read()");
    SolvePlan& p = mPlan;
    p.heldBytes = heldBytes(mInputBytes + double(mScene.memUsage()));
    p.limitBytes = memoryLimit(mRequest, mRanks);
    p.maxIterations = mOptions.maxIterations;
    mPlanned = true;
    if (mMethod == "montecarlo") return p;
    const bool slabs = mOptions.spread == Spread::Slabs && mRanks && mRanks->distributed();
    const int threads = workerThreads();
    // Auto: half of what the limit leaves once the solve has what it needs without a cache.
    mOptions.visibilityCache = slabs ? 0 : mCache >= 0.0 ? size_t(std::min(mCache, 1e18))
        : RadiositySolver::visibilityCacheFor(mScene, mOptions, threads,
            p.limitBytes - p.heldBytes);
    p.solverBytes = double(RadiositySolver::memoryEstimate(mScene, mOptions, threads));
    p.directions = int(DirectionSet::fromCount(mOptions.directions).size());
    const int share = mRanks ? mRanks->ranks() : 1;
    p.secondsPerIteration = (mScene.isGlossy() ? kGlossySeconds : kDiffuseSeconds)
        * double(mScene.size()) * double(p.directions) / double(std::max(1, threads * share));
    p.checkMemory(mRequest.spell("max-memory"), "fewer voxels or directions, or no "
        + mRequest.spell("accelerate") + ",");
    return p;
}

SolveResult
SurfaceSolve::run(openvdb::util::NullInterrupter* interrupt, SolveControl control)
{
    if (!mPlanned) plan();
    SolveResult result;
    control = reportingInto(result, std::move(control), mRequest, mRanks);
    if (mMethod == "montecarlo") {
        result.grids = solveMonteCarlo(mScene, mMonteCarlo, interrupt, control);
    } else {
        openvdb::GridBase::Ptr specular;
        // Given up: with slabs, the ranks other than 0 free it once their slab is set up.
        openvdb::GridBase::Ptr radiosity = solveRadiosity(std::move(mScene), mOptions, interrupt,
            control, &specular);
        if (radiosity) {
            recordLight(mRequest, *radiosity);
            result.grids.push_back(radiosity);
        }
        if (specular) result.grids.push_back(specular);
    }
    result.warnings = mWarnings;
    result.plan = mPlan;
    return result;
}

SolveResult
solveSurfaces(const openvdb::GridPtrVec& grids, const Request& request,
    const Distribution* ranks, openvdb::util::NullInterrupter* interrupt, SolveControl control)
{
    SurfaceSolve solve(request, ranks);
    return runSteps(solve, grids, interrupt, std::move(control));
}

OutsideLight
solvedLight(const openvdb::GridPtrVec& grids, std::vector<std::string>& warnings)
{
    OutsideLight light;
    // A surface solve's radiosity grid, else a cloud solve's.
    openvdb::StringMetadata::ConstPtr meta;
    if (const openvdb::GridBase::ConstPtr radiosity = findGrid(grids, names::kRadiosity)) {
        meta = radiosity->getMetadata<openvdb::StringMetadata>(kLightMeta);
    }
    for (size_t i = 0; i < grids.size() && !meta; ++i) {
        meta = grids[i]->getMetadata<openvdb::StringMetadata>(kLightMeta);
    }
    if (!meta) return light;
    Request r("solve", surfaceSolveOptions());
    std::istringstream lines(meta->value());
    try {
        for (std::string line; std::getline(lines, line);) {
            const size_t eq = line.find('=');
            if (eq == std::string::npos) continue;
            r.set(line.substr(0, eq), line.substr(eq + 1));
        }
        RadiosityOptions o;
        lightOf(r, "sweep", o);
        light.sky = o.sky;
        light.sun = o.sun;
    } catch (const std::exception& e) {
        warnings.push_back(std::string("the light it was solved with is not shown: ") + e.what());
    }
    return light;
}

std::string
stoppedShort(const SolveResult& result, const Request& request)
{
    if (result.converged) return "";
    std::ostringstream os;
    os << "stopped at " << request.spell("iterations") << " " << result.plan.maxIterations
       << " with residual " << result.residual << " > " << request.spell("tolerance") << " "
       << request.getString("tolerance");
    return os.str();
}

} // namespace vdbrad
