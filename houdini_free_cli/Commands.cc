#include "Commands.h"

#include "Progress.h"

#include "grids/CanonicalGrids.h"
#include "vdbrad/MonteCarloSolver.h"
#include "vdbrad/Checkpoint.h"
#include "vdbrad/CloudTransfer.h"
#include "vdbrad/GridIO.h"
#include "vdbrad/ImageIO.h"
#include "vdbrad/RadiositySolver.h"
#include "vdbrad/Renderer.h"
#include "vdbrad/Voxelizer.h"
#include "vdbrad/vdbrad.h"

#include <tbb/global_control.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <functional>
#include <iomanip>
#include <iostream>
#include <map>
#include <sstream>
#include <sys/stat.h>
#include <unistd.h>

namespace vdbrad {
namespace cli {

namespace {

// ---- standard streams and files ----------------------------------------------------------------

bool isStdin(const std::string& p) { return p == "-" || p == "stdin.vdb"; }
bool isStdout(const std::string& p) { return p == "-" || p == "stdout.vdb"; }
std::string inputLabel(const std::string& p) { return isStdin(p) ? "<stdin>" : p; }
std::string outputLabel(const std::string& p) { return isStdout(p) ? "<stdout>" : p; }

/// Checks on an output made before any heavy work, so a bad command line fails in milliseconds.
void
checkOutput(const std::string& out, const std::vector<std::string>& inputs, bool overwrite)
{
    if (isStdout(out)) {
        if (::isatty(STDOUT_FILENO) == 1) {
            throw UsageError("refusing to write VDB data to a terminal; redirect standard output "
                "or give a file name");
        }
        return;
    }
    struct stat so;
    if (::stat(out.c_str(), &so) == 0) {
        if (S_ISDIR(so.st_mode)) throw UserError(out + ": is a directory");
        for (const auto& in : inputs) {
            struct stat si;
            if (!isStdin(in) && ::stat(in.c_str(), &si) == 0 && si.st_dev == so.st_dev
                && si.st_ino == so.st_ino && !overwrite) {
                throw UsageError("output '" + out + "' is the input file; pass --overwrite to "
                    "replace it");
            }
        }
    }
    const size_t slash = out.find_last_of('/');
    const std::string dir = slash == std::string::npos ? "." : out.substr(0, slash + 1);
    struct stat sd;
    if (::stat(dir.c_str(), &sd) != 0 || !S_ISDIR(sd.st_mode)) {
        throw UserError(out + ": folder '" + dir + "' does not exist");
    }
}

VdbFile
readInput(const std::string& path)
{
    try {
        if (isStdin(path)) {
            if (::isatty(STDIN_FILENO) == 1) {
                throw UsageError("refusing to read VDB data from a terminal; pipe a file in");
            }
            return readVdbStream(std::cin);
        }
        return readVdbFile(path);
    } catch (const UsageError&) {
        throw;
    } catch (const std::exception& e) {
        throw UserError(inputLabel(path) + ": " + errorMessage(e));
    }
}

void
writeOutput(const VdbFile& file, const std::string& path)
{
    try {
        const std::string bytes = serializeVdb(file);
        if (isStdout(path)) {
            // One write of complete bytes: a failure before this point leaves stdout empty.
            if (std::fwrite(bytes.data(), 1, bytes.size(), stdout) != bytes.size()
                || std::fflush(stdout) != 0) {
                throw UserError("<stdout>: write failed");
            }
            return;
        }
        writeFileAtomic(path, bytes);
    } catch (const UserError&) {
        throw;
    } catch (const std::exception& e) {
        throw UserError(outputLabel(path) + ": " + errorMessage(e));
    }
}

void
warn(const std::string& label, const std::string& what)
{
    std::cerr << "vdbrad: warning: " << label << ": " << what << "\n";
}

// Runs @a f, turning library errors into one user line naming @a label.
template<typename F>
auto
forFile(const std::string& label, F&& f) -> decltype(f())
{
    try {
        return f();
    } catch (const Cancelled&) {
        throw;
    } catch (const UserError&) {
        throw;
    } catch (const UsageError&) {
        throw;
    } catch (const std::exception& e) {
        throw UserError(label + ": " + errorMessage(e));
    }
}

// ---- option groups shared by several commands ---------------------------------------------------

const OptionSpec kQuiet{"quiet", OptionType::Flag, "", "", "no progress messages on stderr"};
const OptionSpec kOverwrite{"overwrite", OptionType::Flag, "", "",
    "allow the output to replace an input file"};
// Convergence acceleration, the same for solve and solve-cloud (Acceleration.h).
const OptionSpec kAccelerate{"accelerate", OptionType::String, "none", "anderson",
    "none, or anderson: Anderson mixing of the last --anderson-depth iterates (for albedos "
    "near 1 and optically thick clouds: tens of sweeps instead of thousands)"};
// Checkpoints (Checkpoint.h) and threads, the same for solve and solve-cloud.
const OptionSpec kCheckpoint{"checkpoint", OptionType::String, "", "state.ckpt",
    "save resumable state to this file every --checkpoint-every iterations (atomically; "
    "removed once the output is written)"};
const OptionSpec kCheckpointEvery{"checkpoint-every", OptionType::Int, "10", "5",
    "iterations between checkpoints, >= 1"};
const OptionSpec kResume{"resume", OptionType::String, "", "state.ckpt",
    "continue the solve saved in this checkpoint (same input and solver options): the result "
    "is bit-identical to an uninterrupted run"};
const OptionSpec kMaxMemory{"max-memory", OptionType::String, "3/4 of RAM", "8G",
    "refuse a solve whose estimated peak memory exceeds this (bytes, or with K, M, G, T: "
    "binary units)"};
const OptionSpec kThreads{"threads", OptionType::Int, "0", "2",
    "worker threads (0: all cores); the result does not depend on it"};
const OptionSpec kAndersonDepth{"anderson-depth", OptionType::Int, "16", "8",
    "iterates --accelerate anderson mixes; it keeps 2 x depth + 2 copies of the solution"};

std::vector<OptionSpec>
sceneOptionSpecs()
{
    return {
        {"surface", OptionType::String, "", "surface",
            "grid to use as the surface (a level set or a vec3s normal grid); default: `normal`, "
            "else the only level set"},
        {"albedo", OptionType::Float, "0.5", "0.7",
            "diffuse albedo in [0, 1] of every voxel when the file has no `albedo` grid"},
        {"separation", OptionType::Int, "26", "6",
            "level sets: 26 (surface blocks 26-connected lines) or 6 (thinner, blocks "
            "6-connected lines)"},
    };
}

SceneOptions
sceneOptions(const Arguments& a)
{
    SceneOptions o;
    o.surface = a.getString("surface");
    o.defaultAlbedo = float(a.getFloat("albedo"));
    o.separation = a.getInt("separation");
    if (!(o.defaultAlbedo >= 0.f && o.defaultAlbedo <= 1.f)) {
        throw UsageError("--albedo must be in [0, 1], got " + a.getString("albedo"));
    }
    if (o.separation != 6 && o.separation != 26) {
        throw UsageError("--separation must be 6 or 26, got " + a.getString("separation"));
    }
    return o;
}

template<typename T>
std::vector<T>
concat(std::vector<T> a, const std::vector<T>& b)
{
    a.insert(a.end(), b.begin(), b.end());
    return a;
}

std::string
withCommas(uint64_t n)
{
    std::string s = std::to_string(n);
    for (int i = int(s.size()) - 3; i > 0; i -= 3) s.insert(size_t(i), ",");
    return s;
}

std::string
formatBytes(double b)
{
    std::ostringstream os;
    os << std::fixed << std::setprecision(1);
    if (b < 1024) os << b << " B";
    else if (b < 1024 * 1024) os << b / 1024 << " KiB";
    else if (b < 1024.0 * 1024 * 1024) os << b / (1024 * 1024) << " MiB";
    else if (b < 1024.0 * 1024 * 1024 * 1024) os << b / (1024.0 * 1024 * 1024) << " GiB";
    else os << b / (1024.0 * 1024 * 1024 * 1024) << " TiB";
    return os.str();
}

// ---- make ------------------------------------------------------------------------------------

int
runMake(const Arguments& a)
{
    const std::string name = a.positional()[0], out = a.positional()[1];
    const grids::Builder* builder = grids::findBuilder(name);
    if (!builder) {
        std::vector<std::string> names;
        for (const auto& b : grids::builders()) names.push_back(b.name);
        std::string msg = "unknown scene '" + name + "'";
        if (auto s = suggest(name, names)) msg += "; did you mean '" + *s + "'?";
        else {
            msg += "; one of:";
            for (const auto& n : names) msg += " " + n;
        }
        throw UsageError(msg);
    }
    grids::BuildParams p;
    p.res = a.getInt("res");
    if (p.res < 1 || p.res > 4096) {
        throw UsageError("--res must be in [1, 4096], got " + a.getString("res"));
    }
    // Negative BuildParams fields mean "the scene's default": reject negatives here, where the
    // user typed them.
    auto optional = [&](const char* opt, float& field, float hi) {
        if (!a.has(opt)) return;
        field = float(a.getFloat(opt));
        if (!(field >= 0.f && field <= hi)) {
            std::ostringstream os;
            os << "--" << opt << " must be in [0, " << hi << "], got " << a.getString(opt);
            throw UsageError(os.str());
        }
    };
    const float big = std::numeric_limits<float>::max();
    optional("albedo", p.albedo, 1.f);
    optional("emission", p.emission, big);
    optional("radius", p.radius, big);
    optional("height", p.height, big);
    optional("tau", p.tau, big);
    if (a.has("seed")) {
        if (a.getInt("seed") < 0) throw UsageError("--seed must be >= 0");
        p.seed = unsigned(a.getInt("seed"));
    }
    checkOutput(out, {}, true);

    ProgressInterrupter progress(a.flag("quiet"));
    VdbFile file;
    progress.start(("building " + name + " at " + std::to_string(p.res)).c_str());
    // Builder messages start with the scene's name already.
    file.grids = forFile("make", [&] { return builder->build(p); });
    progress.end();
    file.metadata->insertMeta("creator", openvdb::StringMetadata(
        std::string("vdbrad ") + VDBRAD_VERSION_STRING));
    writeOutput(file, out);
    return 0;
}

// ---- voxelize --------------------------------------------------------------------------------

int
runVoxelize(const Arguments& a)
{
    const std::string in = a.positional()[0], out = a.positional()[1];
    VoxelizeOptions o;
    if (a.has("voxel-size")) {
        if (a.has("res")) throw UsageError("give --voxel-size or --res, not both");
        o.voxelSize = a.getFloat("voxel-size");
        if (!(o.voxelSize > 0.0) || !std::isfinite(o.voxelSize)) {
            throw UsageError("--voxel-size must be > 0, got " + a.getString("voxel-size"));
        }
    }
    o.resolution = a.getInt("res");
    if (o.resolution < 1 || o.resolution > 16384) {
        throw UsageError("--res must be in [1, 16384], got " + a.getString("res"));
    }
    o.separation = a.getInt("separation");
    if (o.separation != 6 && o.separation != 26) {
        throw UsageError("--separation must be 6 or 26, got " + a.getString("separation"));
    }
    o.defaultAlbedo = float(a.getFloat("albedo"));
    if (!(o.defaultAlbedo >= 0.f && o.defaultAlbedo <= 1.f)) {
        throw UsageError("--albedo must be in [0, 1], got " + a.getString("albedo"));
    }
    o.keepSdf = a.flag("keep-sdf");
    if (isStdin(in)) throw UsageError("the mesh must be a file (its MTL files are found beside it)");
    checkOutput(out, {in}, a.flag("overwrite"));

    ProgressInterrupter progress(a.flag("quiet"));
    progress.start(("reading " + in).c_str());
    // Mesh errors already start with the file name (and line): no label of our own.
    const TriangleMesh mesh = [&] {
        try {
            return readMesh(in);
        } catch (const std::exception& e) {
            throw UserError(errorMessage(e));
        }
    }();
    progress.end(std::to_string(mesh.triangles.size()) + " triangles");
    VdbFile file;
    file.grids = forFile(in, [&] { return voxelizeMesh(mesh, o, &progress); });
    const openvdb::GridBase::Ptr normal = file.grids.front();
    if (!a.flag("quiet")) {
        std::cerr << "voxelized " << in << ": " << withCommas(normal->activeVoxelCount())
                  << " surface voxels, voxel size " << normal->voxelSize()[0] << ", "
                  << o.separation << "-separating\n";
    }
    if (!findGrid(file.grids, names::kEmission)) {
        warn(in, "nothing emits (no MTL material with Ke > 0): the scene will be dark");
    }
    file.metadata->insertMeta("creator", openvdb::StringMetadata(
        std::string("vdbrad ") + VDBRAD_VERSION_STRING));
    writeOutput(file, out);
    return 0;
}

// ---- info ------------------------------------------------------------------------------------

void
describeGrids(std::ostream& os, const std::string& label, const VdbFile& file)
{
    os << label << ": " << file.grids.size() << " grid" << (file.grids.size() == 1 ? "" : "s");
    for (auto it = file.metadata->beginMeta(); it != file.metadata->endMeta(); ++it) {
        os << (it == file.metadata->beginMeta() ? "; " : ", ") << it->first << " = "
           << it->second->str();
    }
    os << "\n";
    for (const auto& g : file.grids) {
        const openvdb::CoordBBox box = g->evalActiveVoxelBoundingBox();
        os << "  '" << g->getName() << "'  " << g->valueType() << ", "
           << openvdb::GridBase::gridClassToString(g->getGridClass()) << ", "
           << withCommas(g->activeVoxelCount()) << " active voxels, voxel size "
           << g->transform().voxelSize()[0] << ", " << formatBytes(double(g->memUsage())) << "\n";
        if (!box.empty()) {
            const openvdb::BBoxd world = g->transform().indexToWorld(box);
            os << "      index " << box.min() << " .. " << box.max() << ", world " << world.min()
               << " .. " << world.max() << "\n";
        }
    }
}

std::string
describeAttribute(const Attribute& a, const char* absent)
{
    if (a.isUniform()) return absent;
    float lo = std::numeric_limits<float>::max(), hi = -lo;
    size_t nonZero = 0;
    const size_t n = a.isRgb() ? a.rgbArray().size() : a.greyArray().size();
    for (size_t i = 0; i < n; ++i) {
        const openvdb::Vec3f c = a.rgb(i);
        lo = std::min({lo, c[0], c[1], c[2]});
        hi = std::max({hi, c[0], c[1], c[2]});
        if (c[0] != 0.f || c[1] != 0.f || c[2] != 0.f) ++nonZero;
    }
    std::ostringstream os;
    os << (a.isRgb() ? "RGB" : "grey") << " grid, values in [" << lo << ", " << hi << "], "
       << withCommas(nonZero) << " non-zero voxels";
    return os.str();
}

int
runInfo(const Arguments& a)
{
    const std::string in = a.positional()[0];
    const SceneOptions options = sceneOptions(a);
    const VdbFile file = readInput(in);
    const std::string label = inputLabel(in);
    describeGrids(std::cout, label, file);

    const GridRoles roles = forFile(label, [&] { return identifyRoles(file.grids, options.surface); });
    std::cout << "scene contract:\n";
    int status = 0;
    // The first problem is the one error line; a second one (a file with a bad surface and a bad
    // cloud) is described with the rest, on standard output.
    auto report = [&](const char* role, const std::exception& e) {
        std::cout << "  " << role << " error: " << errorMessage(e) << "\n";
        std::cout.flush();
        if (status == 0) std::cerr << "vdbrad: error: " << label << ": " << errorMessage(e) << "\n";
        status = 1;
    };
    if (roles.surface) {
        try {
            ProgressInterrupter progress(true);
            const Scene scene = buildScene(file.grids, options, &progress);
            std::cout << "  surface:   " << withCommas(scene.size()) << " surface voxels from "
                      << (scene.surfaceKind() == GridRoles::SurfaceKind::LevelSet
                             ? "level set '" : "normal grid '")
                      << scene.surfaceName() << "'";
            if (scene.surfaceKind() == GridRoles::SurfaceKind::LevelSet) {
                std::cout << " (" << options.separation << "-separating)";
            }
            std::cout << ", " << formatBytes(double(scene.memUsage())) << " in memory\n";
            std::cout << "  albedo:    " << describeAttribute(scene.albedo(),
                ("none: uniform " + std::to_string(options.defaultAlbedo) + " (--albedo)").c_str())
                      << "\n";
            std::cout << "  emission:  " << describeAttribute(scene.emission(), "none") << "\n";
            std::cout << "  solution:  " << (scene.isRgb() ? "RGB" : "grey") << " radiosity\n";
            if (!scene.hasEmission()) warn(label, "nothing emits: the scene is dark");
        } catch (const std::exception& e) {
            report("surface:  ", e);
        }
    } else {
        std::cout << "  surface:   none (no level set, no vec3s grid named 'normal')\n";
    }
    if (roles.density) {
        try {
            const Cloud cloud = buildCloud(file.grids);
            float lo = std::numeric_limits<float>::max(), hi = 0.f;
            for (float s : cloud.extinctionArray()) { lo = std::min(lo, s); hi = std::max(hi, s); }
            std::cout << "  cloud:     " << withCommas(cloud.size()) << " medium voxels from '"
                      << cloud.densityName() << "', extinction in [" << lo << ", " << hi
                      << "] per world unit, max optical depth per voxel "
                      << hi * cloud.voxelSize() << "\n";
            std::cout << "  cloud albedo: " << describeAttribute(cloud.albedo(), "none: 1") << "\n";
        } catch (const std::exception& e) {
            report("cloud:    ", e);
        }
    } else {
        std::cout << "  cloud:     none (no float grid named 'density')\n";
    }
    // A solved file: the result and how it was obtained.
    const openvdb::GridBase::ConstPtr result = findGrid(file.grids, names::kRadiosity);
    if (result) {
        float lo = std::numeric_limits<float>::max(), hi = -lo;
        auto range = [&](const openvdb::Vec3f& c) {
            lo = std::min({lo, c[0], c[1], c[2]});
            hi = std::max({hi, c[0], c[1], c[2]});
        };
        if (auto f = openvdb::GridBase::constGrid<openvdb::FloatGrid>(result)) {
            for (auto it = f->cbeginValueOn(); it; ++it) range(openvdb::Vec3f(*it));
        } else if (auto v = openvdb::GridBase::constGrid<openvdb::Vec3SGrid>(result)) {
            for (auto it = v->cbeginValueOn(); it; ++it) range(*it);
        }
        std::cout << "  radiosity: " << result->valueType() << ", values in [" << lo << ", " << hi
                  << "]";
        for (const char* key : {meta::kDirections, meta::kIterations, meta::kResidual,
                 meta::kLines, meta::kSeconds, meta::kVersion}) {
            if (auto m = (*result)[key]) std::cout << ", " << key + 7 << " " << m->str();
        }
        std::cout << "\n";
    }
    std::vector<std::string> passed;
    for (const auto& g : file.grids) {
        if (g == result) continue;
        if (g != roles.surface && g != roles.albedo && g != roles.emission && g != roles.density) {
            passed.push_back("'" + g->getName() + "'");
        }
    }
    if (!passed.empty()) {
        std::cout << "  passed through:";
        for (const auto& p : passed) std::cout << " " << p;
        std::cout << "\n";
    }
    return status;
}

// ---- surface ---------------------------------------------------------------------------------

int
runSurface(const Arguments& a)
{
    const std::string in = a.positional()[0], out = a.positional()[1];
    const SceneOptions options = sceneOptions(a);
    checkOutput(out, {in}, a.flag("overwrite"));
    const VdbFile file = readInput(in);
    const std::string label = inputLabel(in);
    ProgressInterrupter progress(a.flag("quiet"));
    const Scene scene = forFile(label, [&] { return buildScene(file.grids, options, &progress); });
    if (!scene.hasEmission()) warn(label, "nothing emits: the scene is dark");
    writeOutput(withGrids(file, sceneToGrids(scene)), out);
    return 0;
}

// ---- compare ---------------------------------------------------------------------------------

// The `radiosity` grid of a file as per-voxel channel values (1 or 3 per voxel), by coordinate.
std::map<openvdb::Coord, openvdb::Vec3d>
radiosityValues(const VdbFile& file, const std::string& label, int& channels)
{
    const openvdb::GridBase::ConstPtr grid = findGrid(file.grids, names::kRadiosity);
    if (!grid) throw UserError(label + ": no grid named 'radiosity' (solve it first)");
    // One map entry per voxel: a huge active tile must fail here, not exhaust memory.
    forFile(label, [&] { VoxelIndex::checkVoxelCount(grid->activeVoxelCount()); });
    std::map<openvdb::Coord, openvdb::Vec3d> values;
    auto add = [&](const openvdb::Coord& xyz, const openvdb::Vec3d& v) {
        if (!std::isfinite(v[0]) || !std::isfinite(v[1]) || !std::isfinite(v[2])) {
            std::ostringstream os;
            os << label << ": radiosity at voxel " << formatCoord(xyz) << " is "
               << (std::isfinite(v[0]) ? std::isfinite(v[1]) ? v[2] : v[1] : v[0]);
            throw UserError(os.str());
        }
        values[xyz] = v;
    };
    if (auto f = openvdb::GridBase::constGrid<openvdb::FloatGrid>(grid)) {
        channels = 1;
        for (auto it = f->cbeginValueOn(); it; ++it) add(it.getCoord(), openvdb::Vec3d(*it, 0, 0));
    } else if (auto v = openvdb::GridBase::constGrid<openvdb::Vec3SGrid>(grid)) {
        channels = 3;
        for (auto it = v->cbeginValueOn(); it; ++it) add(it.getCoord(), openvdb::Vec3d(*it));
    } else {
        throw UserError(label + ": grid 'radiosity' is " + grid->valueType()
            + ", expected float or vec3s");
    }
    return values;
}

int
runCompare(const Arguments& a)
{
    const std::string pathA = a.positional()[0], pathB = a.positional()[1];
    const std::string labelA = inputLabel(pathA), labelB = inputLabel(pathB);
    int channelsA = 0, channelsB = 0;
    const auto A = radiosityValues(readInput(pathA), labelA, channelsA);
    const auto B = radiosityValues(readInput(pathB), labelB, channelsB);
    if (channelsA != channelsB) {
        throw UserError(labelA + " and " + labelB + ": one radiosity is grey, the other RGB");
    }
    if (A.size() != B.size()) {
        throw UserError(labelA + " and " + labelB + ": radiosity on " + withCommas(A.size())
            + " and " + withCommas(B.size()) + " voxels: not the same scene");
    }
    // B is the reference: mean |A - B| / mean |B| and max |A - B| / max |B| over voxels and
    // channels, the figures of BENCHMARKS.md's trade study.
    double diff = 0.0, total = 0.0, worst = 0.0, largest = 0.0;
    for (const auto& [xyz, b] : B) {
        const auto it = A.find(xyz);
        if (it == A.end()) {
            throw UserError(labelA + " and " + labelB + ": radiosity voxels differ (e.g. "
                + formatCoord(xyz) + "): not the same scene");
        }
        for (int c = 0; c < channelsB; ++c) {
            const double d = std::abs(it->second[c] - b[c]);
            diff += d;
            total += std::abs(b[c]);
            worst = std::max(worst, d);
            largest = std::max(largest, std::abs(b[c]));
        }
    }
    std::cout << "voxels " << B.size() << " mean_rel " << (total > 0.0 ? diff / total : 0.0)
              << " max_rel " << (largest > 0.0 ? worst / largest : 0.0) << "\n";
    return 0;
}

// ---- solve -----------------------------------------------------------------------------------

// --directions, --iterations and --tolerance, checked the same way for every solver.
struct IterationLimits
{
    int directions = 0, iterations = 0;
    double tolerance = 0.0;
};

IterationLimits
iterationLimits(const Arguments& a)
{
    IterationLimits l;
    l.directions = a.getInt("directions");
    if (l.directions < 1 || size_t(l.directions) > DirectionSet::maxCount()) {
        throw UsageError("--directions must be in [1, " + std::to_string(DirectionSet::maxCount())
            + "], got " + a.getString("directions"));
    }
    l.iterations = a.getInt("iterations");
    if (l.iterations < 1) throw UsageError("--iterations must be >= 1");
    l.tolerance = a.getFloat("tolerance");
    if (!(l.tolerance >= 0.0)) throw UsageError("--tolerance must be >= 0");
    return l;
}

// --accelerate and --anderson-depth.
void
accelerationOptions(const Arguments& a, Acceleration& accelerate, int& depth)
{
    try {
        accelerate = accelerationFromString(a.getString("accelerate"));
    } catch (const std::exception& e) {
        throw UsageError("--accelerate: " + errorMessage(e));
    }
    depth = a.getInt("anderson-depth");
    if (depth < 1 || depth > 256) {
        throw UsageError("--anderson-depth must be in [1, 256], got " + a.getString("anderson-depth"));
    }
}

// Iterate @a solver (RadiositySolver, CloudTransfer or MonteCarloSolver) to its tolerance or
// @a maxIterations, one progress step per iteration reporting its residual; @a after (if any)
// runs after each iteration.
template<typename SolverT>
void
iterateWithProgress(SolverT& solver, int maxIterations, ProgressInterrupter& progress,
    const std::function<void()>& after = {})
{
    while (!solver.converged() && solver.iterationCount() < maxIterations) {
        const std::string step = "iteration " + std::to_string(solver.iterationCount() + 1);
        progress.start(step.c_str());
        std::ostringstream result;
        result << "residual " << solver.iterate(&progress);
        progress.end(result.str());
        if (after) after();
    }
}

// Threads TBB will run with now (after any --threads limit).
int
workerThreads()
{
    return int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
}

// Bytes this process holds now (resident set: the program, the input, the scene), or, where
// /proc is missing, @a fallback.
double
residentBytes(double fallback)
{
    std::ifstream statm("/proc/self/statm");
    double pages = 0.0, resident = 0.0;
    if (statm >> pages >> resident) return resident * double(::sysconf(_SC_PAGE_SIZE));
    return fallback;
}

// Bytes the input's grids hold in memory.
size_t
fileBytes(const VdbFile& file)
{
    size_t bytes = 0;
    for (const auto& g : file.grids) bytes += size_t(g->memUsage());
    return bytes;
}

// --threads: a TBB limit for the rest of the command (null: all cores).
std::unique_ptr<tbb::global_control>
threadLimit(const Arguments& a)
{
    const int threads = a.getInt("threads");
    if (threads < 0) throw UsageError("--threads must be >= 0 (0: all cores)");
    if (threads == 0) return nullptr;
    return std::make_unique<tbb::global_control>(tbb::global_control::max_allowed_parallelism,
        size_t(threads));
}

// A size in bytes ("512M", "8G", "1.5T", "1000000"; binary units), > 0 or, if @a zero, >= 0.
double
parseBytes(const std::string& option, const std::string& text, bool zero)
{
    char* end = nullptr;
    double v = std::strtod(text.c_str(), &end);
    std::string unit(end ? end : "");
    if (!unit.empty() && (unit.back() == 'B' || unit.back() == 'b')) unit.pop_back();
    if (unit.size() > 1 && (unit.back() == 'i' || unit.back() == 'I')) unit.pop_back();
    const std::string units = "KMGT";
    if (unit.size() == 1 && units.find(char(std::toupper(unit[0]))) != std::string::npos) {
        v *= std::pow(1024.0, double(units.find(char(std::toupper(unit[0]))) + 1));
    } else if (!unit.empty()) {
        v = -1.0;
    }
    if (end == text.c_str() || !(v > 0.0 || (zero && v == 0.0)) || !std::isfinite(v)) {
        throw UsageError("--" + option + ": '" + text + "' is not a size (e.g. 8G, 512M, "
            "1000000" + (zero ? ", 0" : "") + ")");
    }
    return v;
}

// --max-memory: bytes, given or 3/4 of physical memory.
double
memoryLimit(const Arguments& a)
{
    if (!a.has("max-memory")) {
        const long pages = ::sysconf(_SC_PHYS_PAGES), size = ::sysconf(_SC_PAGE_SIZE);
        return pages > 0 && size > 0 ? 0.75 * double(pages) * double(size) : 1e300;
    }
    return parseBytes("max-memory", a.getString("max-memory"), false);
}

// --visibility-cache: bytes, or -1 for auto (half of what --max-memory leaves to the solve).
double
visibilityCacheOption(const Arguments& a)
{
    const std::string text = a.getString("visibility-cache");
    return text == "auto" ? -1.0 : parseBytes("visibility-cache", text, true);
}

// The estimated peak (what the process holds now plus what the solver will allocate), as a line
// to print; refuses to go on past --max-memory, before the solver allocates anything.
std::string
checkMemory(const Arguments& a, const std::string& label, double held, double solver)
{
    const double limit = memoryLimit(a), peak = held + solver;
    if (peak > limit) {
        throw UserError(label + ": the solve needs about " + formatBytes(peak)
            + " of memory, over the " + formatBytes(limit) + " allowed (--max-memory; fewer "
            "voxels or directions, or no --accelerate, need less)");
    }
    return "memory: about " + formatBytes(peak) + " at peak (held now " + formatBytes(held)
        + ", solver " + formatBytes(solver) + "; limit " + formatBytes(limit) + ")\n";
}

// --checkpoint FILE --checkpoint-every K and --resume FILE.
struct Checkpointing
{
    std::string save, resume;
    int every = 10;

