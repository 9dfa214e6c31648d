#include "Commands.h"

#include "Progress.h"
#include "ToolSupport.h"

#include "grids/CanonicalGrids.h"
#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/surface/RadiositySolver.h"
#include "vdbrad/sweep/Acceleration.h"
#include "vdbrad/sweep/DirectionSet.h"
#include "vdbrad/vdbrad.h"

#include <algorithm>
#include <iostream>

namespace vdbrad {
namespace cli {

namespace {

// ---- option groups shared by several commands ---------------------------------------------------

const OptionSpec kQuiet{"quiet", OptionType::Flag, "", "", "no progress messages on stderr"};
// Files from other tools: what was read how (double grids as float, Cd as albedo, ...).
const OptionSpec kVerbose{"verbose", OptionType::Flag, "", "",
    "say on stderr how the input's grids were read: double or vec3d grids converted to float, "
    "half-float storage, `Cd` or `color` taken as the albedo"};
const OptionSpec kDensity{"density", OptionType::String, "density", "smoke",
    "the fog volume's grid (float or double): extinction per world unit, times "
    "--extinction-scale"};
const OptionSpec kOverwrite{"overwrite", OptionType::Flag, "", "",
    "allow the output to replace an input file"};
// Convergence acceleration, the same for solve and solve-cloud (Acceleration.h).
const OptionSpec kAccelerate = OptionSpec{"accelerate", OptionType::String, "none", "anderson",
    "anderson: Anderson mixing of the last --anderson-depth iterates (for albedos near 1 and "
    "optically thick clouds: tens of sweeps instead of thousands)"}
    .oneOf({toString(Acceleration::None), toString(Acceleration::Anderson)});
// solve-cloud chooses by default (CloudTransfer::chooseAcceleration).
const OptionSpec kCloudAccelerate = OptionSpec{"accelerate", OptionType::String, "auto", "none",
    "anderson: Anderson mixing of the last --anderson-depth iterates (tens of sweeps instead of "
    "hundreds in optically thick, conservative clouds; 2 x depth + 2 copies of the moments); "
    "auto: anderson where the thickest column's plain sweeps would decay slower than 1/2 per "
    "sweep (omega0 tau / (tau + 2) > 1/2, delta-M scaled), else none"}
    .oneOf({"auto", toString(Acceleration::None), toString(Acceleration::Anderson)});
const OptionSpec kAndersonDepth = OptionSpec{"anderson-depth", OptionType::Int, "16", "8",
    "iterates --accelerate anderson mixes; it keeps 2 x depth + 2 copies of the solution"}
    .within(1, 256);
// Iterations, checkpoints (Checkpoint.h), threads and memory, the same for solve and solve-cloud.
const OptionSpec kDirections = OptionSpec{"directions", OptionType::Int, "300", "1000",
    "direction pairs swept per iteration (the nearest count a discrete sphere gives is used)"}
    .within(1, double(DirectionSet::maxCount()));
const OptionSpec kCheckpoint{"checkpoint", OptionType::String, "", "state.ckpt",
    "save resumable state to this file every --checkpoint-every iterations (atomically; "
    "removed once the output is written)"};
const OptionSpec kCheckpointEvery = OptionSpec{"checkpoint-every", OptionType::Int, "10", "5",
    "iterations between checkpoints"}.atLeast(1);
const OptionSpec kResume{"resume", OptionType::String, "", "state.ckpt",
    "continue the solve saved in this checkpoint (same input and solver options): the result "
    "is bit-identical to an uninterrupted run"};
const OptionSpec kMaxMemory{"max-memory", OptionType::String, "3/4 of RAM", "8G",
    "refuse a solve whose estimated peak memory exceeds this (bytes, or with K, M, G, T: "
    "binary units; per process: under mpirun the default is shared by the ranks on a machine)"};
const OptionSpec kThreads = OptionSpec{"threads", OptionType::Int, "0", "2",
    "worker threads (0: all cores); the result does not depend on it"}.atLeast(0);

std::vector<OptionSpec>
sceneOptionSpecs()
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
            "grid"}.within(0.1, 1),
        kVerbose,
    };
}

