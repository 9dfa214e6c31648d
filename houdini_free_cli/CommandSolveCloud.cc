// `vdbrad solve-cloud`: the light in a fog volume lit by the sun (CloudTransfer), with the
// surfaces of a scene in the same file (FogSurfaces.h).
#include "Commands.h"
#include "Progress.h"
#include "SolveSupport.h"
#include "ToolSupport.h"

#include "vdbrad/cloud/CloudTransfer.h"
#include "vdbrad/core/GridContract.h"
#include "vdbrad/scene/Scene.h"
#include "vdbrad/sweep/DirectionSet.h"
#include "vdbrad/vdbrad.h"

#include <cstdlib>
#include <iostream>
#include <optional>
#include <string>

namespace vdbrad {
namespace cli {

namespace {

// Option @a name: "auto" (nullopt) or an integer in [lo, hi] (@a what it counts).
std::optional<int>
autoOrCount(const Arguments& a, const char* name, long lo, long hi, const char* what)
{
    const std::string text = a.getString(name);
    if (text == "auto") return std::nullopt;
    char* end = nullptr;
    const long v = std::strtol(text.c_str(), &end, 10);
    if (text.empty() || *end != '\0' || v < lo || v > hi) {
        throw UsageError("--" + std::string(name) + " must be auto or " + what + " in ["
            + std::to_string(lo) + ", " + std::to_string(hi) + "], got '" + text + "'");
    }
    return int(v);
}

} // namespace

int
runSolveCloud(const Arguments& a)
{
    const std::string in = a.positional()[0], out = a.positional()[1];
    CloudOptions cloudOpts;
    cloudOpts.extinctionScale = float(a.getFloat("extinction-scale"));
    cloudOpts.defaultAlbedo = float(a.getFloat("albedo"));
    cloudOpts.density = a.getString("density");
    if (a.has("emission")) cloudOpts.emission = a.getString("emission");
    cloudOpts.emissionScale = float(a.getFloat("emission-scale"));
    {
        const std::vector<double> c = numberList(a, "emission-color", 3, "r,g,b");
        cloudOpts.emissionColour = openvdb::Vec3f(float(c[0]), float(c[1]), float(c[2]));
    }
    CloudTransferOptions o;
    o.ranks = &job();
    const std::vector<double> sun = numberList(a, "sun", 2, "zenith,azimuth in degrees");
    o.sunZenith = sun[0];
    o.sunAzimuth = sun[1];
    if (!(o.sunZenith >= 0.0 && o.sunZenith <= 89.9)) {
        throw UsageError("--sun: the zenith angle must be in [0, 89.9] degrees");
    }
    o.up = choice<int>(a, "up", {{"x", 0}, {"y", 1}, {"z", 2}});
    o.periodic = a.flag("periodic");
    if (const auto v = autoOrCount(a, "min-period", 0, 4096, "a voxel count")) o.minPeriod = *v;
    if (a.has("min-period") && !o.periodic) {
        throw UsageError("--min-period applies to --periodic boxes only");
    }
    if (const auto v = autoOrCount(a, "directions", 1, long(DirectionSet::maxCount()), "a count")) {
        o.directions = *v;
    }
    o.maxIterations = a.getInt("iterations");
    o.tolerance = a.getFloat("tolerance");
    o.irradiance = a.getFloat("irradiance");
    const std::string name = a.getString("output-name");
    if (name.empty()) throw UsageError("--output-name must not be empty");
    if (a.has("legendre")) {
        if (a.has("g")) throw UsageError("give --g or --legendre, not both");
        const std::vector<double> chi = numberList(a, "legendre", 0, "chi_0 = 1, chi_1, ...");
        try {
            o.phase = PhaseFunction::legendre(chi);
        } catch (const std::exception& e) {
            throw UsageError("--legendre: " + errorMessage(e));
        }
    } else {
        o.phase = PhaseFunction::henyeyGreenstein(a.getFloat("g"));
    }
    if (const auto v = autoOrCount(a, "phase-order", 0, 32, "an order")) o.phaseOrder = *v;
    if (a.getString("accelerate") != "auto") {
        o.accelerate = accelerationFromString(a.getString("accelerate"));
    }
    o.source = choice<VoxelSource>(a, "voxel-source",
        {{"constant", VoxelSource::Constant}, {"linear", VoxelSource::Linear}});
    o.harmonicWeights = a.getString("weights") == "harmonic";
    o.andersonDepth = a.getInt("anderson-depth");
    if (a.has("ground-albedo")) o.groundAlbedo = a.getFloat("ground-albedo");
    SolveSession session(a, in, out);
    const VdbFile& file = session.file();
    const std::string& label = session.label();
    describeReading(a, label, file, "", cloudOpts.density);
    ProgressInterrupter& progress = session.progress();
    // A surface scene in the same file (a level set or `normal` grid) is solved with the fog
    // (unless --no-surfaces); its `albedo` grid is the surfaces', not the fog's.
    const bool hasSurface = forFile(label, [&] {
        return bool(identifyRoles(file.grids, "", cloudOpts.density).surface);
    });
    const bool withSurfaces = hasSurface && !a.flag("no-surfaces");
    cloudOpts.albedoGrid = !hasSurface;
    Scene scene;
    if (withSurfaces) {
        SceneOptions sceneOpts;
        sceneOpts.defaultAlbedo = float(a.getFloat("surface-albedo"));
        scene = forFile(label, [&] { return buildScene(file.grids, sceneOpts, &progress); });
        o.surfaces = &scene;
        if (o.periodic || o.groundAlbedo) {
            throw UsageError("a file with surfaces is solved in an open box without "
                "--ground-albedo (give the ground as surface voxels; or --no-surfaces)");
        }
    }
    const Cloud cloud = forFile(label, [&] {
        return buildCloud(file.grids, cloudOpts, &progress);
    });
    if (cloud.lostEmitters() > 0) {
        warn(label, withCommas(cloud.lostEmitters()) + " voxels of '" + cloud.emissionName()
            + "' emit where '" + cloud.densityName() + "' is 0 or inactive: the medium emits "
            "through its extinction, so they add no light");
    }
    const std::string memory = checkMemory(a, label,
        heldBytes(double(fileBytes(file) + cloud.memUsage() + scene.memUsage())),
        double(CloudTransfer::memoryEstimate(cloud, o, workerThreads())));
    openvdb::FloatGrid::Ptr ground;
    openvdb::GridBase::Ptr radiosity;
    const openvdb::GridBase::Ptr intensity = forFile(label, [&] {
        return solveCloud(cloud, o, &progress, session.control(memory), &ground, &radiosity);
    });
    intensity->setName(name);
    recordEmission(*intensity, cloud, cloudOpts);
    openvdb::GridPtrVec outputs{intensity};
    if (ground) outputs.push_back(ground);
    if (radiosity) outputs.push_back(radiosity);
    session.finish(outputs, out, o.maxIterations);
    return 0;
}

} // namespace cli
} // namespace vdbrad
