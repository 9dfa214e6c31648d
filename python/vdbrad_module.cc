// The Python module `vdbrad`: the library's one-call functions on pyopenvdb grids.
//
//     import pyopenvdb, vdbrad
//     grids, _ = pyopenvdb.readAll("cornell.vdb")
//     lit = vdbrad.solve(grids, directions=1000)      # grids + `radiosity`
//     image = vdbrad.render(lit, width=640, height=480)   # numpy float32 (480, 640, 3)
//
// Keyword arguments mirror the command-line tool's options (houdini_free_cli/Commands.cc), '-'
// spelt '_', with the same defaults; errors are Python exceptions carrying the library's
// messages; warnings the tool prints go to Python's `warnings`.
//
// Grids: pyopenvdb (OpenVDB 10) is a Boost.Python module, and wrapping a grid type registers
// converters between its Python class and std::shared_ptr<GridType> in Boost.Python's registry,
// which every module loading the same libboost_python shares. So this module, pybind11 for its
// own functions, crosses grids through that registry: boost::python::extract coming in,
// boost::python::object(ptr) going out. An extracted pointer holds a reference to its Python
// object, which must not be dropped without the GIL, so the library gets a shallow copy
// (copyGrid(): the same tree and transform, not tied to Python), and the caller's grid objects
// themselves pass through to the results.
//
// Threads: the GIL is released while the library works; Ctrl-C reaches it through
// PythonInterrupter. Nothing is written anywhere: an interrupted call returns nothing.
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <boost/python.hpp>

#include "vdbrad/core/Precision.h"
#include "vdbrad/core/TextFormat.h"
#include "vdbrad/distribute/Distribution.h"
#include "vdbrad/glossy/Brdf.h"
#include "vdbrad/sweep/Acceleration.h"
#include "vdbrad/vdbrad.h"

#include <tbb/global_control.h>

#include <unistd.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <thread>
#include <utility>
#include <vector>

namespace py = pybind11;
namespace bp = boost::python;
using namespace py::literals;

namespace vdbrad {
namespace python {
namespace {

/// The MPI job this interpreter runs in, joined at import (null before): solves are shared with
/// its ranks when Python runs under mpirun.
std::unique_ptr<Distribution>&
job()
{
    static std::unique_ptr<Distribution> ranks;
    return ranks;
}

// ---- grids between pyopenvdb and the library ---------------------------------------------------

template<typename T> struct Tag { using Type = T; };

/// Calls @a op(Tag<GridT>()) for every grid type a pyopenvdb build may wrap (Debian's: float,
/// bool and vec3s; with PY_OPENVDB_WRAP_ALL_GRID_TYPES the others too) until it returns true.
template<typename OpT>
bool
forEachGridType(OpT&& op)
{
    using namespace openvdb;
    return op(Tag<FloatGrid>()) || op(Tag<Vec3SGrid>()) || op(Tag<BoolGrid>())
        || op(Tag<DoubleGrid>()) || op(Tag<Int32Grid>()) || op(Tag<Int64Grid>())
        || op(Tag<Vec3DGrid>()) || op(Tag<Vec3IGrid>());
}

std::string
typeName(py::handle obj)
{
    return py::str(py::type::handle_of(obj).attr("__name__")).cast<std::string>();
}

/// The grid of the pyopenvdb object @a obj, as a shallow copy (see the file comment).
/// @throw TypeError if @a obj is not a pyopenvdb grid
openvdb::GridBase::Ptr
gridFromPython(py::handle obj)
{
    const bp::object object{bp::handle<>(bp::borrowed(obj.ptr()))};
    openvdb::GridBase::Ptr grid;
    forEachGridType([&](auto tag) {
        using GridT = typename decltype(tag)::Type;
        bp::extract<typename GridT::Ptr> extracted(object);
        if (!extracted.check()) return false;
        // None converts too, to a null pointer.
        if (const typename GridT::Ptr ptr = extracted()) grid = ptr->copyGrid();
        return true;
    });
    if (!grid) throw py::type_error("expected a pyopenvdb grid, got " + typeName(obj));
    return grid;
}

/// A sequence of pyopenvdb grids (or one grid): its objects, and the grids' shallow copies.
struct InputGrids
{
    std::vector<py::object> objects;
    openvdb::GridPtrVec grids;

