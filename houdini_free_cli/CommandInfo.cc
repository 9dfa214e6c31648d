// `vdbrad info`, `surface` and `compare`: look at a file, at what the solver will see in it, and
// at how far one solve is from another.
#include "Commands.h"
#include "Progress.h"
#include "ToolSupport.h"

#include "vdbrad/request/SharedOptions.h"

#include "vdbrad/vdbrad.h"

#include <algorithm>
#include <cmath>
#include <cstdlib>
#include <iostream>
#include <limits>
#include <map>
#include <sstream>

namespace vdbrad {
namespace cli {

namespace {

// A cloud solve's scattered-light moments (ScatteredSource.h: J_sh0, J_sh1, ...): k for a
// grid named PREFIX_shk, else -1.
int
moment(const openvdb::GridBase& g, std::string& prefix)
{
    const std::string& name = g.getName();
    const size_t at = name.rfind("_sh");
    if (at == std::string::npos || at + 3 == name.size()
        || name.find_first_not_of("0123456789", at + 3) != std::string::npos) {
        return -1;
    }
    prefix = name.substr(0, at);
    return std::atoi(name.c_str() + at + 3);
}

// The last grid of the run of moments that starts with grid @a first (PREFIX_sh0): listed as
// one.
size_t
momentRun(const openvdb::GridPtrVec& grids, size_t first)
{
    std::string prefix, next;
    if (moment(*grids[first], prefix) != 0) return first;
    size_t last = first;
    while (last + 1 < grids.size() && moment(*grids[last + 1], next) == int(last + 1 - first)
        && next == prefix) {
        ++last;
    }
    return last;
}

// The file's metadata, then one line per grid: type, class, voxels, memory, bounds.
void
describeGrids(std::ostream& os, const std::string& label, const VdbFile& file)
{
    os << label << ": " << file.grids.size() << " grid" << (file.grids.size() == 1 ? "" : "s");
    for (auto it = file.metadata->beginMeta(); it != file.metadata->endMeta(); ++it) {
        os << (it == file.metadata->beginMeta() ? "; " : ", ") << it->first << " = "
           << it->second->str();
    }
    os << "\n";
    for (size_t i = 0; i < file.grids.size(); ++i) {
        const auto& g = file.grids[i];
        const size_t last = momentRun(file.grids, i);
        if (last > i) {
            os << "  '" << g->getName() << "' .. '" << file.grids[last]->getName() << "'  "
               << g->valueType() << ", " << (last - i + 1) << " grids of "
               << withCommas(g->activeVoxelCount()) << " active voxels, "
               << formatBytes(double(g->memUsage()) * double(last - i + 1)) << ": the "
               "scattered light's angular moments (for render)\n";
            i = last;
            continue;
        }
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

// A scene attribute's range and non-zero voxels, or @a absent when the file has no grid for it.
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

} // namespace

namespace {

// The warning for a scene whose voxels emit nothing: none when the file was solved under
// light from outside (a solve's `vdbrad:light`).
void
warnUnlit(const std::string& label, const Scene& scene, const openvdb::GridPtrVec& grids)
{
    if (scene.hasEmission()) return;
    for (const openvdb::GridBase::Ptr& g : grids) {
        const auto light = g->getMetadata<openvdb::StringMetadata>("vdbrad:light");
        if (light && !light->value().empty()) return;
    }
    warn(label, "nothing emits: the scene is dark unless lit from outside (solve's --sun, "
        "--sky or --environment)");
}

} // namespace

int
runInfo(const Arguments& a)
{
    const std::string in = a.positional()[0];
    const SceneOptions options = options::sceneOptions(a.request());
    const VdbFile file = readInput(in);
    const std::string label = inputLabel(in);
    describeGrids(std::cout, label, file);

    const std::string density = a.getString("density");
    const GridRoles roles = forFile(label, [&] {
        return identifyRoles(file.grids, options.surface, density);
    });
    std::cout << "scene contract:\n";
    for (const std::string& note : roles.notes) std::cout << "  read:      " << note << "\n";
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
            if (scene.isGlossy()) {
                std::cout << "  specular:  " << describeAttribute(scene.specular(), "none")
                          << " (glossy lobes)\n";
                std::cout << "  roughness: " << describeAttribute(scene.roughness(),
                    ("none: uniform " + std::to_string(options.defaultRoughness)
                        + " (--roughness)").c_str()) << "\n";
            }
            std::cout << "  solution:  " << (scene.isRgb() ? "RGB" : "grey") << " radiosity\n";
            warnUnlit(label, scene, file.grids);
        } catch (const std::exception& e) {
            report("surface:  ", e);
        }
    } else {
        std::cout << "  surface:   none (no level set, no vec3s grid named 'normal')\n";
    }
    if (roles.density) {
        try {
            // With a surface in the file, `albedo` is the surfaces' (solve-cloud solves both).
            CloudOptions cloudOpts;
            cloudOpts.density = density;
            cloudOpts.albedoGrid = !roles.surface;
            const Cloud cloud = buildCloud(file.grids, cloudOpts);
            float lo = std::numeric_limits<float>::max(), hi = 0.f;
            for (float s : cloud.extinctionArray()) { lo = std::min(lo, s); hi = std::max(hi, s); }
            std::cout << "  cloud:     " << withCommas(cloud.size()) << " medium voxels from '"
                      << cloud.densityName() << "', extinction in [" << lo << ", " << hi
                      << "] per world unit, max optical depth per voxel "
                      << hi * cloud.voxelSize() << "\n";
            std::cout << "  cloud albedo: " << describeAttribute(cloud.albedo(), roles.surface
                ? "none: 1 (`albedo` is the surfaces'; solve-cloud --albedo)" : "none: 1") << "\n";
            if (roles.surface) {
                std::cout << "  fog in a surface scene: `vdbrad solve-cloud` solves both\n";
            }
        } catch (const std::exception& e) {
            report("cloud:    ", e);
        }
    } else {
        std::cout << "  cloud:     none (no float or double grid named '" << density << "')\n";
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
                 meta::kLines, meta::kSeconds, meta::kBrdf, meta::kControlPoints,
                 meta::kHarmonicOrder, meta::kRanks, meta::kVersion}) {
            if (auto m = (*result)[key]) std::cout << ", " << key + 7 << " " << m->str();
        }
        std::cout << "\n";
    }
    std::vector<std::string> passed;
    for (size_t i = 0; i < file.grids.size(); ++i) {
        const auto& g = file.grids[i];
        if (g == result) continue;
        if (!roles.uses(g) && g->getName() != names::kSpecularRadiosity) {
            const size_t last = momentRun(file.grids, i);
            passed.push_back("'" + g->getName() + "'" + (last > i ? " .. '"
                + file.grids[last]->getName() + "'" : std::string()));
            i = last;
        }
    }
    if (!passed.empty()) {
        std::cout << "  passed through:";
        for (const auto& p : passed) std::cout << " " << p;
        std::cout << "\n";
    }
    return status;
}

int
runSurface(const Arguments& a)
{
    const std::string in = a.positional()[0], out = a.positional()[1];
    const SceneOptions options = options::sceneOptions(a.request());
    checkOutput(out, {in}, a.flag("overwrite"));
    const VdbFile file = readInput(in);
    const std::string label = inputLabel(in);
    describeReading(a, label, file, options.surface, names::kDensity);
    ProgressInterrupter progress(a.flag("quiet"));
    const Scene scene = forFile(label, [&] { return buildScene(file.grids, options, &progress); });
    warnUnlit(label, scene, file.grids);
    writeOutput(withGrids(file, sceneToGrids(scene)), out);
    return 0;
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
    // channels, the figures of the trade study (docs/journal/2026-11-25-speed-accuracy-trade.md).
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

} // namespace cli
} // namespace vdbrad
