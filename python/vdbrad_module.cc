// The Python module `vdbrad`: the library's one-call functions on pyopenvdb grids.
//
//     import pyopenvdb, vdbrad
//     grids, _ = pyopenvdb.readAll("cornell.vdb")
//     lit = vdbrad.solve(grids, directions=1000)      # grids + `radiosity`
//     image = vdbrad.render(lit, res=(640, 480))   # numpy float32 (480, 640, 3)
//
// Keyword arguments are the library's option tables (vdbrad/request/), the same the tool reads,
// '-' spelt '_': each function's signature and docstring are generated from them, the values
// read and checked by the library's Request (requestFrom()); errors are Python exceptions
// carrying the library's messages; warnings the tool prints go to Python's `warnings`.
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
/// handler raised. @a limit, if any, holds TBB's threads meanwhile (the results do not depend
/// on it).
template<typename WorkT>
auto
runReleased(std::unique_ptr<tbb::global_control> limit, WorkT&& work)
{
    (void)limit;   // held until the work is done
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

// ---- keyword arguments: the library's requests -------------------------------------------------
//
// Each function's keyword arguments are the options the library declares for its command
// (vdbrad/request/: the same table the tool's options, help and docs come from), '-' spelt '_'.
// Values cross as the text the tool would read (numbers as Python's repr, which reads back
// exactly; sequences comma-separated), so the library checks and reads them once for both.

std::string
keyword(const std::string& option)
{
    std::string s = option;
    for (char& c : s) {
        if (c == '-') c = '_';
    }
    return s;
}

std::string
pythonText(py::handle value)
{
    if (py::isinstance<py::str>(value)) return value.cast<std::string>();
    if (PyBool_Check(value.ptr())) throw py::type_error("a bool");
    if (PyIndex_Check(value.ptr())) return py::str(py::int_(py::reinterpret_borrow<py::object>(value)));
    if (PyNumber_Check(value.ptr())) {
        return py::repr(py::float_(py::reinterpret_borrow<py::object>(value)));
    }
    if (py::isinstance<py::iterable>(value)) {
        std::string s;
        for (py::handle item : value) s += (s.empty() ? "" : ",") + pythonText(item);
        return s;
    }
    throw py::type_error(typeName(value));
}

/// The request of @a command from @a kwargs; @a own: keywords the function reads itself.
/// @throw TypeError for an unknown keyword or a value of no option's type
Request
requestFrom(const std::string& command, const std::vector<OptionSpec>& options,
    const py::kwargs& kwargs, const std::vector<std::string>& own = {})
{
    Request request(command, options, Spelling::Python);
    std::vector<std::string> names = own;
    for (const OptionSpec& o : options) names.push_back(keyword(o.name));
    for (const auto& [key, value] : kwargs) {
        const std::string name = key.cast<std::string>();
        if (std::find(own.begin(), own.end(), name) != own.end()) continue;
        std::string option = name;
        for (char& c : option) {
            if (c == '_') c = '-';
        }
        const OptionSpec* spec = request.find(option);
        if (!spec || name.find('-') != std::string::npos) {
            std::string msg = keyword(command) + "() got an unexpected keyword argument '" + name
                + "'";
            if (auto s = suggest(name, names)) msg += "; did you mean '" + *s + "'?";
            throw py::type_error(msg);
        }
        if (value.is_none()) continue;   // the default
        if (spec->type == OptionType::Flag) {
            if (!PyBool_Check(value.ptr())) {
                throw py::type_error(name + " must be True or False, got " + typeName(value));
            }
            if (value.cast<bool>()) request.set(option, "");
            continue;
        }
        std::string text;
        try {
            text = pythonText(value);
        } catch (const py::type_error& e) {
            throw py::type_error(name + " must be a number, a str or a sequence of numbers, got "
                + std::string(e.what()));
        }
        request.set(option, text);
    }
    return request;
}

/// A Python literal for the default of @a o (None where the default describes what happens).
std::string
pythonDefault(const OptionSpec& o)
{
    if (o.type == OptionType::Flag) return "False";
    if (o.describedDefault || o.defaultValue.empty()) return "None";
    if (o.type != OptionType::String) return o.defaultValue;
    return "'" + o.defaultValue + "'";
}

/// @brief The docstring of @a function: its signature as inspect.signature() reads it, then
/// @a summary, then each keyword's help from the library's table.
std::string
docstring(const std::string& function, const std::string& leading,
    const std::vector<std::string>& own, const std::vector<OptionSpec>& options,
    const std::string& summary)
{
    std::string sig = function + "(" + leading + ", *";
    for (const std::string& k : own) sig += ", " + k + "=None";
    for (const OptionSpec& o : options) sig += ", " + keyword(o.name) + "=" + pythonDefault(o);
    std::ostringstream doc;
    doc << sig << ")\n--\n\n" << summary << "\n\nKeyword arguments (the tool's options, '-' spelt "
        "'_'; None: the default):\n";
    for (const OptionSpec& o : options) {
        doc << "  " << keyword(o.name) << ": " << o.doc;
        std::string notes = o.validValues();
        if (!o.defaultValue.empty()) {
            notes += (notes.empty() ? "" : "; ") + std::string("default ") + o.defaultValue;
        }
        if (!notes.empty()) doc << " (" << notes << ")";
        doc << "\n";
    }
    return doc.str();
}

/// Say @a result's warnings, and that it stopped short of the tolerance.
void
warnAll(const SolveResult& result, const Request& request)
{
    for (const std::string& w : result.warnings) warn(w);
    if (!result.converged) warn(stoppedShort(result, request));
}

/// The checkpoint of a finished solve has served (as the tool removes it once the output is
/// written).
void
removeCheckpoint(const Request& request)
{
    if (request.has("checkpoint")) std::remove(request.getString("checkpoint").c_str());
}

// ---- solve, solve_cloud ------------------------------------------------------------------------

/// A solve (SurfaceSolve, CloudSolve) of @a command on the caller's grids.
template<typename SolveT>
py::list
solveGrids(const std::string& command, const std::vector<OptionSpec>& options,
    const py::object& gridsIn, const py::kwargs& kwargs)
{
    const InputGrids input(gridsIn);
    const Request request = requestFrom(command, options, kwargs);
    SolveT solve(request, job().get());
    const SolveResult result = runReleased(threadLimit(request), [&](PythonInterrupter* i) {
        return runSteps(solve, input.grids, i, SolveControl());
    });
    warnAll(result, request);
    removeCheckpoint(request);
    return withResults(input, result.grids);
}

py::list
solve(const py::object& grids, const py::kwargs& kwargs)
{
    return solveGrids<SurfaceSolve>("solve", surfaceSolveOptions(), grids, kwargs);
}

py::list
solveCloudGrids(const py::object& grids, const py::kwargs& kwargs)
{
    return solveGrids<CloudSolve>("solve-cloud", cloudSolveOptions(), grids, kwargs);
}

// ---- voxelize ----------------------------------------------------------------------------------

py::list
voxelize(const std::string& path, const py::kwargs& kwargs)
{
    const Request request = requestFrom("voxelize", voxelizeMeshOptions(), kwargs);
    const VoxelizeOptions o = voxelizeOptions(request);
    std::vector<std::string> warnings;
    const openvdb::GridPtrVec grids = runReleased(nullptr, [&](PythonInterrupter* interrupt) {
        const TriangleMesh mesh = readMesh(path);
        warnings = meshWarnings(mesh, path, o, request);
        std::vector<std::string> voxelWarnings;
        openvdb::GridPtrVec result = voxelizeMesh(mesh, o, interrupt, &voxelWarnings);
        for (const std::string& w : voxelWarnings) warnings.push_back(path + ": " + w);
        for (const std::string& w : sceneWarnings(result, path)) warnings.push_back(w);
        return result;
    });
    for (const std::string& w : warnings) warn(w);
    return toList(grids);
}

// ---- render ------------------------------------------------------------------------------------

/// @a bytes to the file @a path whole: written beside it, then renamed over it.
void
writeFile(const std::string& bytes, const std::string& path)
{
    const std::string part = path + ".part";
    {
        std::ofstream file(part, std::ios::binary);
        file.write(bytes.data(), std::streamsize(bytes.size()));
        file.close();
        if (!file) {
            std::remove(part.c_str());
            throw py::value_error("cannot write '" + path + "'");
        }
    }
    if (std::rename(part.c_str(), path.c_str()) != 0) {
        std::remove(part.c_str());
        throw py::value_error("cannot write '" + path + "'");
    }
}

py::array_t<float>
render(const py::object& gridsIn, const py::kwargs& kwargs)
{
    const InputGrids input(gridsIn);
    const Request request = requestFrom("render", renderImageOptions(), kwargs, {"exr"});
    RenderRequest q = readRenderRequest(request);
    std::string exr;
    if (kwargs.contains("exr") && !kwargs["exr"].is_none()) exr = kwargs["exr"].cast<std::string>();
    // The sky and sun it was solved under: the background, and the gather's light.
    std::vector<std::string> lightWarnings;
    const OutsideLight light = solvedLight(input.grids, lightWarnings);
    q.render.sky = light.sky;
    q.render.sun = light.sun;
    for (const std::string& w : lightWarnings) warn(w);
    const Image image = runReleased(nullptr, [&](PythonInterrupter* interrupt) {
        if (!q.meshPath.empty()) {
            q.render.mesh = std::make_shared<const TriangleMesh>(readMesh(q.meshPath));
        }
        return renderImage(input.grids, q.render, interrupt);
    });
    for (const std::string& w : image.warnings) warn(w);
    // Both images are encoded before either is written, so an error leaves neither behind.
    const std::string exrBytes = exr.empty() ? std::string() : encodeExr(image, q.pixel);
    const std::string pngBytes = q.png.empty() ? std::string() : encodePng(image, q.tone);
    if (!exr.empty()) writeFile(exrBytes, exr);
    if (!q.png.empty()) writeFile(pngBytes, q.png);
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
    } catch (const OptionError& e) {
        PyErr_SetString(PyExc_ValueError, e.what());
    }
}

} // namespace
} // namespace python
} // namespace vdbrad