    explicit InputGrids(const py::object& in)
    {
        if (py::isinstance<py::str>(in)) {
            throw py::type_error("expected a list of pyopenvdb grids, got a str (a path? read "
                                 "it with pyopenvdb.readAll first)");
        }
        if (!py::isinstance<py::iterable>(in) || isGrid(in)) {
            add(in);
            return;
        }
        for (py::handle item : in) add(item);
    }

private:
    static bool isGrid(const py::object& in)
    {
        const bp::object object{bp::handle<>(bp::borrowed(in.ptr()))};
        return forEachGridType([&](auto tag) {
            using GridT = typename decltype(tag)::Type;
            return !in.is_none() && bp::extract<typename GridT::Ptr>(object).check();
        });
    }
    void add(py::handle item)
    {
        grids.push_back(gridFromPython(item));
        objects.push_back(py::reinterpret_borrow<py::object>(item));
    }
};

void
warn(const std::string& what)
{
    if (PyErr_WarnEx(PyExc_UserWarning, what.c_str(), 1) < 0) throw py::error_already_set();
}

/// @a grid as a pyopenvdb object; None (with a warning) for a type this pyopenvdb does not wrap
/// (Debian's has no int32 grids, e.g. the voxelizer's `material_id`).
py::object
gridToPython(const openvdb::GridBase::Ptr& grid)
{
    py::object result = py::none();
    const bool known = forEachGridType([&](auto tag) {
        using GridT = typename decltype(tag)::Type;
        if (!grid->isType<GridT>()) return false;
        const bp::converter::registration* to =
            bp::converter::registry::query(bp::type_id<typename GridT::Ptr>());
        if (!to || !to->m_to_python) return false;
        try {
            const bp::object object(openvdb::gridPtrCast<GridT>(grid));
            result = py::reinterpret_borrow<py::object>(object.ptr());
        } catch (const bp::error_already_set&) {
            throw py::error_already_set();
        }
        return true;
    });
    if (!known) {
        warn("grid '" + grid->getName() + "' (" + grid->valueType() + ") has no pyopenvdb type "
            "in this build: left out");
    }
    return result;
}

/// The caller's grid objects with @a results added, each in place of the first input grid of
/// its name, else after them (as the tool's output file: OutputGrids.h, withGrids()).
py::list
withResults(const InputGrids& input, const openvdb::GridPtrVec& results)
{
    std::vector<py::object> out = input.objects;
    std::vector<std::string> names;
    for (const auto& g : input.grids) names.push_back(g->getName());
    for (const openvdb::GridBase::Ptr& r : results) {
        if (!r) continue;
        py::object object = gridToPython(r);
        if (object.is_none()) continue;
        size_t i = 0;
        while (i < names.size() && names[i] != r->getName()) ++i;
        if (i == names.size()) {
            out.push_back(object);
            names.push_back(r->getName());
        } else {
            out[i] = object;
        }
    }
    py::list list;
    for (const py::object& o : out) list.append(o);
    return list;
}

py::list
toList(const openvdb::GridPtrVec& grids)
{
    py::list list;
    for (const openvdb::GridBase::Ptr& g : grids) {
        py::object object = gridToPython(g);
        if (!object.is_none()) list.append(object);
    }
    return list;
}

// ---- cancellation ------------------------------------------------------------------------------

/// @brief The library's interrupter, driven by Python's signal handling.
/// @details While the library works without the GIL, SIGINT only trips Python's flag. So the
/// thread that called into the module, if it is Python's main thread (the one signals are
/// handled on), takes the GIL now and then to let Python run the handler (PyErr_CheckSignals).
/// If the handler raises (KeyboardInterrupt for SIGINT), its error is kept and every thread
/// is told to stop; the library unwinds with vdbrad::Cancelled, and raise() re-raises it.
/// TBB's worker threads only read the flag: they never touch Python.
class PythonInterrupter final : public openvdb::util::NullInterrupter
{
public:
    /// Constructed with the GIL held, on the calling thread.
    PythonInterrupter()
        : mCaller(std::this_thread::get_id())
    {
        const py::module_ threading = py::module_::import("threading");
        mChecks = threading.attr("current_thread")().is(threading.attr("main_thread")());
    }

    bool wasInterrupted(int = -1) override
    {
        if (mStop.load(std::memory_order_relaxed)) return true;
        if (!mChecks || std::this_thread::get_id() != mCaller) return false;
        // The GIL may be busy with other Python threads: ask at most every 20 ms.
        const auto now = std::chrono::steady_clock::now();
        if (now - mLastCheck < std::chrono::milliseconds(20)) return false;
        mLastCheck = now;
        py::gil_scoped_acquire gil;
        if (PyErr_CheckSignals() == 0) return false;
        mError = std::make_unique<py::error_already_set>();   // fetches the handler's error
        mStop.store(true);
        return true;
    }

    /// Whether a signal handler raised (the work may still have finished before it stopped).
    bool signalled() const { return bool(mError); }

