#!/usr/bin/env python3
"""Tests of the Python module `vdbrad` (python/vdbrad_module.cc) on pyopenvdb grids.

CTest runs it as `python_module` with Debian's interpreter and PYTHONPATH set to the module's
build folder:  PYTHONPATH=build/python /usr/bin/python3 python/test_vdbrad.py
"""
import math
import os
import signal
import subprocess
import sys
import tempfile
import threading
import time
import unittest
import warnings

import numpy as np
import pyopenvdb as vdb

import vdbrad


def furnace_box(n, albedo, emission):
    """grids/CanonicalGrids.h's makeFurnaceBox built with pyopenvdb: the one-voxel shell of a
    closed unit cube, n voxels a side, inward normals (edges and corners: the normalised sum of
    their faces'), uniform albedo and emission. Every voxel's radiosity is E / (1 - albedo)."""
    xform = vdb.createLinearTransform(voxelSize=1.0 / n)
    normal, albedo_grid, emission_grid = vdb.Vec3SGrid(), vdb.FloatGrid(), vdb.FloatGrid()
    normals, albedos, emissions = (g.getAccessor() for g in (normal, albedo_grid, emission_grid))
    for i in range(n):
        for j in range(n):
            on_side = i in (0, n - 1) or j in (0, n - 1)
            for k in (range(n) if on_side else (0, n - 1)):
                v = [(c == 0) - (c == n - 1) for c in (i, j, k)]
                length = math.sqrt(sum(x * x for x in v))
                normals.setValueOn((i, j, k), tuple(x / length for x in v))
                albedos.setValueOn((i, j, k), albedo)
                emissions.setValueOn((i, j, k), emission)
    for grid, name in ((normal, "normal"), (albedo_grid, "albedo"), (emission_grid, "emission")):
        grid.name = name
        grid.transform = xform
    return [normal, albedo_grid, emission_grid]


def active_values(grid):
    return np.array([item.value for item in grid.citerOnValues()])


class Furnace(unittest.TestCase):
    """A closed box whose every wall emits E = 1 with albedo 0.5: radiosity 2 everywhere."""

    @classmethod
    def setUpClass(cls):
        cls.n = 16
        cls.grids = furnace_box(cls.n, 0.5, 1.0)
        cls.lit = vdbrad.solve(cls.grids, directions=300, tolerance=1e-6)

    def test_solve_returns_the_inputs_and_radiosity(self):
        self.assertEqual([g.name for g in self.lit], ["normal", "albedo", "emission", "radiosity"])
        for out, given in zip(self.lit, self.grids):
            self.assertIs(out, given)
        radiosity = self.lit[3]
        self.assertIsInstance(radiosity, vdb.FloatGrid)
        self.assertEqual(radiosity.activeVoxelCount(), self.grids[0].activeVoxelCount())
        self.assertGreater(radiosity["vdbrad:iterations"], 0)
        self.assertEqual(radiosity["vdbrad:voxels"], self.n ** 3 - (self.n - 2) ** 3)

    def test_radiosity_is_e_over_one_minus_albedo(self):
        b = active_values(self.lit[3])
        self.assertEqual(len(b), self.n ** 3 - (self.n - 2) ** 3)
        self.assertLess(np.max(np.abs(b - 2.0)) / 2.0, 1e-5)

    def test_solving_again_replaces_radiosity(self):
        again = vdbrad.solve(self.lit, directions=100)
        self.assertEqual([g.name for g in again], ["normal", "albedo", "emission", "radiosity"])
        self.assertIsNot(again[3], self.lit[3])

    def test_render_from_inside_sees_the_furnace_radiosity(self):
        c = (self.n - 1) / 2 / self.n   # the box's centre, world units
        image = vdbrad.render(self.lit, res=(64, 48),
                              camera=((c, c, c), (c, c, 1.0), (0, 1, 0), 60))
        self.assertEqual(image.shape, (48, 64, 3))
        self.assertEqual(image.dtype, np.float32)
        self.assertTrue(np.all(np.isfinite(image)))
        # Every pixel sees a wall: radiosity E / (1 - albedo) = 2 (pixels hold B, not B / pi).
        self.assertLess(abs(float(image.mean()) - 2.0), 1e-4)
        self.assertLess(float(np.max(np.abs(image - 2.0))), 1e-4)

    def test_render_from_outside_frames_the_box(self):
        image = vdbrad.render(self.lit, res="40x30", background=(0.25, 0.5, 0.75))
        self.assertEqual(image.shape, (30, 40, 3))
        # The corner pixels see the background, the centre the box's front wall (whose voxels
        # face inwards: the renderer shows their own radiosity, 2).
        np.testing.assert_allclose(image[0, 0], (0.25, 0.5, 0.75))
        np.testing.assert_allclose(image[15, 20], (2.0, 2.0, 2.0), rtol=1e-4)

    def test_threads_do_not_change_the_result(self):
        grids = furnace_box(8, 0.7, 1.0)
        one = active_values(vdbrad.solve(grids, directions=100, threads=1)[3])
        every = active_values(vdbrad.solve(grids, directions=100)[3])
        np.testing.assert_array_equal(one, every)