PYBIND11_MODULE(vdbrad, m)
{
    using namespace vdbrad;
    using namespace vdbrad::python;
    // pyopenvdb registers the grid converters this module crosses grids with.
    py::module_::import("pyopenvdb");
    openvdb::initialize();
    // On the main thread, before any other runs (Distribution.h).
    job() = vdbrad::Distribution::join();
    // Under mpirun every rank must finalise MPI before it exits, or mpirun calls the job failed.
    py::module_::import("atexit").attr("register")(py::cpp_function([] {
        if (job()) job()->finalize();
    }));
    py::register_exception_translator(&translate);

    m.doc() = "vdbrad: voxel radiosity on OpenVDB grids (pyopenvdb in, pyopenvdb and NumPy out). "
        "Keyword arguments mirror the vdbrad tool's options ('-' spelt '_'); see "
        "`vdbrad help COMMAND`.";
    m.attr("__version__") = VDBRAD_VERSION_STRING;

    // Signatures and docstrings come from the library's option tables (docstring()).
    py::options options;
    options.disable_function_signatures();
    m.def("solve", &solve, py::arg("grids"), docstring("solve", "grids", {},
        surfaceSolveOptions(),
        "Solve the radiosity of a surface scene (`vdbrad solve`).\n\n"
        "grids: pyopenvdb grids following the scene contract (a level set or a `normal` grid, "
        "optional `albedo`, `emission`, `specular`, `roughness`). Returns a new list: the same "
        "grid objects, with the `radiosity` grid (and `specular_radiosity` for glossy scenes) in "
        "place of any grid of that name, else appended, as `vdbrad solve` writes its output "
        "file. The input grids are not changed. MemoryError past max_memory; Ctrl-C raises "
        "KeyboardInterrupt (a checkpoint saved so far stays to resume from).").c_str());

    m.def("solve_cloud", &solveCloudGrids, py::arg("grids"), docstring("solve_cloud", "grids",
        {}, cloudSolveOptions(),
        "Solve the light in a fog volume (`density` grid) lit by the sun (`vdbrad solve-cloud`), "
        "with the surfaces of a scene among the same grids.\n\n"
        "Returns the grids with `mean_intensity` (output_name), and `ground_irradiance` with "
        "ground_albedo, `radiosity` with surfaces, as for solve().").c_str());

    m.def("voxelize", &voxelize, py::arg("path"), docstring("voxelize", "path", {},
        voxelizeMeshOptions(),
        "Voxelize an OBJ (with MTL) or PLY mesh into a surface scene (`vdbrad voxelize`).\n\n"
        "Returns a list of pyopenvdb grids: `normal`, and `albedo`, `emission`, ... as the mesh "
        "has them (grids of a type this pyopenvdb lacks, e.g. Debian's int32 `material_id`, are "
        "left out with a warning).").c_str());

    m.def("render", &render, py::arg("grids"), docstring("render", "grids", {"exr"},
        renderImageOptions(),
        "Render solved grids (`vdbrad render`): a NumPy float32 array (height, width, 3) of "
        "linear RGB radiosity, top row first (an emitter of emission 1 shows as 1.0).\n\n"
        "exr: also write the image to this OpenEXR file (the tool's OUT.exr), png: a tone-mapped "
        "preview; both are encoded before either is written. res: 'WIDTHxHEIGHT' or (width, "
        "height); camera: ten numbers, or nested (eye, target, up, fov).").c_str());
}