    /// Raise what the signal handler raised (KeyboardInterrupt where it raised nothing we saw).
    [[noreturn]] void raise()
    {
        if (mError) throw py::error_already_set(*mError);
        PyErr_SetNone(PyExc_KeyboardInterrupt);
        throw py::error_already_set();
    }

private:
    const std::thread::id mCaller;
    bool mChecks = false;
    std::chrono::steady_clock::time_point mLastCheck{};
    std::atomic<bool> mStop{false};
    std::unique_ptr<py::error_already_set> mError;
};

/// Runs @a work(interrupter) without the GIL; a cancelled run raises what Python's signal
/// handler raised. @a threads > 0 limits TBB's threads meanwhile (the results do not depend on it).
template<typename WorkT>
auto
runReleased(int threads, WorkT&& work)
{
    if (threads < 0) throw py::value_error("threads must be >= 0 (0: all cores)");
    const std::unique_ptr<tbb::global_control> limit = threads == 0 ? nullptr
        : std::make_unique<tbb::global_control>(
            tbb::global_control::max_allowed_parallelism, size_t(threads));
    PythonInterrupter interrupter;
    try {
        auto result = [&] {
            py::gil_scoped_release release;
            return work(&interrupter);
        }();
        // Work that finished without asking again still must not swallow the Ctrl-C.
        if (interrupter.signalled()) interrupter.raise();
        return result;
    } catch (const Cancelled&) {
        interrupter.raise();
    }
}

int
workerThreads()
{
    return int(tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism));
}

// ---- options -----------------------------------------------------------------------------------

/// @a word of the keyword @a option, mapped through @a values. @throw ValueError naming them
template<typename T>
T
choice(const char* option, const std::string& word,
    std::initializer_list<std::pair<const char*, T>> values)
{
    std::string names;
    for (const auto& [name, value] : values) {
        if (word == name) return value;
        names += (names.empty() ? "" : ", ") + std::string(name);
    }
    throw py::value_error(std::string(option) + " must be one of " + names + ", got '" + word
        + "'");
}

SceneOptions
sceneOptions(const std::string& surface, float albedo, int separation, float roughness)
{
    SceneOptions o;
    o.surface = surface;
    o.defaultAlbedo = albedo;
    o.separation = choice<int>("separation", std::to_string(separation), {{"26", 26}, {"6", 6}});
    o.defaultRoughness = roughness;
    return o;
}

bool
isAuto(const py::object& value)
{
    return value.is_none()
        || (py::isinstance<py::str>(value) && value.cast<std::string>() == "auto");
}

/// The number of bytes @a value (a Python or NumPy number), > 0 or, if @a zero, >= 0.
double
bytes(const char* option, const py::object& value, bool zero)
{
    const double v = !py::isinstance<py::str>(value) && PyNumber_Check(value.ptr())
        ? value.cast<double>() : -1.0;
    if (!(v > 0.0 || (zero && v == 0.0)) || !std::isfinite(v)) {
        throw py::value_error(std::string(option) + " must be " + (zero ? "'auto' or " : "None or ")
            + "a number of bytes" + (zero ? " (0: none)" : " > 0"));
    }
    return v;
}

/// max_memory: bytes, or None for 3/4 of physical memory (the tool's --max-memory).
double
memoryLimit(const py::object& maxMemory)
{
    if (maxMemory.is_none()) {
        const double physical = physicalMemory();
        return physical > 0.0 ? 0.75 * physical : 1e300;
    }
    return bytes("max_memory", maxMemory, false);
}

/// A solve refused before it allocates; raised as MemoryError.
class MemoryLimitError : public std::runtime_error
{
public:
    using std::runtime_error::runtime_error;
};

/// @throw MemoryLimitError where @a held now plus @a solver's arrays exceed @a limit.
void
checkMemory(double limit, double held, double solver)
{
    const double peak = held + solver;
    if (peak <= limit) return;
    throw MemoryLimitError("the solve needs about " + formatBytes(peak) + " of memory, over the "
        + formatBytes(limit) + " allowed (max_memory; fewer voxels or directions, or no "
        "accelerate, need less)");
}

/// How a solve stopped (SolveControl::stopped, called without the GIL).
struct Outcome
{
    bool converged = true;
    double residual = 0.0;
};

SolveControl
recording(Outcome& outcome)
{
    SolveControl control;
    control.stopped = [&outcome](int, double residual, bool converged) {
        outcome.converged = converged;
        outcome.residual = residual;
    };
    return control;
}

void
warnUnconverged(const Outcome& outcome, int iterations)
{
    if (outcome.converged) return;
    std::ostringstream os;
    os << "stopped at iterations=" << iterations << " with residual " << outcome.residual
       << " > tolerance";
    warn(os.str());
}

// ---- solve -------------------------------------------------------------------------------------

py::list
solve(const py::object& gridsIn, int directions, int iterations, double tolerance,
    float albedo, const std::string& surface, int separation, float roughness,
    const std::string& update, const std::string& method, int samples, int gather,
    const std::string& lines, float occlusionDepth, const std::string& precision,
    const py::object& visibilityCache, const std::string& direct, int directSamples,
    const std::string& brdf, int controlPoints, int harmonics, const std::string& glossyRotation,
    const std::string& accelerate, int andersonDepth, int threads, const py::object& maxMemory)
{
    const InputGrids input(gridsIn);
    const SceneOptions sceneOpts = sceneOptions(surface, albedo, separation, roughness);
    RadiosityOptions o;
    o.ranks = job().get();
    o.directions = directions;
    o.maxIterations = iterations;
    o.tolerance = tolerance;
    o.occlusionDepth = occlusionDepth;
    choice<int>("method", method, {{"sweep", 0}, {"raycast", 1}, {"montecarlo", 2}});
    o.visibility = method == "raycast" ? Visibility::RayCast : Visibility::Sweep;
    o.update = choice<UpdateScheme>("update", update, {{"jacobi", UpdateScheme::Jacobi},
        {"inplace", UpdateScheme::InPlace}, {"progressive", UpdateScheme::Progressive}});
    o.lines = choice<LineType>("lines", lines,
        {{"naive", LineType::Naive}, {"standard", LineType::Standard}});
    o.precision = precisionFromString(precision);
    o.accelerate = accelerationFromString(accelerate);
    o.andersonDepth = andersonDepth;
    o.direct = choice<DirectMode>("direct", direct, {{"auto", DirectMode::Auto},
        {"exact", DirectMode::Exact}, {"sweep", DirectMode::Sweep}});
    o.directSamples = directSamples;
    o.glossy.model = brdfModelFromName(brdf);
    o.glossy.controlPoints = choice<int>("control_points", std::to_string(controlPoints),
        {{"12", 12}, {"42", 42}, {"162", 162}, {"642", 642}, {"2562", 2562}});
    if (harmonics < 0) throw py::value_error("harmonics must be >= 0 (0: control points)");
    if (harmonics > 0) {
        o.glossy.basis = GlossyBasis::Harmonics;
        o.glossy.harmonicOrder = harmonics;
    }
    o.glossy.rotation = choice<ControlPoints::RotationKind>("glossy_rotation", glossyRotation,
        {{"resampled", ControlPoints::RotationKind::Resampled},
            {"continuous", ControlPoints::RotationKind::Continuous},
            {"permutation", ControlPoints::RotationKind::Permutation}});
    if (o.accelerate != Acceleration::None && o.update == UpdateScheme::Progressive) {
        throw py::value_error("accelerate needs update='jacobi' or 'inplace', not progressive");
    }
    if (method == "montecarlo" && o.accelerate != Acceleration::None) {
        throw py::value_error("accelerate does not apply to method='montecarlo'");
    }
    if (gather != 0 && method != "montecarlo") {
        throw py::value_error("gather applies only to method='montecarlo'");
    }
    // None or "auto": half of what max_memory leaves once the solve has the rest.
    std::optional<size_t> cache;
    if (!isAuto(visibilityCache)) cache = size_t(std::min(bytes("visibility_cache",
        visibilityCache, true), 1e18));
    MonteCarloOptions mc;
    mc.samples = samples;
    mc.maxIterations = iterations;
    mc.tolerance = tolerance;
    mc.gather = gather;
    const double limit = memoryLimit(maxMemory);

    Outcome outcome;
    std::vector<std::string> warnings;
    const openvdb::GridPtrVec results = runReleased(threads, [&](PythonInterrupter* interrupt) {
        Scene scene = buildScene(input.grids, sceneOpts, interrupt);
        if (!scene.hasEmission()) warnings.push_back("nothing emits: the scene is dark");
        if (scene.raisedRoughness() > 0) {
            warnings.push_back(std::to_string(scene.raisedRoughness()) + " glossy voxels have "
                "a roughness below 0.1, raised to 0.1 (control points resolve no sharper lobe)");
        }
        if (scene.isGlossy() && method != "sweep") {
            throw openvdb::ValueError("glossy surfaces (a `specular` grid) are solved by the "
                "line sweeps only (method='sweep')");
        }
        if (scene.isGlossy() && o.update == UpdateScheme::Progressive) {
            throw openvdb::ValueError("glossy surfaces need update='inplace' or 'jacobi'");
        }
        if (scene.isGlossy() && o.accelerate != Acceleration::None) {
            warnings.push_back("glossy surfaces are not Anderson-accelerated: solving without it");
            o.accelerate = Acceleration::None;
        }
        if (method == "montecarlo") {
            return solveMonteCarlo(scene, mc, interrupt, recording(outcome));
        }
        const double held = residentBytes();
        o.visibilityCache = cache ? *cache
            : RadiositySolver::visibilityCacheFor(scene, o, workerThreads(), limit - held);
        checkMemory(limit, held, double(RadiositySolver::memoryEstimate(scene, o,
            workerThreads())));
        openvdb::GridBase::Ptr specular;
        openvdb::GridBase::Ptr radiosity = solveRadiosity(std::move(scene), o, interrupt,
            recording(outcome), &specular);
        return openvdb::GridPtrVec{radiosity, specular};
    });
    for (const std::string& w : warnings) warn(w);
    warnUnconverged(outcome, iterations);
    return withResults(input, results);
}

// ---- solve_cloud -------------------------------------------------------------------------------

/// None or "auto" (nullopt), else the integer @a value of keyword @a option.
std::optional<int>
autoOr(const char* option, const py::object& value)
{
    if (isAuto(value)) return std::nullopt;
    if (!py::isinstance<py::int_>(value)) {
        throw py::type_error(std::string(option) + " must be 'auto' or an int");
    }
    return value.cast<int>();
}

py::list
solveCloudGrids(const py::object& gridsIn, const std::pair<double, double>& sun,
    const std::string& up, bool periodic, const py::object& minPeriod, float albedo, double g,
    const std::optional<std::vector<double>>& legendre, const py::object& phaseOrder,
    const std::string& voxelSource, const std::string& weights, const std::string& density,
    float extinctionScale, const std::string& emission, float emissionScale,
    const std::array<float, 3>& emissionColour, double irradiance, const std::optional<double>& groundAlbedo,
    float surfaceAlbedo, bool noSurfaces, const py::object& directions, int iterations,
    double tolerance, const std::string& accelerate, int andersonDepth, int threads,
    const py::object& maxMemory, const std::string& outputName)
{
    const InputGrids input(gridsIn);
    CloudOptions cloudOpts;
    cloudOpts.extinctionScale = extinctionScale;
    cloudOpts.defaultAlbedo = albedo;
    cloudOpts.density = density;
    cloudOpts.emission = emission;
    cloudOpts.emissionScale = emissionScale;
    cloudOpts.emissionColour = openvdb::Vec3f(emissionColour[0], emissionColour[1],
        emissionColour[2]);
    CloudTransferOptions o;
    o.ranks = job().get();
    o.sunZenith = sun.first;
    o.sunAzimuth = sun.second;
    if (!(o.sunZenith >= 0.0 && o.sunZenith <= 89.9)) {
        throw py::value_error("sun: the zenith angle must be in [0, 89.9] degrees");
    }
    o.up = choice<int>("up", up, {{"x", 0}, {"y", 1}, {"z", 2}});
    o.periodic = periodic;
    if (const auto v = autoOr("min_period", minPeriod)) {
        if (!periodic) throw py::value_error("min_period applies to periodic boxes only");
        o.minPeriod = *v;
    }
    if (const auto v = autoOr("directions", directions)) o.directions = *v;
    o.maxIterations = iterations;
    o.tolerance = tolerance;
    o.irradiance = irradiance;
    if (outputName.empty()) throw py::value_error("output_name must not be empty");
    if (legendre) {
        if (g != 0.0) throw py::value_error("give g or legendre, not both");
        o.phase = PhaseFunction::legendre(*legendre);
    } else {
        o.phase = PhaseFunction::henyeyGreenstein(g);
    }
    if (const auto v = autoOr("phase_order", phaseOrder)) o.phaseOrder = *v;
    if (accelerate != "auto") o.accelerate = accelerationFromString(accelerate);
    o.andersonDepth = andersonDepth;
    o.source = choice<VoxelSource>("voxel_source", voxelSource,
        {{"constant", VoxelSource::Constant}, {"linear", VoxelSource::Linear}});
    o.harmonicWeights = choice<bool>("weights", weights, {{"harmonic", true}, {"cells", false}});
    o.groundAlbedo = groundAlbedo;
    const double limit = memoryLimit(maxMemory);

    Outcome outcome;
    std::string lost;   // said once the GIL is back
    const openvdb::GridPtrVec results = runReleased(threads, [&](PythonInterrupter* interrupt) {
        // A surface scene among the grids is solved with the fog (as `vdbrad solve-cloud`);
        // its `albedo` grid is then the surfaces', not the fog's.
        const bool hasSurface = bool(identifyRoles(input.grids, "", density).surface);
        const bool withSurfaces = hasSurface && !noSurfaces;
        cloudOpts.albedoGrid = !hasSurface;
        Scene scene;
        if (withSurfaces) {
            if (o.periodic || o.groundAlbedo) {
                throw openvdb::ValueError("grids with surfaces are solved in an open box "
                    "without ground_albedo (give the ground as surface voxels; or "
                    "no_surfaces=True)");
            }
            SceneOptions sceneOpts;
            sceneOpts.defaultAlbedo = surfaceAlbedo;
            scene = buildScene(input.grids, sceneOpts, interrupt);
            o.surfaces = &scene;
        }
        const Cloud cloud = buildCloud(input.grids, cloudOpts, interrupt);
        if (cloud.lostEmitters() > 0) {
            lost = std::to_string(cloud.lostEmitters()) + " voxels of '" + cloud.emissionName()
                + "' emit where '" + cloud.densityName() + "' is 0 or inactive: the medium "
                "emits through its extinction, so they add no light";
        }
        checkMemory(limit, residentBytes(),
            double(CloudTransfer::memoryEstimate(cloud, o, workerThreads())));
        openvdb::FloatGrid::Ptr ground;
        openvdb::GridBase::Ptr radiosity;
        openvdb::GridBase::Ptr intensity = solveCloud(cloud, o, interrupt, recording(outcome),
            &ground, &radiosity);
        intensity->setName(outputName);
        recordEmission(*intensity, cloud, cloudOpts);
        return openvdb::GridPtrVec{intensity, ground, radiosity};
    });
    if (!lost.empty()) warn(lost);
    warnUnconverged(outcome, iterations);
    return withResults(input, results);
}

// ---- voxelize ----------------------------------------------------------------------------------

py::list
voxelize(const std::string& path, const std::optional<int>& res,
    const std::optional<double>& voxelSize, int separation, float albedo, bool keepSdf,
    bool specular)
{
    VoxelizeOptions o;
    if (voxelSize) {
        if (res) throw py::value_error("give voxel_size or res, not both");
        o.voxelSize = *voxelSize;
    }
    o.resolution = res.value_or(128);
    o.separation = choice<int>("separation", std::to_string(separation), {{"26", 26}, {"6", 6}});
    o.defaultAlbedo = albedo;
    o.keepSdf = keepSdf;
    o.specular = specular;
    std::vector<std::string> warnings;
    const openvdb::GridPtrVec grids = runReleased(0, [&](PythonInterrupter* interrupt) {
        const TriangleMesh mesh = readMesh(path);
        warnings = mesh.warnings;
        for (const Material& m : mesh.materials) {
            if (o.specular && m.reflectance() > 1.f) {
                std::ostringstream os;
                os.precision(4);
                os << path << ": material '" << m.name << "': Kd + Ks = " << m.reflectance()
                   << " > 1, both scaled by 1/" << m.reflectance() << " (a surface reflects no "
                   << "more light than it receives; specular=False: Kd alone)";
                warnings.push_back(os.str());
            }
        }
        std::vector<std::string> voxelWarnings;
        openvdb::GridPtrVec result = voxelizeMesh(mesh, o, interrupt, &voxelWarnings);
        for (const std::string& w : voxelWarnings) warnings.push_back(path + ": " + w);
        if (!findGrid(result, names::kEmission)) {
            warnings.push_back(path + ": nothing emits (no MTL material with Ke > 0): the "
                "scene will be dark");
        }
        return result;
    });
    for (const std::string& w : warnings) warn(w);
    return toList(grids);
}

// ---- render ------------------------------------------------------------------------------------

openvdb::Vec3d
vec3(const py::handle& v, const char* what)
{
    const auto xyz = v.cast<std::vector<double>>();
    if (xyz.size() != 3) throw py::value_error(std::string("camera: ") + what + " needs 3 numbers");
    return openvdb::Vec3d(xyz[0], xyz[1], xyz[2]);
}

/// (eye, target, up, fov) or the tool's ten numbers eye x,y,z, target x,y,z, up x,y,z, fov.
Camera
cameraFrom(const py::sequence& c)
{
    Camera cam;
    if (c.size() == 10) {
        const auto v = c.cast<std::vector<double>>();
        cam.eye = openvdb::Vec3d(v[0], v[1], v[2]);
        cam.target = openvdb::Vec3d(v[3], v[4], v[5]);
        cam.up = openvdb::Vec3d(v[6], v[7], v[8]);
        cam.fov = v[9];
    } else if (c.size() == 4) {
        cam.eye = vec3(c[0], "eye");
        cam.target = vec3(c[1], "target");
        cam.up = vec3(c[2], "up");
        cam.fov = c[3].cast<double>();
    } else {
        throw py::value_error("camera must be (eye, target, up, fov) or ten numbers");
    }
    if (!(cam.fov > 0.0 && cam.fov < 180.0)) {
        throw py::value_error("camera: the field of view must be in (0, 180) degrees");
    }
    return cam;
}

py::array_t<float>
render(const py::object& gridsIn, int width, int height, const std::optional<py::sequence>& camera,
    int aa, int gather, int directSamples, int glossyRays,
    const std::tuple<float, float, float>& background, const std::string& surface, float albedo,
    int separation, float roughness, const std::string& density, float extinctionScale,
    const std::string& cloudSource, const std::optional<std::string>& mesh)
{
    const InputGrids input(gridsIn);
    RenderOptions o;
    o.scene = sceneOptions(surface, albedo, separation, roughness);
    if (width < 1 || height < 1 || width > 16384 || height > 16384) {
        throw py::value_error("width and height must be in [1, 16384]");
    }
    o.width = width;
    o.height = height;
    if (camera) o.camera = cameraFrom(*camera);
    o.background = openvdb::Vec3f(std::get<0>(background), std::get<1>(background),
        std::get<2>(background));
    o.samplesPerPixel = aa;
    o.gather = gather;
    o.directSamples = directSamples;
    o.glossyRays = glossyRays;
    o.cloud.extinctionScale = extinctionScale;
    o.cloud.density = density;
    o.cloudSource = cloudSource;
    const Image image = runReleased(0, [&](PythonInterrupter* interrupt) {
        if (mesh) o.mesh = std::make_shared<const TriangleMesh>(readMesh(*mesh));
        return renderImage(input.grids, o, interrupt);
    });
    for (const std::string& w : image.warnings) warn(w);
    // Rows top first, pixels of three floats: the image's own layout.
    py::array_t<float> pixels({py::ssize_t(image.height), py::ssize_t(image.width),
        py::ssize_t(3)});
    static_assert(sizeof(openvdb::Vec3f) == 3 * sizeof(float), "Vec3f is three packed floats");
    std::memcpy(pixels.mutable_data(), image.pixels.data(), image.pixels.size() * sizeof(float) * 3);
    return pixels;
}

// ---- errors ------------------------------------------------------------------------------------

/// The library's exceptions as Python's, with the library's message (errorMessage(): without
/// OpenVDB's "ValueError: " prefix).
void
translate(std::exception_ptr error)
{
    try {
        if (error) std::rethrow_exception(error);
    } catch (const Cancelled& e) {   // cancelled with no Python error (not a signal of ours)
        PyErr_SetString(PyExc_KeyboardInterrupt, errorMessage(e).c_str());
    } catch (const openvdb::ValueError& e) {
        PyErr_SetString(PyExc_ValueError, errorMessage(e).c_str());
    } catch (const openvdb::TypeError& e) {
        PyErr_SetString(PyExc_TypeError, errorMessage(e).c_str());
    } catch (const openvdb::KeyError& e) {
        PyErr_SetString(PyExc_KeyError, errorMessage(e).c_str());
    } catch (const openvdb::IoError& e) {   // CheckpointError too
        PyErr_SetString(PyExc_OSError, errorMessage(e).c_str());
    } catch (const openvdb::Exception& e) {
        PyErr_SetString(PyExc_RuntimeError, errorMessage(e).c_str());
    } catch (const MemoryLimitError& e) {
        PyErr_SetString(PyExc_MemoryError, e.what());
    }
}

} // namespace
} // namespace python
} // namespace vdbrad