class Interrupt(unittest.TestCase):
    def test_ctrl_c_raises_keyboard_interrupt(self):
        # Albedo 0.9999 and no tolerance: ~10 ms an iteration, the residual falling by ~1e-4 of
        # itself per iteration, for up to a million iterations: hours. The Timer's thread runs
        # only because the solve released the GIL.
        grids = furnace_box(32, 0.9999, 1.0)
        # Python's own handler, also when the test was started with SIGINT ignored.
        previous = signal.signal(signal.SIGINT, signal.default_int_handler)
        timer = threading.Timer(0.5, os.kill, (os.getpid(), signal.SIGINT))
        start = time.monotonic()
        timer.start()
        try:
            with self.assertRaises(KeyboardInterrupt):
                vdbrad.solve(grids, directions=1000, iterations=1000000, tolerance=0)
        finally:
            timer.cancel()
            signal.signal(signal.SIGINT, previous)
        elapsed = time.monotonic() - start
        self.assertGreaterEqual(elapsed, 0.5)
        self.assertLess(elapsed, 3.0)
        print(f"\n  interrupted {elapsed - 0.5:.3f} s after SIGINT", flush=True)
        # Nothing was added to the caller's grids, and the module still solves.
        self.assertEqual([g.name for g in grids], ["normal", "albedo", "emission"])
        lit = vdbrad.solve(furnace_box(8, 0.5, 1.0), directions=50)
        self.assertEqual(lit[-1].name, "radiosity")


class Options(unittest.TestCase):
    """Each function's keywords are the tool's options of its command, from one table."""

    # The tool's own: what it prints on stderr and whether it may replace a file. Python's own:
    # render's exr, where the tool takes OUT.exr as an argument.
    TOOL_ONLY = {"verbose", "overwrite", "quiet"}
    PYTHON_ONLY = {"render": {"exr"}}

    @staticmethod
    def tool_options():
        """{command: {option: default}} from `vdbrad help --markdown` (docs/command-line.md)."""
        text = subprocess.run([os.environ["VDBRAD_TOOL"], "help", "--markdown"],
                              capture_output=True, text=True, check=True).stdout
        commands, current = {}, None
        for line in text.splitlines():
            if line.startswith("### `vdbrad "):
                current = commands.setdefault(line.split()[2], {})
            elif line.startswith("| `--") and current is not None:
                cells = [c.strip() for c in line.split(" | ")]
                current[cells[0].strip("|` -").replace("-", "_")] = cells[2].strip("`")
        return commands

    def test_keywords_are_the_tools_options(self):
        import inspect
        tool = self.tool_options()
        for function, command in (("solve", "solve"), ("solve_cloud", "solve-cloud"),
                                  ("voxelize", "voxelize"), ("render", "render")):
            parameters = inspect.signature(getattr(vdbrad, function)).parameters
            keywords = {name: p.default for name, p in parameters.items()
                        if p.kind == p.KEYWORD_ONLY}
            expected = set(tool[command]) - self.TOOL_ONLY
            self.assertEqual(set(keywords) - self.PYTHON_ONLY.get(function, set()), expected,
                             function)
            self.assertGreater(len(expected), 5)
            for name in expected:
                given, shown = keywords[name], tool[command][name]
                if given is None or given is False:
                    continue   # no default, one described in words, or a flag
                if isinstance(given, str):
                    self.assertEqual(given, shown, f"{function}({name}=...)")
                else:
                    self.assertEqual(given, float(shown), f"{function}({name}=...)")
            # The docstring carries each keyword's help.
            for name in expected:
                self.assertIn(f"  {name}: ", getattr(vdbrad, function).__doc__)

    def test_values_read_as_the_tool_reads_them(self):
        grids = furnace_box(6, 0.5, 1.0)
        # A tuple, a list and the tool's text are one value; NumPy numbers are numbers.
        a = vdbrad.render(vdbrad.solve(grids, directions=np.int64(40)), res=(8, 6),
                          background=[0, 0, 0])
        b = vdbrad.render(vdbrad.solve(grids, directions="40"), res="8x6", background="0,0,0")
        np.testing.assert_array_equal(a, b)
        with self.assertRaisesRegex(ValueError, "option directions: '4.5' is not an integer"):
            vdbrad.solve(grids, directions=4.5)
        with self.assertRaisesRegex(TypeError, "keep_sdf must be True or False"):
            vdbrad.voxelize("x.obj", keep_sdf=1)


