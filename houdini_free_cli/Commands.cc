#include "Commands.h"

#include "Progress.h"
#include "ToolSupport.h"

#include "grids/CanonicalGrids.h"
#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/request/SharedOptions.h"
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
const OptionSpec kOverwrite{"overwrite", OptionType::Flag, "", "",
    "allow the output to replace an input file"};

// The options of a command the library serves, then the tool's own: what it says on stderr and
// whether it may replace a file.
std::vector<OptionSpec>
withToolOptions(const std::vector<OptionSpec>& library, std::vector<OptionSpec> tool)
{
    return concat(library, tool);
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
            withToolOptions(voxelizeMeshOptions(), {kOverwrite, kQuiet}),
            {"vdbrad voxelize room.obj room.vdb --res 256",
                "vdbrad voxelize room.obj - | vdbrad solve - - | vdbrad render - room.exr"},
            runVoxelize},
        {"info", "FILE", 1, 1,
            "describe a file's grids and what the scene contract finds in it",
            withToolOptions(options::scene(), {kVerbose, options::density()}),
            {"vdbrad info scene.vdb", "vdbrad make cornell - | vdbrad info -"},
            runInfo},
        {"surface", "IN OUT", 2, 2,
            "write the surface voxels the solver will see (normal, albedo, emission grids)",
            withToolOptions(options::scene(), {kVerbose, kOverwrite, kQuiet}),
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
            withToolOptions(surfaceSolveOptions(), {kVerbose, kOverwrite, kQuiet}),
            {"vdbrad make cornell - | vdbrad solve - cornell_lit.vdb --directions 1000",
                "vdbrad solve scene.vdb out.vdb --lines standard --tolerance 1e-4"},
            runSolve},
        {"solve-cloud", "IN OUT", 2, 2,
            "solve the light in a fog volume (`density` grid) lit by the sun, the sky and by the "
            "surfaces of a scene in the same file (a level set or `normal` grid, its `albedo` "
            "and `emission`: a foggy room lit by its lamps); writes the input's grids plus the "
            "mean radiance `mean_intensity` (and the surfaces' `radiosity`)",
            withToolOptions(cloudSolveOptions(), {kVerbose, kOverwrite, kQuiet}),
            {"vdbrad make cumulus - | vdbrad solve-cloud - lit.vdb --sun 40,0",
                "vdbrad make cumulus - | vdbrad solve-cloud - day.vdb --sky-model clear "
                "--sun 40,30 --irradiance 100",
                "vdbrad make cornell --tau 1 - | vdbrad solve-cloud - foggy.vdb --irradiance 0",
                "vdbrad solve-cloud slab.vdb out.vdb --periodic --sun 60,0 --albedo 0"},
            runSolveCloud},
        {"render", "IN OUT.exr", 2, 2,
            "render a solved scene (surface radiosity, or a cloud's scattered light) to an "
            "OpenEXR image, and optionally a PNG preview",
            withToolOptions(renderImageOptions(), {kVerbose, kOverwrite, kQuiet}),
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
    } catch (const OptionError& e) {   // options the library's requests refuse together
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
