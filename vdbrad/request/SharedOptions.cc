#include "vdbrad/request/SharedOptions.h"

#include "vdbrad/core/Constants.h"
#include "vdbrad/sweep/Acceleration.h"
#include "vdbrad/sweep/DirectionSet.h"

namespace vdbrad {
namespace options {

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