class Checkpoints(unittest.TestCase):
    def test_interrupted_solve_resumes_bit_identically(self):
        # Albedo 0.9999 and no tolerance: each iteration ~10 ms, for hours. Ctrl-C once the
        # first checkpoint exists; the resumed solve then ends where an uninterrupted one does.
        grids = furnace_box(24, 0.9999, 1.0)
        options = dict(directions=300, tolerance=0, visibility_cache=0)
        with self.assertWarnsRegex(UserWarning, "stopped at iterations 200 with residual"):
            reference = active_values(vdbrad.solve(grids, iterations=200, **options)[-1])
        with tempfile.TemporaryDirectory() as folder:
            ck = os.path.join(folder, "state.ckpt")

            def interrupt_once_saved():
                while not os.path.exists(ck):
                    time.sleep(0.001)
                os.kill(os.getpid(), signal.SIGINT)

            previous = signal.signal(signal.SIGINT, signal.default_int_handler)
            watcher = threading.Thread(target=interrupt_once_saved)
            watcher.start()
            try:
                with self.assertRaises(KeyboardInterrupt):
                    vdbrad.solve(grids, iterations=1000000, checkpoint=ck, checkpoint_every=2,
                                 **options)
            finally:
                watcher.join()
                signal.signal(signal.SIGINT, previous)
            self.assertTrue(os.path.exists(ck))
            with self.assertWarnsRegex(UserWarning, "stopped at iterations 200"):
                resumed = vdbrad.solve(grids, iterations=200, resume=ck, **options)
            self.assertEqual(resumed[-1]["vdbrad:iterations"], 200)
            np.testing.assert_array_equal(active_values(resumed[-1]), reference)
            # Resuming a checkpoint of other options is refused, naming the file.
            with self.assertRaisesRegex(OSError, "state.ckpt"):
                vdbrad.solve(grids, iterations=200, resume=ck, directions=100, tolerance=0)
            # A finished solve removes the checkpoint it kept.
            with self.assertWarnsRegex(UserWarning, "stopped at iterations 4"):
                vdbrad.solve(grids, iterations=4, checkpoint=ck, **options)
            self.assertFalse(os.path.exists(ck))


def mpi_child(spread, out):
    """Run by each rank under mpirun (Distributed): solve a furnace box shared by the ranks;
    rank 0 saves the radiosity."""
    lit = vdbrad.solve(furnace_box(16, 0.7, 1.0), directions=100, iterations=6, tolerance=0,
                       visibility_cache=0, distribute=spread)
    if os.environ.get("OMPI_COMM_WORLD_RANK", "0") == "0":
        np.save(out, active_values(lit[-1]))


@unittest.skipUnless(os.environ.get("VDBRAD_MPIEXEC"), "built without MPI")
class Distributed(unittest.TestCase):
    def test_ranks_give_the_serial_bits(self):
        # The module joins the MPI job at import: every rank runs the script, each sweeps its
        # share (directions) or its slab (slabs), rank 0 gets the whole result.
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")   # stopped at the cap: tolerance 0
            serial = active_values(vdbrad.solve(furnace_box(16, 0.7, 1.0), directions=100,
                                                iterations=6, tolerance=0, visibility_cache=0)[-1])
        for spread in ("directions", "slabs"):
            with tempfile.TemporaryDirectory() as folder:
                out = os.path.join(folder, "b.npy")
                done = subprocess.run(
                    [os.environ["VDBRAD_MPIEXEC"], "--oversubscribe", "--allow-run-as-root",
                     "-np", "2", sys.executable, "-W", "ignore", os.path.abspath(__file__),
                     "--mpi-child", spread, out],
                    capture_output=True, text=True, timeout=120)
                self.assertEqual(done.returncode, 0, done.stderr)
                np.testing.assert_array_equal(np.load(out), serial, spread)