PYBIND11_MODULE(vdbrad, m)
{
    using namespace vdbrad::python;
    // pyopenvdb registers the grid converters this module crosses grids with.
    py::module_::import("pyopenvdb");
    openvdb::initialize();
    // On the main thread, before any other runs (Distribution.h).
    job() = vdbrad::Distribution::join();
    py::register_exception_translator(&translate);

    m.doc() = "vdbrad: voxel radiosity on OpenVDB grids (pyopenvdb in, pyopenvdb and NumPy out). "
        "Keyword arguments mirror the vdbrad tool's options ('-' spelt '_'); see "
        "`vdbrad help COMMAND`.";
    m.attr("__version__") = VDBRAD_VERSION_STRING;

    m.def("solve", &solve, py::arg("grids"), py::kw_only(),
        "directions"_a = 300, "iterations"_a = 200, "tolerance"_a = 1e-5, "albedo"_a = 0.5f,
        "surface"_a = "", "separation"_a = 26, "roughness"_a = 0.5f, "update"_a = "inplace",
        "method"_a = "sweep", "samples"_a = 256, "gather"_a = 0, "lines"_a = "naive",
        "occlusion_depth"_a = 1.f, "precision"_a = "auto", "visibility_cache"_a = "auto",
        "direct"_a = "auto", "direct_samples"_a = 16, "brdf"_a = "phong",
        "control_points"_a = 162, "harmonics"_a = 0, "glossy_rotation"_a = "resampled",
        "accelerate"_a = "none", "anderson_depth"_a = 16, "threads"_a = 0,
        "max_memory"_a = py::none(),
        R"(Solve the radiosity of a surface scene (`vdbrad solve`).

grids: pyopenvdb grids following the scene contract (a level set or a `normal` grid, optional
`albedo`, `emission`, `specular`, `roughness`). Returns a new list: the same grid objects, with
the `radiosity` grid (and `specular_radiosity` for glossy scenes) in place of any grid of that
name, else appended, as `vdbrad solve` writes its output file. The input grids are not changed.
visibility_cache: bytes, or 'auto' (half of what max_memory leaves); max_memory: bytes, None for
3/4 of physical memory (MemoryError beyond). Ctrl-C raises KeyboardInterrupt.)");

    m.def("solve_cloud", &solveCloudGrids, py::arg("grids"), py::kw_only(),
        "sun"_a = std::make_pair(0.0, 0.0), "up"_a = "y", "periodic"_a = false,
        "min_period"_a = "auto", "albedo"_a = 1.f, "g"_a = 0.0, "legendre"_a = py::none(),
        "phase_order"_a = "auto", "voxel_source"_a = "linear", "weights"_a = "harmonic",
        "density"_a = "density", "extinction_scale"_a = 1.f, "emission"_a = "",
        "emission_scale"_a = 1.f,
        "emission_color"_a = std::array<float, 3>{1.f, 1.f, 1.f}, "irradiance"_a = 1.0,
        "ground_albedo"_a = py::none(), "surface_albedo"_a = 0.5f, "no_surfaces"_a = false,
        "directions"_a = "auto", "iterations"_a = 1000, "tolerance"_a = 1e-6,
        "accelerate"_a = "auto", "anderson_depth"_a = 16, "threads"_a = 0,
        "max_memory"_a = py::none(), "output_name"_a = "mean_intensity",
        R"(Solve the light in a fog volume (`density` grid) lit by the sun (`vdbrad solve-cloud`),
with the surfaces of a scene among the same grids.

sun: (zenith, azimuth) in degrees. emission: the fire's grid ('' : `flame` if there is one),
emitting value x emission_scale x emission_color per world unit of path. Returns the grids with `mean_intensity` (output_name), and
`ground_irradiance` with ground_albedo, `radiosity` with surfaces, as for solve().)");

    m.def("voxelize", &voxelize, py::arg("path"), py::kw_only(), "res"_a = py::none(),
        "voxel_size"_a = py::none(), "separation"_a = 26, "albedo"_a = 0.5f,
        "keep_sdf"_a = false, "specular"_a = true,
        R"(Voxelize an OBJ (with MTL) or PLY mesh into a surface scene (`vdbrad voxelize`).

res: voxels along the mesh's longest axis (default 128), or voxel_size in world units. Returns
a list of pyopenvdb grids: `normal`, and `albedo`, `emission`, ... as the mesh has them (grids
of a type this pyopenvdb lacks, e.g. Debian's int32 `material_id`, are left out with a warning).)");

    m.def("render", &render, py::arg("grids"), py::kw_only(), "width"_a = 640,
        "height"_a = 480, "camera"_a = py::none(), "aa"_a = 1, "gather"_a = 0,
        "direct_samples"_a = 16, "glossy_rays"_a = 32,
        "background"_a = std::make_tuple(0.f, 0.f, 0.f), "surface"_a = "", "albedo"_a = 0.5f,
        "separation"_a = 26, "roughness"_a = 0.5f, "density"_a = "density",
        "extinction_scale"_a = 1.f, "cloud_source"_a = "mean_intensity", "mesh"_a = py::none(),
        R"(Render solved grids (`vdbrad render`): a NumPy float32 array (height, width, 3) of linear
RGB radiosity, top row first (an emitter of emission 1 shows as 1.0).

camera: (eye, target, up, fov) or ten numbers as the tool's --camera; None frames the scene from
-z. mesh: the OBJ or PLY path the scene was voxelized from, drawn with exact outlines.)");
}
