#include "vdbrad/request/CloudRequest.h"

#include "vdbrad/request/SharedOptions.h"
#include "vdbrad/request/SurfaceRequest.h"

#include "vdbrad/core/GridContract.h"
#include "vdbrad/core/TextFormat.h"
#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/sweep/Acceleration.h"
#include "vdbrad/sweep/DirectionSet.h"

#include <openvdb/Exceptions.h>

#include <algorithm>
#include <utility>

namespace vdbrad {

namespace {

// Cost of one voxel and direction pair per iteration (the sweeps, the update, the mixing) on
// one core of the CI machine, from whole iterations on two (12-07): the WDAS cloud at 1/16
// took 6.2 s isotropic (303 directions) and 25 s at phase order 8 (967); the res-64 cumulus
// 0.38 and 1.7 s (this model: 0.32 and 1.4).
constexpr double kIsotropicSeconds = 100e-9, kPerOrderSeconds = 4e-9;

std::vector<OptionSpec>
mediumOptions()
{
    return {
        {"sun", OptionType::String, "0,0", "60,30",
            "sun zenith angle from the up axis, in [0, 89.9], and azimuth, degrees (with "
            "--sky, --sky-model or --environment: no sun unless given, or the map's)"},
        options::up(),
        {"periodic", OptionType::Flag, "", "",
            "wrap light around the two horizontal axes (a tile of an infinite field)"},
        {"min-period", OptionType::String, "auto", "0",
            "--periodic: solve a box narrower than this many voxels (0 to 4096) as "
            "copies side by side (light wrapping a narrow box rises by whole layers: "
            "thin slabs over-absorb); auto: sqrt(directions) / 2, fewer where the box "
            "is optically thick; 0: never. A box one voxel deep along a horizontal "
            "axis is a 2D medium, swept in the plane of the other two, never copied"},
        OptionSpec{"albedo", OptionType::Float, "1", "0.99",
            "single-scattering albedo where the file has no `albedo` grid"}.within(0, 1),
        OptionSpec{"g", OptionType::Float, "0", "0.85",
            "Henyey-Greenstein asymmetry; 0: isotropic"}.above(-1).below(1),
        {"legendre", OptionType::String, "", "1,0.8,0.6",
            "phase function as Legendre coefficients chi_0 = 1, chi_1, ... (e.g. Mie), "
            "instead of --g"},
        {"legendre-file", OptionType::String, "", "c1.txt",
            "phase function as Legendre coefficients chi_0 = 1, chi_1, ... read from a text "
            "file (white space or commas, # comments; e.g. a Mie code's output, "
            "samples/phase/cloud_c1.txt), instead of --g"},
        {"phase-order", OptionType::String, "auto", "6",
            "spherical-harmonic order kept for an anisotropic phase (delta-M beyond), "
            "0 to 32; (order + 1)^2 floats per voxel; auto: 8 (the beam's first "
            "scattering keeps the whole phase function; slabs g 0.85-0.9 within 0.25 % "
            "of adding-doubling)"},
        {"source-order", OptionType::String, "auto", "4",
            "harmonic order of the scattered light's angular moments written for `render` "
            "(grids NAME_sh0, NAME_sh1, ...: (order + 1)^2 of them, at most the phase "
            "order), 0 to 16: the picture shows the light the solve found in the camera's "
            "direction, and the sun's first scattering with the whole phase function; auto: "
            "the phase order (WDAS at g 0.877: order 4 is 1.4-3.8 % off the picture of 8, "
            "in a third of the file)"},
        OptionSpec{"voxel-source", OptionType::String, "linear", "constant",
            "the scattered light's shape inside a voxel along each line step: linear "
            "(its slope from the voxels before and after: right in voxels of optical "
            "depth ~1 and more) or constant (the thesis' scheme: thin voxels only)"}
            .oneOf({"linear", "constant"}),
        OptionSpec{"weights", OptionType::String, "harmonic", "cells",
            "direction weights for an anisotropic phase: harmonic (refitted to integrate "
            "spherical harmonics exactly to twice the phase order: the error then falls "
            "with --directions and --phase-order) or cells (each direction's solid "
            "angle)"}.oneOf({"harmonic", "cells"}),
        options::density(),
        OptionSpec{"extinction-scale", OptionType::Float, "1", "10",
            "extinction per world unit = density x this"}.above(0),
        {"emission", OptionType::String, "flame", "heat",
            "the fire's grid (float or double): the medium emits this x --emission-scale "
            "x --emission-color, radiance per world unit of path, the same in every "
            "direction (where the density is not 0); default `flame` where the file has "
            "one"},
        OptionSpec{"emission-scale", OptionType::Float, "1", "20",
            "multiplies the emission grid"}.atLeast(0),
        {"emission-color", OptionType::String, "1,1,1", "1,0.45,0.1",
            "linear RGB colour of the emission (not grey: an RGB solve)"},
        {"irradiance", OptionType::String, "1", "3",
            "sun irradiance F0 on a plane normal to the beam (grey, or linear r,g,b: an RGB "
            "solve)"},
        OptionSpec{"ground-albedo", OptionType::Float, "", "0.4",
            "a Lambertian ground of this albedo under the box (its footprint; with "
            "--periodic the whole plane) reflecting light back into the cloud; writes "
            "its irradiance as `ground_irradiance`, one layer of voxels below the box. "
            "Default: none (light leaving downwards is gone). --sky-model clear: also the "
            "clear sky's ground below the horizon (default 0.2 there)"}.within(0, 1),
        OptionSpec{"surface-albedo", OptionType::Float, "0.5", "0.7",
            "albedo of the surfaces where the file has a surface but no `albedo` "
            "grid"}.within(0, 1),
        {"no-surfaces", OptionType::Flag, "", "",
            "ignore a surface scene in the file: solve the fog alone"},
    };
}

std::vector<OptionSpec>
iterationOptions()
{
    return {
        {"directions", OptionType::String, "auto", "1000",
            "direction pairs swept per iteration (the nearest count a discrete sphere "
            "gives is used); auto: for a phase function of asymmetry |g| > 0.5 (its "
            "peak must be carried from voxel to voxel) 1000, else 300"},
        OptionSpec{"iterations", OptionType::Int, "1000", "100", "source-iteration cap"}
            .atLeast(1),
        OptionSpec{"tolerance", OptionType::Float, "1e-6", "1e-4",
            "stop when max|J' - J| / max|J'| falls below this"}.atLeast(0),
        // Chosen by default (CloudTransfer::chooseAcceleration).
        OptionSpec{"accelerate", OptionType::String, "auto", "none",
            "anderson: Anderson mixing of the last --anderson-depth iterates (tens of sweeps "
            "instead of hundreds in optically thick, conservative clouds; 2 x depth + 2 copies "
            "of the moments of order <= 1); auto: anderson where the thickest column's plain "
            "sweeps would decay slower than 1/2 per sweep (omega0 tau / (tau + 2) > 1/2, "
            "delta-M scaled), else none"}
            .oneOf({"auto", toString(Acceleration::None), toString(Acceleration::Anderson)}),
        options::andersonDepth(),
        OptionSpec{"diffusion", OptionType::String, "on", "off",
            "diffusion synthetic acceleration: after each sweep a diffusion solve over the "
            "medium's voxels corrects the mean radiance's smooth error modes, the slow ones in "
            "clouds many optical depths across (a slab of optical depth 100: 8 iterations "
            "instead of 161; not for phase functions of asymmetry below -0.7); off: source "
            "iteration (and Anderson) alone"}
            .oneOf({"on", "off"}),
    };
}

// --source-order: auto, all the moments the solve has (ScatteredSource::kMaxOrder at most).
int
sourceOrder(const Request& r)
{
    return r.autoOr("source-order", 0, ScatteredSource::kMaxOrder, "an order")
        .value_or(ScatteredSource::kMaxOrder);
}

// The phase function: --g or --legendre.
PhaseFunction
phaseFunction(const Request& r)
{
    const int given = int(r.has("g")) + int(r.has("legendre")) + int(r.has("legendre-file"));
    if (given > 1) {
        r.fail("give one of " + r.spell("g") + ", " + r.spell("legendre") + " and "
            + r.spell("legendre-file"));
    }
    if (r.has("legendre-file")) {
        try {
            return PhaseFunction::readLegendre(r.getString("legendre-file"));
        } catch (const openvdb::ValueError& e) {
            r.fail(r.spell("legendre-file") + ": " + errorMessage(e));
        } catch (const openvdb::IoError& e) {
            // An unreadable file stays an I/O error (exit 1), named after the option.
            OPENVDB_THROW(openvdb::IoError, r.spell("legendre-file") + ": " + errorMessage(e));
        }
    }
    if (!r.has("legendre")) return PhaseFunction::henyeyGreenstein(r.getFloat("g"));
    const std::vector<double> chi = r.numbers("legendre", 0, "chi_0 = 1, chi_1, ...");
    try {
        return PhaseFunction::legendre(chi);
    } catch (const std::exception& e) {
        r.fail(r.spell("legendre") + ": " + errorMessage(e));
    }
}

// The beam's irradiance F0 and colour from an RGB irradiance.
void
setSunIrradiance(const openvdb::Vec3d& F, CloudTransferOptions& o)
{
    o.irradiance = std::max({F[0], F[1], F[2]});
    o.sunColour = o.irradiance > 0.0 ? F / o.irradiance : openvdb::Vec3d(1.0);
}

// The sun (always there unless a sky is given without --sun) and the sky: --sky,
// --sky-model clear, --environment (a sun in the map is the sun).
void
setLight(const Request& r, CloudTransferOptions& o)
{
    const bool skyGiven = r.has("sky") || r.getString("sky-model") == "clear"
        || r.has("environment");
    const openvdb::Vec3d F = r.colour("irradiance");
    std::optional<Sun> sun;
    if (!skyGiven || r.has("sun")) {
        sun = Sun{o.sunZenith, o.sunAzimuth, o.up, F, 0.53};
        setSunIrradiance(F, o);
    } else {
        if (r.has("irradiance")) {
            r.fail(r.spell("irradiance") + " with a sky needs " + r.spell("sun"));
        }
        o.irradiance = 0.0;
    }
    o.sky = options::skyOf(r, sun, o.groundAlbedo.value_or(0.2), o.up);
    if (const auto& mapSun = o.sky.sun()) {
        if (r.has("sun") || r.has("irradiance")) {
            r.fail(r.spell("environment") + " holds a sun (" + o.sky.describe() + "); "
                + r.spell("sun") + " and " + r.spell("irradiance") + " would add a second");
        }
        if (!(mapSun->zenith <= 89.9)) {
            r.fail(r.spell("environment") + ": its sun is " + std::to_string(mapSun->zenith)
                + " degrees from the zenith; a cloud's sun must be within 89.9 (turn the map "
                "with " + r.spell("up") + ")");
        }
        o.sunZenith = mapSun->zenith;
        o.sunAzimuth = mapSun->azimuth;
        setSunIrradiance(mapSun->irradiance, o);
    }
}

} // namespace

const std::vector<OptionSpec>&
cloudSolveOptions()
{
    static const std::vector<OptionSpec> table = concat(concat(concat(concat(concat(
        mediumOptions(), options::sky()), iterationOptions()), options::checkpoints()),
        options::resources()),
        {{"output-name", OptionType::String, "mean_intensity", "scatter",
            "name of the output grid (e.g. `scatter` for Houdini volume shaders)"}});
    return table;
}

CloudSolve::CloudSolve(const Request& r, const Distribution* ranks)
    : mRequest(r)
    , mRanks(ranks)
{
    CloudOptions& c = mCloudOptions;
    c.extinctionScale = float(r.getFloat("extinction-scale"));
    c.defaultAlbedo = float(r.getFloat("albedo"));
    c.density = r.getString("density");
    if (r.has("emission")) c.emission = r.getString("emission");
    c.emissionScale = float(r.getFloat("emission-scale"));
    const std::vector<double> colour = r.numbers("emission-color", 3, "r,g,b");
    c.emissionColour = openvdb::Vec3f(float(colour[0]), float(colour[1]), float(colour[2]));

    CloudTransferOptions& o = mOptions;
    o.ranks = ranks;
    const std::vector<double> sun = r.numbers("sun", 2, "zenith,azimuth in degrees");
    o.sunZenith = sun[0];
    o.sunAzimuth = sun[1];
    if (!(o.sunZenith >= 0.0 && o.sunZenith <= 89.9)) {
        r.fail(r.spell("sun") + ": the zenith angle must be in [0, 89.9] degrees");
    }
    o.up = r.choice<int>("up", {{"x", 0}, {"y", 1}, {"z", 2}});
    if (r.has("ground-albedo")) o.groundAlbedo = r.getFloat("ground-albedo");
    o.periodic = r.flag("periodic");
    if (const auto v = r.autoOr("min-period", 0, 4096, "a voxel count")) o.minPeriod = *v;
    if (r.has("min-period") && !o.periodic) {
        r.fail(r.spell("min-period") + " applies to " + r.spell("periodic") + " boxes only");
    }
    if (const auto v = r.autoOr("directions", 1, long(DirectionSet::maxCount()), "a count")) {
        o.directions = *v;
    }
    o.maxIterations = r.getInt("iterations");
    o.tolerance = r.getFloat("tolerance");
    setLight(r, o);
    if (r.getString("output-name").empty()) r.fail(r.spell("output-name") + " must not be empty");
    o.phase = phaseFunction(r);
    if (const auto v = r.autoOr("phase-order", 0, 32, "an order")) o.phaseOrder = *v;
    if (r.getString("accelerate") != "auto") {
        o.accelerate = accelerationFromString(r.getString("accelerate"));
    }
    o.source = r.choice<VoxelSource>("voxel-source",
        {{"constant", VoxelSource::Constant}, {"linear", VoxelSource::Linear}});
    o.harmonicWeights = r.getString("weights") == "harmonic";
    o.andersonDepth = r.getInt("anderson-depth");
    o.diffusion = r.getString("diffusion") == "on";
    SolveControl probe;
    options::setCheckpoints(r, 0, probe);
    memoryLimit(r, ranks);   // a bad --max-memory fails before any work
}

void
CloudSolve::read(const openvdb::GridPtrVec& grids, openvdb::util::NullInterrupter* interrupt)
{
    const Request& r = mRequest;
    for (const auto& g : grids) mInputBytes += double(g->memUsage());
    // A surface scene among the grids (a level set or `normal` grid) is solved with the fog
    // (unless --no-surfaces); its `albedo` grid is the surfaces', not the fog's.
    const bool hasSurface = bool(identifyRoles(grids, "", mCloudOptions.density).surface);
    mCloudOptions.albedoGrid = !hasSurface;
    if (hasSurface && !r.flag("no-surfaces")) {
        SceneOptions sceneOpts;
        sceneOpts.defaultAlbedo = float(r.getFloat("surface-albedo"));
        mScene = buildScene(grids, sceneOpts, interrupt);
        mOptions.surfaces = &mScene;
        if (mOptions.periodic || mOptions.groundAlbedo) {
            r.fail("grids with surfaces are solved in an open box without "
                + r.spell("ground-albedo") + " (give the ground as surface voxels; or "
                + r.spell("no-surfaces") + ")");
        }
    }
    mCloud = buildCloud(grids, mCloudOptions, interrupt);
    mRead = true;
    // Unlit, the answer is 0 everywhere: refused before any time is spent on it.
    if (!(mOptions.irradiance > 0.0) && !(mOptions.sky.horizontalIrradiance().length() > 0.0)
        && mCloud.emission().isZero() && !mScene.hasEmission()) {
        OPENVDB_THROW(openvdb::ValueError, "nothing lights the cloud: no sun ("
            + r.spell("irradiance") + " is 0), no " + r.spell("sky") + " or " + r.spell("environment") + ", the medium "
            "does not emit (no fire where the density is) and no surface emits");
    }
    if (mCloud.lostEmitters() > 0) {
        mWarnings.push_back(withCommas(mCloud.lostEmitters()) + " voxels of '"
            + mCloud.emissionName() + "' emit where '" + mCloud.densityName() + "' is 0 or "
            "inactive: the medium emits through its extinction, so they add no light");
    }
}

const SolvePlan&
CloudSolve::plan()
{
    if (!mRead) throw std::logic_error("CloudSolve::plan() before read()");
    SolvePlan& p = mPlan;
    const int threads = workerThreads();
    p.heldBytes = heldBytes(mInputBytes + double(mCloud.memUsage() + mScene.memUsage()));
    p.limitBytes = memoryLimit(mRequest, mRanks);
    // What the transfer solves: a periodic box uniform along an axis, one voxel deep.
    mSlice = uniformSlice(mCloud, mOptions);
    const Cloud& solved = mSlice ? *mSlice : mCloud;
    const int order = CloudTransfer::phaseOrderFor(mOptions);
    p.solverBytes = double(CloudTransfer::memoryEstimate(solved, mOptions, threads));
    // The scattered source's moments after the solve (CloudTransfer::scatteredSource(): all
    // M coefficients, then W of them in double, float and grids).
    const double M = double((order + 1) * (order + 1));
    const int written = std::min(order, sourceOrder(mRequest));
    const double W = double((written + 1) * (written + 1));
    p.solverBytes += double(solved.size()) * (4.0 * M + 24.0) + double(mCloud.size()) * 17.0 * W;
    p.maxIterations = mOptions.maxIterations;
    p.directions = int(DirectionSet::fromCount(CloudTransfer::directionCount(mOptions)).size());
    const int share = mRanks ? mRanks->ranks() : 1;
    p.secondsPerIteration = (kIsotropicSeconds + kPerOrderSeconds * order)
        * double(solved.size() + mScene.size()) * double(p.directions)
        / double(std::max(1, threads * share));
    mPlanned = true;
    p.checkMemory(mRequest.spell("max-memory"), "fewer voxels or directions, or no "
        + mRequest.spell("accelerate") + ",");
    return p;
}

SolveResult
CloudSolve::run(openvdb::util::NullInterrupter* interrupt, SolveControl control)
{
    if (!mPlanned) plan();
    SolveResult result;
    control = reportingInto(result, std::move(control), mRequest, mRanks);
    openvdb::FloatGrid::Ptr ground;
    openvdb::GridBase::Ptr radiosity;
    openvdb::GridPtrVec sources;
    const openvdb::GridBase::Ptr intensity = solveCloud(mCloud, mSlice.get(), mOptions,
        interrupt, control, &ground, &radiosity, &sources, sourceOrder(mRequest));
    intensity->setName(mRequest.getString("output-name"));
    for (size_t k = 0; k < sources.size(); ++k) {
        sources[k]->setName(ScatteredSource::gridName(intensity->getName(), int(k)));
    }
    recordEmission(*intensity, mCloud, mCloudOptions);
    recordLight(mRequest, *intensity);
    result.grids.push_back(intensity);
    if (ground) result.grids.push_back(ground);
    if (radiosity) result.grids.push_back(radiosity);
    result.grids.insert(result.grids.end(), sources.begin(), sources.end());
    result.warnings = mWarnings;
    result.plan = mPlan;
    return result;
}

SolveResult
solveClouds(const openvdb::GridPtrVec& grids, const Request& request, const Distribution* ranks,
    openvdb::util::NullInterrupter* interrupt, SolveControl control)
{
    CloudSolve solve(request, ranks);
    return runSteps(solve, grids, interrupt, std::move(control));
}

} // namespace vdbrad