class Module(unittest.TestCase):
    def test_import_before_pyopenvdb(self):
        # A fresh interpreter importing vdbrad first (it imports pyopenvdb itself).
        done = subprocess.run([sys.executable, "-c", "import vdbrad, pyopenvdb; "
                               "print(vdbrad.__version__, pyopenvdb.FloatGrid().name == '')"],
                              capture_output=True, text=True, timeout=60)
        self.assertEqual(done.returncode, 0, done.stderr)
        self.assertTrue(done.stdout.strip().endswith("True"))

    def test_unlit_scene_is_refused(self):
        with self.assertRaisesRegex(ValueError, "nothing lights the scene: .* no sun, sky or environment"):
            vdbrad.solve(furnace_box(4, 0.5, 0.0), directions=20)
        # A sky lights it (from outside: the box's walls face inwards, so none of it enters).
        lit = vdbrad.solve(furnace_box(4, 0.5, 0.0), directions=20, sky=1.0)
        self.assertEqual(active_values(lit[-1]).max(), 0.0)
        # An RGB sky makes the grey box's solve RGB; its light is recorded for render().
        rgb = vdbrad.solve(furnace_box(4, 0.5, 0.0), directions=20, sky=(0.2, 0.3, 0.5))
        self.assertEqual(type(rgb[-1]).__name__, "Vec3SGrid")
        self.assertEqual(rgb[-1].metadata["vdbrad:light"], "sky=0.2,0.3,0.5\n")


class Errors(unittest.TestCase):
    def test_no_surface(self):
        density = vdb.FloatGrid()
        density.name = "smoke"
        density.getAccessor().setValueOn((0, 0, 0), 1.0)
        with self.assertRaises(KeyError) as caught:
            vdbrad.solve([density])
        self.assertIn("no surface: expected a level-set float grid", str(caught.exception))

    def test_not_a_grid(self):
        with self.assertRaisesRegex(TypeError, "expected a pyopenvdb grid, got int"):
            vdbrad.solve([1])
        with self.assertRaisesRegex(TypeError, "a path"):
            vdbrad.solve("scene.vdb")

    def test_bad_option(self):
        grids = furnace_box(4, 0.5, 1.0)
        with self.assertRaisesRegex(ValueError, "update must be jacobi, inplace or "
                                                "progressive, got 'bogus'"):
            vdbrad.solve(grids, update="bogus")
        with self.assertRaisesRegex(TypeError, "unexpected keyword argument 'direction'; did "
                                               "you mean 'directions'"):
            vdbrad.solve(grids, direction=10)
        with self.assertRaisesRegex(ValueError, "checkpoint_every needs checkpoint FILE"):
            vdbrad.solve(grids, checkpoint_every=3)
        with self.assertRaisesRegex(MemoryError, "max_memory"):
            vdbrad.solve(grids, max_memory="1K")
        with self.assertRaisesRegex(ValueError, "albedo"):
            vdbrad.solve(grids[:1], albedo=1.5)

    def test_missing_mesh(self):
        with self.assertRaisesRegex(OSError, "no_such.obj"):
            vdbrad.voxelize("/no_such.obj")

    def test_render_before_solve(self):
        with self.assertRaisesRegex(ValueError, "solve"):
            vdbrad.render(furnace_box(4, 0.5, 1.0), res=(8, 8))


CUBE_OBJ = """mtllib cube.mtl
usemtl wall
v 0 0 0
v 1 0 0
v 1 1 0
v 0 1 0
v 0 0 1
v 1 0 1
v 1 1 1
v 0 1 1
f 1 2 3 4
f 5 8 7 6
f 1 5 6 2
f 4 3 7 8
f 1 4 8 5
f 2 6 7 3
"""


class Voxelize(unittest.TestCase):
    def test_mesh_furnace(self):
        # A closed cube wound to face inwards, every face emitting 1 with albedo 0.5: voxelized
        # and solved, its faces are the furnace again. The voxels of its 12 edges take one
        # face's normal and see the next face's voxels edge-on, so they get little more than
        # their own emission (1.005-1.11 at res 16): E <= B <= E / (1 - albedo) is all they keep.
        with tempfile.TemporaryDirectory() as folder:
            with open(os.path.join(folder, "cube.obj"), "w") as f:
                f.write(CUBE_OBJ)
            with open(os.path.join(folder, "cube.mtl"), "w") as f:
                f.write("newmtl wall\nKd 0.5 0.5 0.5\nKe 1 1 1\n")
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                grids = vdbrad.voxelize(os.path.join(folder, "cube.obj"), res=16)
        names = [g.name for g in grids]
        self.assertIn("normal", names)
        self.assertIn("emission", names)
        lit = vdbrad.solve(grids, directions=300)
        self.assertEqual(lit[-1].name, "radiosity")
        lo, hi = lit[0].evalActiveVoxelBoundingBox()
        faces, edges = [], []
        for item in lit[-1].citerOnValues():
            on_bounds = sum(item.min[a] in (lo[a], hi[a]) for a in range(3))
            (faces if on_bounds <= 1 else edges).append(item.value)
        faces, edges = np.array(faces), np.array(edges)
        self.assertEqual(len(faces) + len(edges), lit[0].activeVoxelCount())
        self.assertGreater(len(faces), 6 * 14 * 14)
        self.assertLess(np.max(np.abs(faces - 2.0)) / 2.0, 1e-4)
        self.assertGreaterEqual(edges.min(), 1.0)
        self.assertLessEqual(edges.max(), 2.0)