template<typename T>
std::vector<T>
concat(std::vector<T> a, const std::vector<T>& b)
{
    a.insert(a.end(), b.begin(), b.end());
    return a;
}

std::string
builderList()
{
    std::string s;
    for (const auto& b : grids::builders()) s += (s.empty() ? "" : ", ") + b.name;
    return s;
}

int
runHelp(const Arguments& a)
{
    if (a.flag("markdown")) {
        std::cout << markdownReference(commands());
        return 0;
    }
    if (a.positional().empty()) {
        std::cout << overviewHelp(commands());
        return 0;
    }
    for (const auto& c : commands()) {
        if (c.name == a.positional()[0]) {
            std::cout << commandHelp(c);
            return 0;
        }
    }
    throw UsageError("no command '" + a.positional()[0] + "'");
}

} // namespace

const std::vector<CommandSpec>&
commands()
{
    static const std::vector<CommandSpec> table = {
        {"make", "NAME OUT.vdb", 2, 2,
            "build a canonical scene or cloud (" + builderList() + ")",
            {OptionSpec{"res", OptionType::Int, "64", "256", "voxels along the longest axis"}
                    .within(1, 4096),
                OptionSpec{"albedo", OptionType::Float, "scene's", "0.5",
                    "albedo (furnaces; single-scattering albedo for clouds)"}.within(0, 1),
                OptionSpec{"emission", OptionType::Float, "1", "2",
                    "emitted radiosity of the emitters"}.atLeast(0),
                OptionSpec{"radius", OptionType::Float, "0.25", "0.2",
                    "disk: emitter radius, world units"}.atLeast(0),
                OptionSpec{"height", OptionType::Float, "scene's", "0.25",
                    "disk, plates: emitter-receiver distance, world units"}.atLeast(0),
                OptionSpec{"tau", OptionType::Float, "scene's", "10",
                    "slab: vertical optical thickness; cumulus: optical diameter; step-cloud: "
                    "the thick columns' (the thin ones': tau / 9)"}.atLeast(0),
                OptionSpec{"seed", OptionType::Int, "1", "7", "cumulus: shape seed"}.atLeast(0),
                kQuiet},
            {"vdbrad make cornell cornell.vdb --res 128",
                "vdbrad make furnace-box - --albedo 0.9 | vdbrad info -",
                "vdbrad make slab slab.vdb --tau 20"},
            runMake},
        {"voxelize", "MESH OUT.vdb", 2, 2,
            "voxelize an OBJ (with MTL: Kd albedo, Ke emission; OBJ objects and groups as a "
            "`material_id` grid) or PLY mesh into a surface scene (normal, albedo, emission "
            "grids)",
            {OptionSpec{"res", OptionType::Int, "128", "256",
                    "voxels along the mesh's longest axis"}.within(1, 16384),
                OptionSpec{"voxel-size", OptionType::Float, "", "0.01",
                    "voxel edge in world units, instead of --res"}.above(0),
                OptionSpec{"separation", OptionType::Int, "26", "6",
                    "26: the surface blocks naive lines (solve's default); 6: thinner, blocks "
                    "standard lines only (solve with --lines standard)"}.oneOf({"6", "26"}),
                OptionSpec{"albedo", OptionType::Float, "0.5", "0.7",
                    "albedo of triangles without a material, in meshes that have materials"}
                    .within(0, 1),
                {"keep-sdf", OptionType::Flag, "", "",
                    "also write the mesh's level set `surface` (closed meshes only)"},
                {"no-specular", OptionType::Flag, "", "",
                    "ignore MTL Ks/Ns/Pr: every surface diffuse (no `specular`, `roughness` grids)"},
                kOverwrite, kQuiet},
            {"vdbrad voxelize room.obj room.vdb --res 256",
                "vdbrad voxelize room.obj - | vdbrad solve - - | vdbrad render - room.exr"},
            runVoxelize},
        {"info", "FILE", 1, 1,
            "describe a file's grids and what the scene contract finds in it",
            concat(sceneOptionSpecs(), {kDensity}),
            {"vdbrad info scene.vdb", "vdbrad make cornell - | vdbrad info -"},
            runInfo},
        {"surface", "IN OUT", 2, 2,
            "write the surface voxels the solver will see (normal, albedo, emission grids)",
            concat(sceneOptionSpecs(), {kOverwrite, kQuiet}),
            {"vdb_tool -read bunny.obj -mesh2ls -write bunny_ls.vdb && "
             "vdbrad surface bunny_ls.vdb bunny_surface.vdb"},
            runSurface},
        {"compare", "A B", 2, 2,
            "compare the radiosity of A with that of the reference B (same voxels): prints "
            "mean |A-B| / mean |B| and max |A-B| / max |B|",
            {},
            {"vdbrad solve box.vdb ref.vdb --method montecarlo --samples 4096 && "
             "vdbrad solve box.vdb fast.vdb --directions 300 && vdbrad compare fast.vdb ref.vdb"},
            runCompare},
        {"solve", "IN OUT", 2, 2,
            "solve the radiosity of a surface scene; writes the input's grids plus `radiosity`",
            concat(sceneOptionSpecs(), {kDirections,
                OptionSpec{"iterations", OptionType::Int, "200", "50", "iteration cap"}
                    .atLeast(1),
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
                    "rays per voxel for --method montecarlo (stored: 4 bytes each)"}
                    .within(1, 1000000),
                OptionSpec{"gather", OptionType::Int, "0", "4096",
                    "--method montecarlo: a final gather of this many fresh rays per voxel from "
                    "the solved --samples pass (not stored: a low-noise reference in the memory "
                    "of --samples; 256 samples are enough), 0 for none"}.within(0, 1000000),
                OptionSpec{"lines", OptionType::String, "naive", "standard",
                    "digital lines: naive (26-connected) or standard (6-connected)"}
                    .oneOf({"naive", "standard"}),
                OptionSpec{"occlusion-depth", OptionType::Float, "1", "1.5",
                    "voxels: a receiver this far behind the wall voxel before it is hidden"}
                    .above(0),
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
                kAccelerate, kAndersonDepth, kCheckpoint, kCheckpointEvery, kResume, kThreads,
                kMaxMemory, kOverwrite, kQuiet}),
            {"vdbrad make cornell - | vdbrad solve - cornell_lit.vdb --directions 1000",
                "vdbrad solve scene.vdb out.vdb --lines standard --tolerance 1e-4"},
            runSolve},
        {"solve-cloud", "IN OUT", 2, 2,
            "solve the light in a fog volume (`density` grid) lit by the sun and by the surfaces "
            "of a scene in the same file (a level set or `normal` grid, its `albedo` and "
            "`emission`: a foggy room lit by its lamps); writes the input's grids plus the mean "
            "radiance `mean_intensity` (and the surfaces' `radiosity`)",
            {{"sun", OptionType::String, "0,0", "60,30",
                    "sun zenith angle from the up axis, in [0, 89.9], and azimuth, degrees"},
                OptionSpec{"up", OptionType::String, "y", "z",
                    "vertical axis: y (Houdini), z (Blender) or x"}.oneOf({"x", "y", "z"}),
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
                {"phase-order", OptionType::String, "auto", "6",
                    "spherical-harmonic order kept for an anisotropic phase (delta-M beyond), "
                    "0 to 32; (order + 1)^2 floats per voxel; auto: the smallest order >= 8 "
                    "that leaves at most 17 % of the phase function to delta-M (8 for g <= "
                    "0.82, 10 for 0.85, 16 for 0.9)"},
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
                kDensity,
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
                OptionSpec{"irradiance", OptionType::Float, "1", "3",
                    "sun irradiance F0 on a plane normal to the beam"}.atLeast(0),
                OptionSpec{"ground-albedo", OptionType::Float, "", "0.4",
                    "a Lambertian ground of this albedo under the box (its footprint; with "
                    "--periodic the whole plane) reflecting light back into the cloud; writes "
                    "its irradiance as `ground_irradiance`, one layer of voxels below the box. "
                    "Default: none (light leaving downwards is gone)"}.within(0, 1),
                OptionSpec{"surface-albedo", OptionType::Float, "0.5", "0.7",
                    "albedo of the surfaces where the file has a surface but no `albedo` "
                    "grid"}.within(0, 1),
                {"no-surfaces", OptionType::Flag, "", "",
                    "ignore a surface scene in the file: solve the fog alone"},
                {"directions", OptionType::String, "auto", "1000",
                    "direction pairs swept per iteration (the nearest count a discrete sphere "
                    "gives is used); auto: for a phase function of asymmetry |g| > 0.5 (its "
                    "peak must be carried from voxel to voxel) 2000 (order / 10)^2, else 300"},
                OptionSpec{"iterations", OptionType::Int, "1000", "100", "source-iteration cap"}
                    .atLeast(1),
                OptionSpec{"tolerance", OptionType::Float, "1e-6", "1e-4",
                    "stop when max|J' - J| / max|J'| falls below this"}.atLeast(0),
                kCloudAccelerate, kAndersonDepth, kCheckpoint, kCheckpointEvery, kResume, kThreads,
                kMaxMemory,
                {"output-name", OptionType::String, "mean_intensity", "scatter",
                    "name of the output grid (e.g. `scatter` for Houdini volume shaders)"},
                kVerbose, kOverwrite, kQuiet},
            {"vdbrad make cumulus - | vdbrad solve-cloud - lit.vdb --sun 40,0",
                "vdbrad make cornell --tau 1 - | vdbrad solve-cloud - foggy.vdb --irradiance 0",
                "vdbrad solve-cloud slab.vdb out.vdb --periodic --sun 60,0 --albedo 0"},
            runSolveCloud},
        {"render", "IN OUT.exr", 2, 2,
            "render a solved scene (surface radiosity, or a cloud's scattered light) to an "
            "OpenEXR image, and optionally a PNG preview",
            concat(sceneOptionSpecs(), {
                {"res", OptionType::String, "640x480", "1920x1080",
                    "image size WIDTHxHEIGHT, each 1 to 16384"},
                {"camera", OptionType::String, "", "0.28,0.27,-0.8,0.28,0.27,0,0,1,0,40",
                    "eye x,y,z, target x,y,z, up x,y,z, vertical fov (degrees), world units; "
                    "default: looking along +z at the scene's bounding box, which it frames"},
                {"png", OptionType::String, "", "preview.png",
                    "also write an 8-bit sRGB PNG, tone mapped (the 90th-percentile luminance "
                    "of the scene's pixels maps to 0.8, then --exposure)"},
                {"exposure", OptionType::Float, "0", "1", "PNG exposure adjustment, in stops"},
                OptionSpec{"exr-type", OptionType::String, "half", "float", "EXR pixel type"}
                    .oneOf({"half", "float"}),
                OptionSpec{"aa", OptionType::Int, "1", "3",
                    "antialiasing: N x N samples per pixel"}.within(1, 16),
                {"mesh", OptionType::String, "", "room.obj",
                    "surfaces: draw the mesh the scene was voxelised from (OBJ or PLY, as given "
                    "to voxelize), shaded by the solved voxels around each point: exact "
                    "outlines instead of voxel ones"},
                OptionSpec{"gather", OptionType::Int, "0", "256",
                    "surfaces: final gather with this many rays per pixel sample from the point "
                    "the camera sees (E + albedo x (exact direct light + mean reflected radiosity "
                    "of what the rays hit): smooth where the voxels are not); 0: show the "
                    "voxels' radiosity"}.within(0, 65536),
                OptionSpec{"direct-samples", OptionType::Int, "16", "64",
                    "--gather and glossy surfaces: shadow rays per pixel sample for the direct "
                    "light"}.within(1, 65536),
                OptionSpec{"glossy-rays", OptionType::Int, "32", "128",
                    "glossy surfaces (solved with a `specular` grid): rays per pixel sample "
                    "drawn from the lobe towards the camera, plus the lamps through the lobe: "
                    "highlights; 0: the lobes' light the same from every direction"}
                    .within(0, 65536),
                {"background", OptionType::String, "0,0,0", "0.2,0.3,0.5",
                    "linear RGB seen where rays hit nothing"},
                OptionSpec{"extinction-scale", OptionType::Float, "1", "10",
                    "clouds: multiplies the density grid, as for the cloud solve"}.above(0),
                kDensity,
                {"cloud-source", OptionType::String, "mean_intensity", "scatter",
                    "clouds: the grid of mean radiance J; the source is albedo x J"},
                kOverwrite, kQuiet}),
            {"vdbrad render lit.vdb lit.exr --png lit.png",
                "vdbrad voxelize room.obj - | vdbrad solve - - | vdbrad render - room.exr "
                "--res 1280x720 --mesh room.obj"},
            runRender},
        {"help", "[COMMAND]", 0, 1, "list commands, or describe one",
            {{"markdown", OptionType::Flag, "", "", "print the command reference as Markdown"}},
            {"vdbrad help make", "vdbrad help --markdown"},
            runHelp},
    };
    return table;
}