    Checkpointing(const Arguments& a, const std::string& in, const std::string& out)
    {
        if (a.has("checkpoint")) save = a.getString("checkpoint");
        if (a.has("resume")) resume = a.getString("resume");
        every = a.getInt("checkpoint-every");
        if (a.has("checkpoint") && save.empty()) throw UsageError("--checkpoint needs a file");
        if (a.has("resume") && resume.empty()) throw UsageError("--resume needs a file");
        if (every < 1) throw UsageError("--checkpoint-every must be >= 1");
        if (a.has("checkpoint-every") && save.empty()) {
            throw UsageError("--checkpoint-every needs --checkpoint FILE");
        }
        for (const std::string& f : {save, resume}) {
            if (!f.empty() && (f == in || f == out || isStdin(f) || isStdout(f))) {
                throw UsageError("a checkpoint must be its own file, not '" + f + "'");
            }
        }
    }

    // Restore @a solver from --resume, if given.
    template<typename SolverT> void restore(SolverT& solver) const
    {
        if (resume.empty()) return;
        std::ifstream f(resume, std::ios::binary);
        if (!f.is_open()) throw UserError(resume + ": cannot open the checkpoint");
        std::ostringstream bytesIn;
        bytesIn << f.rdbuf();
        if (f.bad()) throw UserError(resume + ": cannot read the checkpoint");
        const std::string bytes = bytesIn.str();
        try {
            solver.restoreState(SolverState::parse(bytes, solver.fingerprint()));
        } catch (const std::exception& e) {
            throw UserError(resume + ": " + errorMessage(e));
        }
    }