class SolveCloud(unittest.TestCase):
    def test_lit_cube_of_fog(self):
        density = vdb.FloatGrid()
        density.name = "density"
        density.gridClass = vdb.GridClass.FOG_VOLUME
        density.transform = vdb.createLinearTransform(voxelSize=0.125)
        density.fill((0, 0, 0), (7, 7, 7), 4.0)   # optical depth 4 across
        out = vdbrad.solve_cloud([density], sun=(30, 0), directions=100)
        self.assertIs(out[0], density)
        # J, and its scattered source's Y_00 coefficient for the renderer (isotropic).
        self.assertEqual([g.name for g in out], ["density", "mean_intensity", "mean_intensity_sh0"])
        j = active_values(out[1])
        self.assertEqual(len(j), 512)
        self.assertTrue(np.all(np.isfinite(j)))
        self.assertGreater(j.min(), 0.0)
        # The solve's energy budget (grid metadata): a conservative cloud (albedo 1) absorbs
        # nothing, and what it reflects and transmits is all the sunlight that entered.
        budget = out[1].metadata
        self.assertEqual(budget["vdbrad:absorptance"], 0.0)
        self.assertAlmostEqual(budget["vdbrad:albedo"] + budget["vdbrad:transmittance"], 1.0,
                               delta=1e-5)
        self.assertGreater(budget["vdbrad:albedo"], 0.1)

    def test_cloud_furnace_under_a_sky(self):
        # A conservative cube of fog under a uniform sky and no sun: J = L in every voxel.
        density = vdb.FloatGrid()
        density.name = "density"
        density.gridClass = vdb.GridClass.FOG_VOLUME
        density.transform = vdb.createLinearTransform(voxelSize=0.125)
        density.fill((0, 0, 0), (7, 7, 7), 4.0)
        out = vdbrad.solve_cloud([density], sky=0.5, directions=100, tolerance=1e-6)
        j = active_values(out[1])
        self.assertEqual(len(j), 512)
        self.assertLess(np.max(np.abs(j - 0.5)), 5e-5)
        self.assertEqual(out[1].metadata["vdbrad:light"], "sky=0.5\n")
        with self.assertRaisesRegex(ValueError, "irradiance with a sky needs sun"):
            vdbrad.solve_cloud([density], sky=0.5, irradiance=2.0)

    def test_fire_lights_the_smoke(self):
        # Blender's and Houdini's fire: `flame` is the medium's emission. An absorbing fog
        # (albedo 0) lit by nothing else: deep in a uniform flame the radiance is the
        # infinite medium's, epsilon / sigma_t, whatever the directions (the centre of a cube
        # 32 optical depths across), times the colour.
        density, flame = vdb.FloatGrid(), vdb.FloatGrid()
        for grid, name, value in ((density, "density", 8.0), (flame, "flame", 5.0)):
            grid.name = name
            grid.gridClass = vdb.GridClass.FOG_VOLUME
            grid.transform = vdb.createLinearTransform(voxelSize=0.25)
            grid.fill((0, 0, 0), (15, 15, 15), value)   # sigma_t 8: 2 per voxel
        out = vdbrad.solve_cloud([density, flame], albedo=0.0, irradiance=0.0, directions=100,
                                 emission_scale=2.0, emission_color=(1.0, 0.5, 0.25))
        j = out[2].getAccessor()
        centre = j.getValue((8, 8, 8))
        self.assertAlmostEqual(centre[0], 10.0 / 8.0, delta=1e-5)    # epsilon = 5 x 2
        self.assertAlmostEqual(centre[1], 0.5 * centre[0], delta=1e-6)
        self.assertAlmostEqual(centre[2], 0.25 * centre[0], delta=1e-6)
        self.assertEqual(out[2].metadata["vdbrad:emission"], "flame")


if __name__ == "__main__":
    if len(sys.argv) == 4 and sys.argv[1] == "--mpi-child":
        mpi_child(sys.argv[2], sys.argv[3])
    else:
        unittest.main(verbosity=2)