namespace {

// An error one rank may meet alone (memory, a bug): said with its rank, and under mpirun the
// whole job stops, since the other ranks would wait for this one's sums.
void
failed(const std::string& what)
{
    const Distribution& ranks = job();
    std::cerr << "vdbrad: error: ";
    if (ranks.distributed()) std::cerr << "rank " << ranks.rank() << ": ";
    std::cerr << what << "\n";
    if (ranks.distributed()) ranks.abort(1);
}

} // namespace

namespace {

// runTool()'s job, for job(): the tool is one host, whose commands run one at a time.
const Distribution* gJob = nullptr;

} // namespace

const Distribution&
job()
{
    static const Distribution alone;
    return gJob ? *gJob : alone;
}

int
runTool(const std::vector<std::string>& args, const Distribution* ranks)
{
    gJob = ranks;
    try {
        if (args.empty() || args[0] == "--help" || args[0] == "-h") {
            std::cout << overviewHelp(commands());
            return args.empty() ? 2 : 0;
        }
        if (args[0] == "--version") {
            std::cout << "vdbrad " << VDBRAD_VERSION_STRING << " (OpenVDB "
                      << openvdb::getLibraryAbiVersionString() << ")\n";
            return 0;
        }
        const CommandSpec* command = nullptr;
        std::vector<std::string> names;
        for (const auto& c : commands()) {
            names.push_back(c.name);
            if (c.name == args[0]) command = &c;
        }
        if (!command) {
            std::string msg = "unknown command '" + args[0] + "'";
            if (auto s = suggest(args[0], names)) msg += "; did you mean '" + *s + "'?";
            msg += " (see 'vdbrad --help')";
            throw UsageError(msg);
        }
        const std::vector<std::string> rest(args.begin() + 1, args.end());
        if (std::find_if(rest.begin(), rest.end(), [](const std::string& s) {
                return s == "--help" || s == "-h"; }) != rest.end()) {
            std::cout << commandHelp(*command);
            return 0;
        }
        if (job().distributed() && command->name != "solve"
            && command->name != "solve-cloud") {
            throw UsageError("only solve and solve-cloud run under mpirun; run '"
                + command->name + "' as one process");
        }
        const Arguments parsed = parseCommand(*command, rest);
        openvdb::initialize();
        return command->run(parsed);
    } catch (const UsageError& e) {
        // Under mpirun every rank reads the same arguments and input: rank 0 says it once.
        if (job().rank() == 0) std::cerr << "vdbrad: error: " << e.what() << "\n";
        return 2;
    } catch (const UserError& e) {
        if (job().rank() == 0) std::cerr << "vdbrad: error: " << e.what() << "\n";
        return 1;
    } catch (const Cancelled&) {
        // mpirun passes a signal to every rank: rank 0 says it; and since a signal may have
        // reached one rank only, while the others wait for its sums, the job ends here.
        const Distribution& ranks = job();
        if (ranks.rank() == 0) {
            std::cerr << "vdbrad: cancelled";
            if (ProgressInterrupter::signalNumber() != 0) {
                std::cerr << " by signal " << ProgressInterrupter::signalNumber();
            }
            std::cerr << "; no output written\n";
        }
        if (ranks.distributed()) ranks.abort(130);
        return 130;
    } catch (const std::bad_alloc&) {
        failed("out of memory");
        return 1;
    } catch (const std::exception& e) {
        failed(errorMessage(e));
        return 1;
    }
}

} // namespace cli
} // namespace vdbrad