    // After an iteration: save every @a every iterations (not once converged: the output
    // follows at once).
    template<typename SolverT> std::function<void()> saver(const SolverT& solver) const
    {
        if (save.empty()) return {};
        return [this, &solver] {
            if (solver.iterationCount() % every != 0 || solver.converged()) return;
            SolverState state;
            solver.saveState(state);
            try {
                writeFileAtomic(save, state.serialize(solver.fingerprint()));
            } catch (const std::exception& e) {
                throw UserError(save + ": " + errorMessage(e));
            }
        };
    }

    // Once the output is written the checkpoint has served.
    void finish() const
    {
        if (!save.empty()) std::remove(save.c_str());
    }
};

int
runSolve(const Arguments& a)
{
    const std::string in = a.positional()[0], out = a.positional()[1];
    const SceneOptions sceneOpts = sceneOptions(a);
    RadiosityOptions o;
    const IterationLimits limits = iterationLimits(a);
    o.directions = limits.directions;
    o.maxIterations = limits.iterations;
    o.tolerance = limits.tolerance;
    o.occlusionDepth = float(a.getFloat("occlusion-depth"));
    const std::string method = a.getString("method");
    if (method == "sweep") o.visibility = Visibility::Sweep;
    else if (method == "raycast") o.visibility = Visibility::RayCast;
    else if (method != "montecarlo") {
        throw UsageError("--method must be sweep, raycast or montecarlo, got '" + method + "'");
    }
    MonteCarloOptions mc;
    mc.samples = a.getInt("samples");
    mc.maxIterations = o.maxIterations;
    mc.tolerance = o.tolerance;
    if (mc.samples < 1 || mc.samples > 1000000) {
        throw UsageError("--samples must be in [1, 1000000], got " + a.getString("samples"));
    }
    const int gather = a.getInt("gather");
    if (gather < 0 || gather > 1000000) {
        throw UsageError("--gather must be in [0, 1000000], got " + a.getString("gather"));
    }
    if (gather > 0 && method != "montecarlo") {
        throw UsageError("--gather applies only to --method montecarlo");
    }
    const std::string update = a.getString("update");
    if (update == "jacobi") o.update = UpdateScheme::Jacobi;
    else if (update == "inplace") o.update = UpdateScheme::InPlace;
    else if (update == "progressive") o.update = UpdateScheme::Progressive;
    else {
        throw UsageError("--update must be jacobi, inplace or progressive, got '" + update + "'");
    }
    accelerationOptions(a, o.accelerate, o.andersonDepth);
    if (o.accelerate != Acceleration::None) {
        if (o.update == UpdateScheme::Progressive) {
            throw UsageError("--accelerate needs --update jacobi or inplace, not progressive");
        }
        if (method == "montecarlo") throw UsageError("--accelerate does not apply to --method montecarlo");
    }
    const std::string lines = a.getString("lines");
    if (lines == "naive") o.lines = LineType::Naive;
    else if (lines == "standard") o.lines = LineType::Standard;
    else throw UsageError("--lines must be naive or standard, got '" + lines + "'");
    if (!(o.occlusionDepth > 0.f)) throw UsageError("--occlusion-depth must be > 0");
    try {
        o.precision = precisionFromString(a.getString("precision"));
    } catch (const openvdb::ValueError& e) {
        throw UsageError("--precision: " + errorMessage(e));
    }
    if (method == "montecarlo" && o.precision != Precision::Auto) {
        throw UsageError("--precision does not apply to --method montecarlo");
    }
    const Checkpointing checkpoints(a, in, out);
    memoryLimit(a);   // a bad --max-memory is a usage error before any work
    const double cache = visibilityCacheOption(a);
    if (a.has("visibility-cache") && method != "sweep") {
        throw UsageError("--visibility-cache applies only to --method sweep");
    }
    if (method == "montecarlo" && (!checkpoints.save.empty() || !checkpoints.resume.empty())) {
        throw UsageError("--checkpoint and --resume do not apply to --method montecarlo");
    }
    const std::unique_ptr<tbb::global_control> limit = threadLimit(a);
    checkOutput(out, {in}, a.flag("overwrite"));

    const VdbFile file = readInput(in);
    const std::string label = inputLabel(in);
    const bool quiet = a.flag("quiet");
    ProgressInterrupter progress(quiet);
    const Scene scene = forFile(label, [&] { return buildScene(file.grids, sceneOpts, &progress); });
    if (!scene.hasEmission()) warn(label, "nothing emits: the scene is dark");
    if (method == "montecarlo") {
        if (!quiet) {
            std::cerr << "Monte Carlo: " << withCommas(scene.size()) << " voxels, " << mc.samples
                      << " rays each" << (scene.isRgb() ? ", RGB" : "") << "\n";
        }
        progress.start("casting rays");
        MonteCarloSolver solver(scene, mc, &progress);
        progress.end();
        iterateWithProgress(solver, mc.maxIterations, progress);
        if (gather > 0) {
            const std::string what = "final gather, " + std::to_string(gather) + " rays per voxel";
            progress.start(what.c_str());
            solver.finalGather(gather, &progress);
            progress.end();
        }
        writeOutput(withGrids(file, solver.grids()), out);
        return 0;
    }
    const double held = residentBytes(double(fileBytes(file) + scene.memUsage()));
    if (cache >= 0.0) {
        o.visibilityCache = size_t(std::min(cache, 1e18));
    } else {
        // Auto: half of what the limit leaves once the solve has what it needs without it.
        const double rest = memoryLimit(a) - held
            - double(RadiositySolver::memoryEstimate(scene, o, workerThreads()));
        o.visibilityCache = size_t(std::min(std::max(0.5 * rest, 0.0), 1e18));
    }
    const std::string memory = checkMemory(a, label, held,
        double(RadiositySolver::memoryEstimate(scene, o, workerThreads())));
    RadiositySolver solver(scene, o);
    checkpoints.restore(solver);   // before any message: a refused checkpoint is one line
    if (!quiet) {
        std::cerr << memory << "solving " << withCommas(scene.size()) << " voxels, "
                  << solver.directions().size() << " directions (nearest to " << o.directions
                  << "), " << lines << " lines" << (scene.isRgb() ? ", RGB" : "")
                  << (o.accelerate == Acceleration::Anderson ? ", Anderson acceleration" : "")
                  << (solver.doublePrecision() ? ", double precision" : "") << "\n";
    }
    iterateWithProgress(solver, o.maxIterations, progress, checkpoints.saver(solver));
    if (!quiet && solver.cachedDirections() > 0) {
        std::cerr << "visibility cache: " << solver.cachedDirections() << " of "
                  << solver.directions().size() << " directions kept ("
                  << formatBytes(double(solver.cacheBytes())) << ")\n";
    }
    if (!quiet && !solver.converged()) {
        warn(label, "stopped at --iterations " + std::to_string(o.maxIterations)
            + " with residual " + std::to_string(solver.residuals().back()) + " > --tolerance");
    }
    writeOutput(withGrids(file, {solver.grid()}), out);
    checkpoints.finish();
    return 0;
}

// ---- render ----------------------------------------------------------------------------------

// "a,b,c" -> exactly @a count finite numbers (count 0: one or more), or a UsageError naming the
// option.
std::vector<double>
numberList(const Arguments& a, const char* option, size_t count, const char* shape)
{
    const std::string text = a.getString(option);
    std::vector<double> values;
    std::istringstream is(text);
    for (std::string item; std::getline(is, item, ',');) {
        char* end = nullptr;
        const double v = std::strtod(item.c_str(), &end);
        if (item.empty() || *end != '\0' || !std::isfinite(v)) {
            throw UsageError("--" + std::string(option) + ": '" + item + "' is not a number (expected "
                + shape + ")");
        }
        values.push_back(v);
    }
    if (count == 0 ? values.empty() : values.size() != count) {
        throw UsageError("--" + std::string(option) + " needs "
            + (count ? std::to_string(count) + " " : "") + "comma-separated numbers (" + shape
            + "), got '" + text + "'");
    }
    return values;
}

int
runRender(const Arguments& a)
{
    const std::string in = a.positional()[0], out = a.positional()[1];
    RenderOptions o;
    o.scene = sceneOptions(a);
    {
        const std::string res = a.getString("res");
        int w = 0, h = 0;
        char tail = 0;
        if (std::sscanf(res.c_str(), "%dx%d%c", &w, &h, &tail) != 2 || w < 1 || h < 1
            || w > 16384 || h > 16384) {
            throw UsageError("--res must be WIDTHxHEIGHT, each in [1, 16384], got '" + res + "'");
        }
        o.width = w;
        o.height = h;
    }
    if (a.has("camera")) {
        const std::vector<double> c = numberList(a, "camera", 10,
            "eye x,y,z, target x,y,z, up x,y,z, vertical fov in degrees");
        Camera cam;
        cam.eye = openvdb::Vec3d(c[0], c[1], c[2]);
        cam.target = openvdb::Vec3d(c[3], c[4], c[5]);
        cam.up = openvdb::Vec3d(c[6], c[7], c[8]);
        cam.fov = c[9];
        if (!(cam.fov > 0.0 && cam.fov < 180.0)) {
            throw UsageError("--camera: the field of view must be in (0, 180) degrees");
        }
        o.camera = cam;
    }
    const std::vector<double> bg = numberList(a, "background", 3, "r,g,b");
    o.background = openvdb::Vec3f(float(bg[0]), float(bg[1]), float(bg[2]));
    o.samplesPerPixel = a.getInt("aa");
    if (o.samplesPerPixel < 1 || o.samplesPerPixel > 16) {
        throw UsageError("--aa must be in [1, 16], got " + a.getString("aa"));
    }
    o.cloud.extinctionScale = float(a.getFloat("extinction-scale"));
    if (!(o.cloud.extinctionScale > 0.f) || !std::isfinite(o.cloud.extinctionScale)) {
        throw UsageError("--extinction-scale must be > 0, got " + a.getString("extinction-scale"));
    }
    o.cloudSource = a.getString("cloud-source");
    const std::string type = a.getString("exr-type");
    if (type != "half" && type != "float") {
        throw UsageError("--exr-type must be half or float, got '" + type + "'");
    }
    ToneMap tone;
    tone.exposureStops = a.getFloat("exposure");
    if (!std::isfinite(tone.exposureStops)) throw UsageError("--exposure must be finite");
    const std::string png = a.getString("png");
    checkOutput(out, {in}, a.flag("overwrite"));
    if (!png.empty()) {
        if (isStdout(png)) throw UsageError("--png needs a file name");
        checkOutput(png, {in}, a.flag("overwrite"));
        if (png == out) throw UsageError("--png and the EXR output are the same file");
    }

    const VdbFile file = readInput(in);
    const std::string label = inputLabel(in);
    ProgressInterrupter progress(a.flag("quiet"));
    const Image image = forFile(label, [&] {
        progress.start("reading the scene");
        Renderer renderer(file.grids, o, &progress);
        progress.end();
        const std::string step = "rendering " + std::to_string(o.width) + "x"
            + std::to_string(o.height);
        progress.start(step.c_str());
        Image result = renderer.render(&progress);
        progress.end();
        return result;
    });
    for (const std::string& w : image.warnings) warn(label, w);
    // Both images are encoded before either is written, so an error leaves neither behind.
    const std::string exrBytes = forFile(outputLabel(out), [&] {
        return encodeExr(image, type == "half" ? ExrPixel::Half : ExrPixel::Float);
    });
    const std::string pngBytes = png.empty() ? std::string()
        : forFile(png, [&] { return encodePng(image, tone); });
    if (isStdout(out)) {
        if (std::fwrite(exrBytes.data(), 1, exrBytes.size(), stdout) != exrBytes.size()
            || std::fflush(stdout) != 0) {
            throw UserError("<stdout>: write failed");
        }
    } else {
        forFile(out, [&] { writeFileAtomic(out, exrBytes); });
    }
    if (!png.empty()) forFile(png, [&] { writeFileAtomic(png, pngBytes); });
    return 0;
}

// ---- solve-cloud -----------------------------------------------------------------------------

int
runSolveCloud(const Arguments& a)
{
    const std::string in = a.positional()[0], out = a.positional()[1];
    CloudOptions cloudOpts;
    cloudOpts.extinctionScale = float(a.getFloat("extinction-scale"));
    if (!(cloudOpts.extinctionScale > 0.f) || !std::isfinite(cloudOpts.extinctionScale)) {
        throw UsageError("--extinction-scale must be > 0, got " + a.getString("extinction-scale"));
    }
    cloudOpts.defaultAlbedo = float(a.getFloat("albedo"));
    if (!(cloudOpts.defaultAlbedo >= 0.f && cloudOpts.defaultAlbedo <= 1.f)) {
        throw UsageError("--albedo must be in [0, 1], got " + a.getString("albedo"));
    }
    CloudTransferOptions o;
    const std::vector<double> sun = numberList(a, "sun", 2, "zenith,azimuth in degrees");
    o.sunZenith = sun[0];
    o.sunAzimuth = sun[1];
    if (!(o.sunZenith >= 0.0 && o.sunZenith <= 89.9)) {
        throw UsageError("--sun: the zenith angle must be in [0, 89.9] degrees");
    }
    const std::string up = a.getString("up");
    if (up == "x") o.up = 0;
    else if (up == "y") o.up = 1;
    else if (up == "z") o.up = 2;
    else throw UsageError("--up must be x, y or z, got '" + up + "'");
    o.periodic = a.flag("periodic");
    {
        const std::string period = a.getString("min-period");
        if (period != "auto") {
            char* end = nullptr;
            const long v = std::strtol(period.c_str(), &end, 10);
            if (period.empty() || *end != '\0' || v < 0 || v > 4096) {
                throw UsageError("--min-period must be auto or a voxel count in [0, 4096], got '"
                    + period + "'");
            }
            o.minPeriod = int(v);
        }
        if (a.has("min-period") && !o.periodic) {
            throw UsageError("--min-period applies to --periodic boxes only");
        }
    }
    const IterationLimits limits = iterationLimits(a);
    o.directions = limits.directions;
    o.maxIterations = limits.iterations;
    o.tolerance = limits.tolerance;
    o.irradiance = a.getFloat("irradiance");
    if (!(o.irradiance >= 0.0) || !std::isfinite(o.irradiance)) {
        throw UsageError("--irradiance must be >= 0");
    }
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
        const double g = a.getFloat("g");
        if (!(g > -1.0 && g < 1.0)) throw UsageError("--g must be in (-1, 1), got " + a.getString("g"));
        o.phase = PhaseFunction::henyeyGreenstein(g);
    }
    o.phaseOrder = a.getInt("phase-order");
    if (o.phaseOrder < 0 || o.phaseOrder > 32) {
        throw UsageError("--phase-order must be in [0, 32], got " + a.getString("phase-order"));
    }
    accelerationOptions(a, o.accelerate, o.andersonDepth);
    const Checkpointing checkpoints(a, in, out);
    memoryLimit(a);
    const std::unique_ptr<tbb::global_control> limit = threadLimit(a);
    checkOutput(out, {in}, a.flag("overwrite"));

