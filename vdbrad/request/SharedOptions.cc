#include "vdbrad/request/SharedOptions.h"

#include "vdbrad/core/Constants.h"
#include "vdbrad/core/Errors.h"
#include "vdbrad/render/ImageIO.h"
#include "vdbrad/sweep/Acceleration.h"
#include "vdbrad/sweep/DirectionSet.h"

#include <openvdb/Exceptions.h>

#include <fstream>
#include <iterator>

namespace vdbrad {
namespace options {

namespace {

// The latitude-longitude map of --environment, from its file.
Sky
environmentOf(const Request& r, int up)
{
    const std::string path = r.getString("environment");
    std::ifstream in(path, std::ios::binary);
    if (!in) r.fail(r.spell("environment") + ": cannot open '" + path + "'");
    const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
    Image map;
    try {
        map = decodeExr(bytes);
    } catch (const openvdb::Exception& e) {
        r.fail(r.spell("environment") + ": '" + path + "' is not a readable OpenEXR image ("
            + errorMessage(e) + ")");
    }
    if (map.width != 2 * map.height) {
        r.fail(r.spell("environment") + ": '" + path + "' is " + std::to_string(map.width) + " x "
            + std::to_string(map.height) + " pixels; a latitude-longitude map is twice as wide "
            "as it is high");
    }
    try {
        return Sky::fromMap(map.width, map.height, map.pixels, up,
            r.getFloat("environment-rotation"));
    } catch (const openvdb::ValueError& e) {
        r.fail(r.spell("environment") + ": '" + path + "': " + errorMessage(e));
    }
}

} // namespace

std::vector<OptionSpec>
scene()
{
    return {
        {"surface", OptionType::String, "", "surface",
            "grid to use as the surface (a level set or a vec3s normal grid); default: `normal`, "
            "else the only level set"},
        OptionSpec{"albedo", OptionType::Float, "0.5", "0.7",
            "diffuse albedo of every voxel when the file has no `albedo` grid"}.within(0, 1),
        OptionSpec{"separation", OptionType::Int, "26", "6",
            "level sets: 26 (surface blocks 26-connected lines) or 6 (thinner, blocks "
            "6-connected lines)"}.oneOf({"6", "26"}),
        OptionSpec{"roughness", OptionType::Float, "0.5", "0.3",
            "roughness of glossy voxels when the file has a `specular` grid and no `roughness` "
            "grid"}.within(double(kMinRoughness), 1),
    };
}

SceneOptions
sceneOptions(const Request& request)
{
    SceneOptions o;
    o.surface = request.getString("surface");
    o.defaultAlbedo = float(request.getFloat("albedo"));
    o.separation = request.getInt("separation");
    o.defaultRoughness = float(request.getFloat("roughness"));
    return o;
}

OptionSpec
density()
{
    return {"density", OptionType::String, "density", "smoke",
        "the fog volume's grid (float or double): extinction per world unit, times "
        "--extinction-scale"};
}

OptionSpec
directions()
{
    return OptionSpec{"directions", OptionType::Int, "300", "1000",
        "direction pairs swept per iteration (the nearest count a discrete sphere gives is used)"}
        .within(1, double(DirectionSet::maxCount()));
}

OptionSpec
accelerate()
{
    return OptionSpec{"accelerate", OptionType::String, "none", "anderson",
        "anderson: Anderson mixing of the last --anderson-depth iterates (for albedos near 1 and "
        "optically thick clouds: tens of sweeps instead of thousands)"}
        .oneOf({toString(Acceleration::None), toString(Acceleration::Anderson)});
}

OptionSpec
andersonDepth()
{
    return OptionSpec{"anderson-depth", OptionType::Int, "16", "8",
        "iterates --accelerate anderson mixes; it keeps 2 x depth + 2 copies of the solution"}
        .within(1, 256);
}

std::vector<OptionSpec>
checkpoints()
{
    return {
        {"checkpoint", OptionType::String, "", "state.ckpt",
            "save resumable state to this file every --checkpoint-every iterations (atomically; "
            "removed once the output is written)"},
        OptionSpec{"checkpoint-every", OptionType::Int, "10", "5",
            "iterations between checkpoints"}.atLeast(1),
        {"resume", OptionType::String, "", "state.ckpt",
            "continue the solve saved in this checkpoint (same input and solver options): the "
            "result is bit-identical to an uninterrupted run"},
    };
}

OptionSpec
up()
{
    return OptionSpec{"up", OptionType::String, "y", "z",
        "vertical axis: y (Houdini), z (Blender) or x"}.oneOf({"x", "y", "z"});
}

std::vector<OptionSpec>
sky()
{
    return {
        {"sky", OptionType::String, "", "0.3",
            "a uniform sky of this radiance (grey, or linear r,g,b): what a voxel facing the "
            "outside receives from each direction in which it sees no voxel, what enters a "
            "cloud's box from each direction"},
        OptionSpec{"sky-model", OptionType::String, "uniform", "clear",
            "uniform: --sky's radiance; clear: Preetham's clear sky for the --sun's position "
            "(the paper's luminance in kcd/m^2 as radiance, so a clear day's sun is about "
            "--irradiance 100; Blender's 'Preetham' Sky Texture is 0.06 of it) over a uniform "
            "ground"}
            .oneOf({"uniform", "clear"}),
        OptionSpec{"turbidity", OptionType::Float, "3", "2",
            "--sky-model clear: the haze (2 very clear, 3 clear, 6 hazy)"}.within(1, 10),
        {"environment", OptionType::String, "", "sky.exr",
            "a latitude-longitude HDR map (OpenEXR, linear RGB) lighting the scene from outside: "
            "each direction takes the map's mean over its own cell; a sun in it (a small region "
            "100x brighter than the median) is split off and computed exactly as --sun is"},
        {"environment-rotation", OptionType::Float, "0", "90",
            "--environment: turns the map about the --up axis, degrees (0: the map's centre "
            "column looks along the first horizontal axis, as Blender's Environment Texture)"},
    };
}

Sky
skyOf(const Request& r, const std::optional<Sun>& sun, double groundAlbedo, int up)
{
    const bool clear = r.getString("sky-model") == "clear";
    if (r.has("turbidity") && !clear) {
        r.fail(r.spell("turbidity") + " needs " + r.spell("sky-model") + " clear");
    }
    if (r.has("environment-rotation") && !r.has("environment")) {
        r.fail(r.spell("environment-rotation") + " needs " + r.spell("environment"));
    }
    const int given = int(r.has("sky")) + int(clear) + int(r.has("environment"));
    if (given > 1) {
        r.fail("one sky at a time: " + r.spell("sky") + ", " + r.spell("sky-model")
            + " clear or " + r.spell("environment"));
    }
    if (r.has("sky")) return Sky::uniform(r.colour("sky"));
    if (clear) {
        if (!sun) {
            r.fail(r.spell("sky-model") + " clear needs " + r.spell("sun") + " (its position)");
        }
        return Sky::clear(sun->zenith, sun->azimuth, sun->up, r.getFloat("turbidity"),
            groundAlbedo, sun->irradiance);
    }
    if (r.has("environment")) return environmentOf(r, up);
    return Sky();
}

std::vector<OptionSpec>
resources()
{
    return {
        OptionSpec{"threads", OptionType::Int, "0", "2",
            "worker threads (0: all cores); the result does not depend on it"}.atLeast(0),
        OptionSpec{"max-memory", OptionType::String, "3/4 of RAM", "8G",
            "refuse a solve whose estimated peak memory exceeds this (bytes, or with K, M, G, T: "
            "binary units; per process: under mpirun the default is shared by the ranks on a "
            "machine)"}.described(),
    };
}

void
setCheckpoints(const Request& request, int rank, SolveControl& control)
{
    const std::string save = request.getString("checkpoint");
    const std::string resume = request.getString("resume");
    if (request.has("checkpoint") && save.empty()) {
        request.fail(request.spell("checkpoint") + " needs a file");
    }
    if (request.has("resume") && resume.empty()) {
        request.fail(request.spell("resume") + " needs a file");
    }
    if (request.has("checkpoint-every") && save.empty()) {
        request.fail(request.spell("checkpoint-every") + " needs "
            + request.spell("checkpoint") + " FILE");
    }
    // Under mpirun rank 0 alone saves; every rank resumes.
    if (rank == 0) control.checkpoint = save;
    control.checkpointEvery = request.getInt("checkpoint-every");
    control.resume = resume;
}

std::string
spellCommand(const Request& request, const std::string& command)
{
    if (request.spelling() == Spelling::CommandLine) return "`vdbrad " + command + "`";
    std::string s = command;
    for (char& c : s) {
        if (c == '-') c = '_';
    }
    return "vdbrad." + s + "()";
}

} // namespace options
} // namespace vdbrad