    const VdbFile file = readInput(in);
    const std::string label = inputLabel(in);
    const bool quiet = a.flag("quiet");
    ProgressInterrupter progress(quiet);
    const Cloud cloud = forFile(label, [&] { return buildCloud(file.grids, cloudOpts, &progress); });
    const std::string memory = checkMemory(a, label,
        residentBytes(double(fileBytes(file) + cloud.memUsage())),
        double(CloudTransfer::memoryEstimate(cloud, o, workerThreads())));
    CloudTransfer transfer = forFile(label, [&] { return CloudTransfer(cloud, o, &progress); });
    checkpoints.restore(transfer);
    if (!quiet) {
        std::cerr << memory << "cloud: " << withCommas(cloud.size()) << " voxels, "
                  << transfer.directions().size() << " directions (nearest to " << o.directions
                  << "), " << (o.periodic ? "periodic" : "open") << " boundaries"
                  << (transfer.copies() != openvdb::Coord(1)
                      ? " (solved as " + std::to_string(transfer.copies().x()) + " x "
                          + std::to_string(transfer.copies().y()) + " x "
                          + std::to_string(transfer.copies().z()) + " copies of the box)"
                      : std::string())
                  << (o.accelerate == Acceleration::Anderson ? ", Anderson acceleration" : "")
                  << "\n";
    }
    iterateWithProgress(transfer, o.maxIterations, progress, checkpoints.saver(transfer));
    const CloudBudget& b = transfer.budget();
    if (!quiet) {
        std::cerr << "albedo " << b.albedo << ", transmittance " << b.transmittance
                  << " (direct " << b.directTransmittance << "), absorptance " << b.absorptance
                  << "; balance " << b.balance() << "\n";
        if (!transfer.converged()) {
            warn(label, "stopped at --iterations " + std::to_string(o.maxIterations)
                + " with residual " + std::to_string(transfer.residuals().back())
                + " > --tolerance");
        }
    }
    writeOutput(withGrids(file, {transfer.grid(name)}), out);
    checkpoints.finish();
    return 0;
}

// ---- help ------------------------------------------------------------------------------------

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

std::string
builderList()
{
    std::string s;
    for (const auto& b : grids::builders()) s += (s.empty() ? "" : ", ") + b.name;
    return s;
}

} // namespace

const std::vector<CommandSpec>&
commands()
{
    static const std::vector<CommandSpec> table = {
        {"make", "NAME OUT.vdb", 2, 2,
            "build a canonical scene or cloud (" + builderList() + ")",
            {{"res", OptionType::Int, "64", "256", "voxels along the longest axis, 1..4096"},
                {"albedo", OptionType::Float, "scene's", "0.5",
                    "albedo in [0, 1] (furnaces; single-scattering albedo for clouds)"},
                {"emission", OptionType::Float, "1", "2", "emitted radiosity of the emitters, >= 0"},
                {"radius", OptionType::Float, "0.25", "0.2", "disk: emitter radius, world units"},
                {"height", OptionType::Float, "scene's", "0.25",
                    "disk, plates: emitter-receiver distance, world units"},
                {"tau", OptionType::Float, "scene's", "10",
                    "slab: vertical optical thickness; cumulus: optical diameter"},
                {"seed", OptionType::Int, "1", "7", "cumulus: shape seed"},
                kQuiet},
            {"vdbrad make cornell cornell.vdb --res 128",
                "vdbrad make furnace-box - --albedo 0.9 | vdbrad info -",
                "vdbrad make slab slab.vdb --tau 20"},
            runMake},
        {"voxelize", "MESH OUT.vdb", 2, 2,
            "voxelize an OBJ (with MTL: Kd albedo, Ke emission) or PLY mesh into a surface "
            "scene (normal, albedo, emission grids)",
            {{"res", OptionType::Int, "128", "256", "voxels along the mesh's longest axis, 1..16384"},
                {"voxel-size", OptionType::Float, "", "0.01",
                    "voxel edge in world units, instead of --res"},
                {"separation", OptionType::Int, "26", "6",
                    "26: the surface blocks naive lines (solve's default); 6: thinner, blocks "
                    "standard lines only (solve with --lines standard)"},
                {"albedo", OptionType::Float, "0.5", "0.7",
                    "albedo of triangles without a material, in meshes that have materials"},
                {"keep-sdf", OptionType::Flag, "", "",
                    "also write the mesh's level set `surface` (closed meshes only)"},
                kOverwrite, kQuiet},
            {"vdbrad voxelize room.obj room.vdb --res 256",
                "vdbrad voxelize room.obj - | vdbrad solve - - | vdbrad render - room.exr"},
            runVoxelize},
        {"info", "FILE", 1, 1,
            "describe a file's grids and what the scene contract finds in it",
            sceneOptionSpecs(),
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
            concat(sceneOptionSpecs(), {
                {"directions", OptionType::Int, "300", "1000",
                    "direction pairs swept per iteration (the nearest count a discrete sphere "
                    "gives is used)"},
                {"iterations", OptionType::Int, "200", "50", "iteration cap, >= 1"},
                {"tolerance", OptionType::Float, "1e-5", "1e-4",
                    "stop when max|B' - B| / max|B'| falls below this"},
                {"update", OptionType::String, "inplace", "jacobi",
                    "inplace (B updated after each half of the directions; fewer iterations), "
                    "jacobi (thesis eq. 4.11) or progressive (shoots the unshot radiosity: "
                    "iteration k = k bounces)"},
                {"method", OptionType::String, "sweep", "raycast",
                    "sweep (the line sweeps), raycast (reference: marches every receiver's line "
                    "through the tree; same lines and rule, far slower) or montecarlo "
                    "(reference: cosine-weighted continuous rays; also writes radiosity_stderr; "
                    "ignores --directions, --lines, --update)"},
                {"samples", OptionType::Int, "256", "4096",
                    "rays per voxel for --method montecarlo (stored: 4 bytes each)"},
                {"gather", OptionType::Int, "0", "4096",
                    "--method montecarlo: a final gather of this many fresh rays per voxel from "
                    "the solved --samples pass (not stored: a low-noise reference in the memory "
                    "of --samples; 256 samples are enough), 0 for none"},
                {"lines", OptionType::String, "naive", "standard",
                    "digital lines: naive (26-connected) or standard (6-connected)"},
                {"occlusion-depth", OptionType::Float, "1", "1.5",
                    "voxels: a receiver this far behind the wall voxel before it is hidden"},
                {"precision", OptionType::String, "auto", "double",
                    "auto, float or double: the solver's state (auto: double when an albedo "
                    "exceeds 0.999, where float rounding, amplified by 1 / (1 - albedo), would "
                    "show)"},
                {"visibility-cache", OptionType::String, "auto", "2G",
                    "memory for remembering what each voxel sees along each direction (~1.3 "
                    "bytes per voxel and direction), so that iterations after the first replay "
                    "it instead of sweeping (3-4x faster, same result): a size (K, M, G, T), 0 "
                    "for none, or auto: half of what --max-memory leaves"},
                kAccelerate, kAndersonDepth, kCheckpoint, kCheckpointEvery, kResume, kThreads,
                kMaxMemory, kOverwrite, kQuiet}),
            {"vdbrad make cornell - | vdbrad solve - cornell_lit.vdb --directions 1000",
                "vdbrad solve scene.vdb out.vdb --lines standard --tolerance 1e-4"},
            runSolve},
        {"solve-cloud", "IN OUT", 2, 2,
            "solve the light in a fog volume (`density` grid) lit by the sun; writes the input's "
            "grids plus the mean radiance `mean_intensity`",
            {{"sun", OptionType::String, "0,0", "60,30",
                    "sun zenith angle from the up axis and azimuth, degrees"},
                {"up", OptionType::String, "y", "z", "vertical axis: y (Houdini) or z (Blender)"},
                {"periodic", OptionType::Flag, "", "",
                    "wrap light around the two horizontal axes (a tile of an infinite field)"},
                {"min-period", OptionType::String, "auto", "0",
                    "--periodic: solve a box narrower than this many voxels as copies side by "
                    "side (light wrapping a narrow box rises by whole layers: thin slabs "
                    "over-absorb); auto: sqrt(directions) / 2, fewer where the box is "
                    "optically thick; 0: never"},
                {"albedo", OptionType::Float, "1", "0.99",
                    "single-scattering albedo in [0, 1] where the file has no `albedo` grid"},
                {"g", OptionType::Float, "0", "0.85",
                    "Henyey-Greenstein asymmetry in (-1, 1); 0: isotropic"},
                {"legendre", OptionType::String, "", "1,0.8,0.6",
                    "phase function as Legendre coefficients chi_0 = 1, chi_1, ... (e.g. Mie), "
                    "instead of --g"},
                {"phase-order", OptionType::Int, "8", "6",
                    "spherical-harmonic order kept for an anisotropic phase (delta-M beyond); "
                    "(order + 1)^2 floats per voxel"},
                {"extinction-scale", OptionType::Float, "1", "10",
                    "extinction per world unit = density x this"},
                {"irradiance", OptionType::Float, "1", "3",
                    "sun irradiance F0 on a plane normal to the beam"},
                {"directions", OptionType::Int, "300", "1000",
                    "direction pairs swept per iteration (nearest achievable count)"},
                {"iterations", OptionType::Int, "1000", "100", "source-iteration cap, >= 1"},
                {"tolerance", OptionType::Float, "1e-6", "1e-4",
                    "stop when max|J' - J| / max|J'| falls below this"},
                kAccelerate, kAndersonDepth, kCheckpoint, kCheckpointEvery, kResume, kThreads,
                kMaxMemory,
                {"output-name", OptionType::String, "mean_intensity", "scatter",
                    "name of the output grid (e.g. `scatter` for Houdini volume shaders)"},
                kOverwrite, kQuiet},
            {"vdbrad make cumulus - | vdbrad solve-cloud - lit.vdb --sun 40,0",
                "vdbrad solve-cloud slab.vdb out.vdb --periodic --sun 60,0 --albedo 0"},
            runSolveCloud},
        {"render", "IN OUT.exr", 2, 2,
            "render a solved scene (surface radiosity, or a cloud's scattered light) to an "
            "OpenEXR image, and optionally a PNG preview",
            concat(sceneOptionSpecs(), {
                {"res", OptionType::String, "640x480", "1920x1080", "image size WIDTHxHEIGHT"},
                {"camera", OptionType::String, "", "0.28,0.27,-0.8,0.28,0.27,0,0,1,0,40",
                    "eye x,y,z, target x,y,z, up x,y,z, vertical fov (degrees), world units; "
                    "default: looking along +z at the scene's bounding box, which it frames"},
                {"png", OptionType::String, "", "preview.png",
                    "also write an 8-bit sRGB PNG, tone mapped (the 90th-percentile luminance "
                    "of the scene's pixels maps to 0.8, then --exposure)"},
                {"exposure", OptionType::Float, "0", "1", "PNG exposure adjustment, in stops"},
                {"exr-type", OptionType::String, "half", "float", "EXR pixel type: half or float"},
                {"aa", OptionType::Int, "1", "3", "antialiasing: N x N samples per pixel, 1..16"},
                {"background", OptionType::String, "0,0,0", "0.2,0.3,0.5",
                    "linear RGB seen where rays hit nothing"},
                {"extinction-scale", OptionType::Float, "1", "10",
                    "clouds: multiplies the density grid, as for the cloud solve"},
                {"cloud-source", OptionType::String, "mean_intensity", "scatter",
                    "clouds: the grid of mean radiance J; the source is albedo x J"},
                kOverwrite, kQuiet}),
            {"vdbrad render lit.vdb lit.exr --png lit.png",
                "vdbrad voxelize room.obj - | vdbrad solve - - | vdbrad render - room.exr --res 1280x720"},
            runRender},
        {"help", "[COMMAND]", 0, 1, "list commands, or describe one",
            {{"markdown", OptionType::Flag, "", "", "print the command reference as Markdown"}},
            {"vdbrad help make", "vdbrad help --markdown"},
            runHelp},
    };
    return table;
}

int
runTool(const std::vector<std::string>& args)
{
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
        const Arguments parsed = parseCommand(*command, rest);
        openvdb::initialize();
        return command->run(parsed);
    } catch (const UsageError& e) {
        std::cerr << "vdbrad: error: " << e.what() << "\n";
        return 2;
    } catch (const UserError& e) {
        std::cerr << "vdbrad: error: " << e.what() << "\n";
        return 1;
    } catch (const Cancelled&) {
        std::cerr << "vdbrad: cancelled";
        if (ProgressInterrupter::signalNumber() != 0) {
            std::cerr << " by signal " << ProgressInterrupter::signalNumber();
        }
        std::cerr << "; no output written\n";
        return 130;
    } catch (const std::bad_alloc&) {
        std::cerr << "vdbrad: error: out of memory\n";
        return 1;
    } catch (const std::exception& e) {
        std::cerr << "vdbrad: error: " << errorMessage(e) << "\n";
        return 1;
    }
}

} // namespace cli
} // namespace vdbrad
