"""The GPU backend (:mod:`impactsph.gpu`) gives the CPU backend's rates, and ``--device gpu``
without a GPU runs on the CPU and says why.

CI has no GPU: the GPU kernels run in numba's CUDA simulator, which is switched on by
``NUMBA_ENABLE_CUDASIM=1`` before numba is imported, so they run in a subprocess: this file is
also that worker (``python tests/test_gpu.py TASK DIR``).  The parent computes the CPU
reference, the worker the same evaluations with :class:`~impactsph.gpu.GpuRates`, and every
output buffer must agree to 1e-10 of its largest value.  Where a GPU is present the same
checks run on it too (``mode = "gpu"``).
"""

from __future__ import annotations

import copy
import dataclasses
import importlib.util
import json
import logging
import os
import pickle
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

TOL = 1e-10
SKIP_CODE = 77  # the worker's exit code for "cannot run here", with the reason on stdout
FIELDS = ("x", "v", "rho", "e", "S", "m", "h", "material", "body", "carried")

#: Small problems (the simulator interprets the kernels in Python).
CASES = {
    # two bars, 25 particles each, colliding: AV, contact between bodies
    "bars-1d": ("bars", ["bodies.0.geometry.spacing=0.0008",
                         "bodies.1.geometry.spacing=0.0008"]),
    # plane-strain Taylor bar on a wall, 8 x 12: ghosts, Mie-Gruneisen, AC (defaults)
    "taylor-2d": ("taylor", ["bodies.0.geometry.count=[8, 12]"]),
    # 4 x 4 x 5 block on a wall: 3D, ghosts, AC with the Shepard variant and the paper's energy
    "block-3d": ("taylor", ["dimension=3", "analysis=none",
                            "bodies.0.velocity=[0.0, 0.0, -200.0]",
                            "bodies.0.geometry.origin=[-0.0015, -0.0015, 0.0]",
                            "bodies.0.geometry.size=[0.003, 0.003, 0.00375]",
                            "bodies.0.geometry.count=[4, 4, 5]",
                            "boundaries.0.point=[0.0, 0.0, 0.0]",
                            "boundaries.0.normal=[0.0, 0.0, 1.0]",
                            "viscosity.correction=shepard", "viscosity.energy_correction=paper"]),
    # the plane-strain Taylor bar with both stabilisations: the gradient correction (a
    # compile-time variant of the passes) and the hourglass control (its own kernel)
    "taylor-2d-stabilised": ("taylor", ["bodies.0.geometry.count=[6, 10]",
                                        "stabilisation.gradient_correction="
                                        "velocity_gradient_and_forces",
                                        "stabilisation.hourglass=1.0"]),
    # the artificial stress (a compile-time variant with more record columns): the plane-strain
    # bar, R by the principal angle, and the 3D block, R by the Jacobi sweeps; the perturbed
    # states have principal stresses of both signs
    "taylor-2d-artificial-stress": ("taylor", ["bodies.0.geometry.count=[6, 10]",
                                               "stabilisation.artificial_stress=0.3"]),
    "block-3d-artificial-stress": ("taylor", ["dimension=3", "analysis=none",
                                              "bodies.0.velocity=[0.0, 0.0, -200.0]",
                                              "bodies.0.geometry.origin=[-0.0015, -0.0015, 0.0]",
                                              "bodies.0.geometry.size=[0.003, 0.003, 0.003]",
                                              "bodies.0.geometry.count=[4, 4, 4]",
                                              "boundaries.0.point=[0.0, 0.0, 0.0]",
                                              "boundaries.0.normal=[0.0, 0.0, 1.0]",
                                              "stabilisation.artificial_stress=0.3"]),
    # Coulomb friction between two bodies (the friction kernel, after the pairs)
    "friction-2d": (str(Path(__file__).parent / "data" / "friction_pair.toml"), []),
    # plane stress (a compile-time variant: the particle pass reads the thickness ratio)
    "taylor-2d-plane-stress": ("taylor", ["bodies.0.geometry.count=[6, 10]",
                                          'two_dimensional="plane_stress"']),
    # a viscosity switch (a compile-time variant: the records carry each particle's factor
    # and memory, and the switch kernel sets the next ones; every switch is the same kernel)
    "taylor-2d-balsara": ("taylor", ["bodies.0.geometry.count=[6, 10]",
                                     'viscosity.scheme="balsara"']),
    # the reconstructing viscosity (a compile-time variant: the gradient kernel fills the
    # records' velocity gradients before the pair kernel)
    "taylor-2d-reconstruction": ("taylor", ["bodies.0.geometry.count=[6, 10]",
                                            'viscosity.scheme="reconstruction"']),
}
#: Cases with a viscosity switch: their buffers have a row per particle for the factor.
SWITCHED = {"taylor-2d-balsara"}
#: Cases evaluated into buffers without rows for the contact force and AC, as the solver makes
#: for runs without them (the bars have no AC; their contact force is then not recorded).
LEAN = {"bars-1d"}
#: Cases with the hourglass control: its state is one more array uploaded every evaluation.
HOURGLASS = {"taylor-2d-stabilised", "friction-2d"}  # the elastic friction pair: "auto" is on
#: Whole runs of 100 steps: the bars, and a 4 x 6 Taylor bar (its neighbour list and ghosts
#: are rebuilt several times, so the uploads after a rebuild are exercised).
RUNS = {
    "bars-1d": CASES["bars-1d"],
    "taylor-2d": ("taylor", ["bodies.0.geometry.count=[4, 6]"]),
}
STEPS = 100
#: Runs with the state on the device between steps (:mod:`impactsph.gpu_step`): the bars (1D,
#: two bodies, AV, probes), two small rings in collision (2D, AC, the artificial stress, the
#: neighbour list rebuilt on the device at every evaluation), a Taylor bar and a 3D block on a
#: wall (ghosts and the walls' constraint on the device).  Each
#: starts from random velocities; a callback halves particle 0's velocity after step 2 (the
#: state downloaded, changed on the host and uploaded again).
_RING = "bodies.{b}.geometry.inner_radius=0.005 bodies.{b}.geometry.outer_radius=0.009"
RESIDENT = {
    # (the left bar's far end carries a tip mass as added inertia: its accelerations, the
    # momentum and the kinetic energy take it)
    "bars-1d": ("bars", [*CASES["bars-1d"][1], "output.history_every=2",
                         "bodies.0.tip_mass={mass=0.002, velocity=[80.0], "
                         "region={origin=[-0.0202], size=[0.004]}}"], 6),
    "rings-2d": ("rings", [*_RING.format(b=0).split(), *_RING.format(b=1).split(),
                           "bodies.0.geometry.centre=[-0.0095, 0.0]",
                           "bodies.1.geometry.centre=[0.0095, 0.0]",
                           "bodies.0.velocity=[50.0, 0.0]", "bodies.1.velocity=[-50.0, 3.0]",
                           "time.neighbour_skin=0.02", "analysis=none", 'viscosity.scheme="ac"',
                           # an elastic case's stabilisation (the kernel gradient correction,
                           # the hourglass control) and Coulomb friction between the bodies
                           'stabilisation.gradient_correction="velocity_gradient_and_forces"',
                           "stabilisation.hourglass=2.0", "contact.friction=0.3",
                           "output.history_every=3"], 4),
    # rigid walls: ghosts chosen, filled and the constraint applied on the device, the wall's
    # Coulomb friction; a gauge's every field, its rows taken from the device at every step
    "taylor-2d": ("taylor", ["bodies.0.geometry.count=[4, 6]", "time.neighbour_skin=0.02",
                             "output.history_every=1",
                             'boundaries=[{type="wall", point=[0.0, 0.0], normal=[0.0, 1.0], '
                             'friction=0.3}]',
                             # a viscosity switch (the variant of taylor-2d-balsara above: its
                             # factors kept on the device, restarted bitwise below)
                             'viscosity.scheme="balsara"',
                             'output.gauges=[{name="foot", body="bar", '
                             'position=[0.001, 0.001], fields=["position", "displacement", '
                             '"velocity", "density", "pressure", "specific_energy", '
                             '"deviatoric_stress", "von_mises_stress", "plastic_work", '
                             '"material_state"]}]'], 5),
    # (h = 1.4 dx: the lattice's sqrt(8) dx pairs lie in the skin, so the 3D rows' split at
    # the support, neighbours.py, is in the lists compared)
    "block-3d": ("taylor", [*CASES["block-3d"][1][:-2], "time.neighbour_skin=0.02",
                            "kernel.h_over_dx=1.4", "output.history_every=1"], 3),
    # a quarter model: two symmetry planes and a wall, corner images of corner images
    "quarter-3d": ("taylor", [*CASES["block-3d"][1][:-2], "time.neighbour_skin=0.02",
                              "bodies.0.geometry.origin=[0.0, 0.0, 0.0]",
                              "bodies.0.geometry.size=[0.0015, 0.0015, 0.00375]",
                              "bodies.0.geometry.count=[2, 2, 5]",
                              'boundaries=[{type="wall", point=[0.0, 0.0, 0.0], '
                              'normal=[0.0, 0.0, 1.0]}, {type="symmetry", '
                              'point=[0.0, 0.0, 0.0], normal=[1.0, 0.0, 0.0]}, '
                              '{type="symmetry", point=[0.0, 0.0, 0.0], '
                              'normal=[0.0, 1.0, 0.0]}]',
                              "output.history_every=1"], 3),
    # records in float32 (compute.record_precision): the device's records by column, rounded
    # as the CPU's rows are
    "taylor-2d-float32": ("taylor", ["bodies.0.geometry.count=[4, 6]", "time.neighbour_skin=0.02",
                                     'compute.record_precision="float32"',
                                     "output.history_every=1"], 5),
    # the walls that hold: the penalty layer and the normal-stress traction; a half model,
    # with a symmetry plane (its ghosts' and their corner images' results mirrored on the
    # device: the AC's u, the correction matrices and the hourglass control's gradients)
    "taylor-2d-layer": ("taylor", ["bodies.0.geometry.count=[2, 6]",
                                   "bodies.0.geometry.origin=[0.0, 0.0]",
                                   "bodies.0.geometry.size=[0.0038, 0.0254]",
                                   'boundaries=[{type="wall", point=[0.0, 0.0], '
                                   'normal=[0.0, 1.0]}, {type="symmetry", point=[0.0, 0.0], '
                                   'normal=[1.0, 0.0]}]',
                                   "contact.wall_layer=0.25",
                                   'contact.traction="normal_stress"',
                                   'stabilisation.gradient_correction='
                                   '"velocity_gradient_and_forces"',
                                   "stabilisation.hourglass=2.0",
                                   # its top held (clamped: the supports' impulse booked)
                                   "bodies.0.clamped={origin=[0.0, 0.02], size=[0.004, 0.01]}",
                                   # a driven region below it (its velocity a function of t)
                                   'bodies.0.driven=[{name="collar", origin=[0.0, 0.012], '
                                   'size=[0.004, 0.006], velocity=[0.0, "-150.0 - 4e7 * t"]}]',
                                   "output.history_every=1"], 4),
}
# axisymmetry: its axis a symmetry plane, the stage's hoop terms, the survey's material
# density (over the thickness ratio) and the walls' layer per radian, on the device
RESIDENT["taylor-axisymmetric"] = ("taylor_axisymmetric", [
    "bodies.0.geometry.count=[3, 8]", "bodies.0.geometry.origin=[0.0, -0.0014]",
    "contact.wall_layer=0.25", "output.history_every=1"], 3)  # (its first row in the layer)
# two smoothing lengths (a body of its own h_over_dx; the artificial stress, whose reference
# spacing is one for the run, off): the device's list with a radius per pair, as the CPU's
# (with the largest h's radius for every pair it held 1,336 entries against the CPU's 1,096)
RESIDENT["rings-2d-widths"] = ("rings", [*RESIDENT["rings-2d"][1],
                                         "stabilisation.artificial_stress=0.0",
                                         "bodies.1.h_over_dx=1.7"], 3)
# a smoothing length that follows the stretch (kernel.max_stretch): set on the device at each
# rebuild from the old list, a half model's ghosts' rows mirrored; the bar at 2,000 m/s, so
# that h grows by 26% in 6 steps and 12 rebuilds (a support left as it was, or the ghosts'
# rows left out, changed the final state by 1.1% and 4.9%); with the kernel gradient
# correction, so that its passes are those of rings-2d-widths (h that differ: one compiled
# module for the two)
RESIDENT["taylor-2d-half-stretch"] = ("taylor", [
    "bodies.0.geometry.count=[2, 6]", "bodies.0.geometry.origin=[0.0, 0.0]",
    "bodies.0.geometry.size=[0.0038, 0.0254]",
    'boundaries=[{type="wall", point=[0.0, 0.0], normal=[0.0, 1.0]}, {type="symmetry", '
    'point=[0.0, 0.0], normal=[1.0, 0.0]}]', "bodies.0.velocity=[0.0, -2000.0]",
    "kernel.max_stretch=3.0", "time.neighbour_skin=0.02", "output.history_every=1",
    'stabilisation.gradient_correction="velocity_gradient_and_forces"'], 6)
# plane stress: the stage's thickness found by the secant iteration, the survey's material
# density over the thickness ratio
RESIDENT["taylor-2d-plane-stress"] = ("taylor", [
    "bodies.0.geometry.count=[4, 6]", 'two_dimensional="plane_stress"',
    "time.neighbour_skin=0.02", "output.history_every=1"], 3)
# SSP-RK3: the three stages (the second and third from their own start), the convex
# combinations and their walls' constraint (the half bar's wall and symmetry plane), the
# books' weights (1/6, 1/6, 2/3); with a switch whose clock stands still at the third
# evaluation (Cullen & Dehnen's, whose factors decay with the time elapsed: the 1D variant
# of tests/test_integrators.py); the step's mean acceleration for the clamps and a driven
# region; the bodies' mean contact force (the bars' history)
_SWITCH = ['viscosity.scheme="cullen_dehnen"', "viscosity.alpha1=1.0", "viscosity.alpha2=2.0"]
for _name, _more in (("taylor-2d-layer", []), ("bars-1d", _SWITCH)):
    RESIDENT[f"{_name}-ssp"] = (RESIDENT[_name][0], [*RESIDENT[_name][1], *_more,
                                                     'time.integrator="ssp_rk3"'], 3)
# the compatible energy update: the work pass after each step (the mean velocity in the
# records' work columns, mirrored into the ghosts: the axisymmetric bar's axis and wall), its
# heating booked instead of the corrector's, a driven region's work at the step's mean
# velocity (a speed quadratic in t, where that mean is not the midpoint's)
_COMPATIBLE = 'time.energy_update="compatible"'
RESIDENT["bars-1d-compatible"] = ("bars", [
    *RESIDENT["bars-1d"][1], _COMPATIBLE,
    'bodies.1.driven=[{name="grip", origin=[0.016], size=[0.0042], '
    'velocity=["-50.0 + 4e13 * t * t"]}]'], 4)
RESIDENT["taylor-axisymmetric-compatible"] = (
    "taylor_axisymmetric", [*RESIDENT["taylor-axisymmetric"][1], _COMPATIBLE], 3)
#: A run with the state on the host and the rates on the device (``compute.resident =
#: false``): the half bar above, its symmetry plane's mirror on the host.
HOST_PATH = {"taylor-2d-half-host": (RESIDENT["taylor-2d-layer"][0],
                                     [*RESIDENT["taylor-2d-layer"][1],
                                      "compute.resident=false"], 2)}


def _halve(sim) -> None:
    """The :data:`RESIDENT` runs' callback: particle 0's velocity halved after step 2."""
    if sim.step == 2:
        sim.state.velocity[0] *= 0.5


def _enforce_input():
    """Particles on both sides of two walls (2D), for the walls' constraint."""
    from impactsph.boundaries import Walls

    rng = np.random.default_rng(11)
    x = rng.uniform(-1.0, 1.0, (40, 2))
    v = rng.normal(0.0, 1.0, (40, 2))
    m = rng.uniform(1.0, 2.0, 40)
    walls = Walls.from_planes([[0.0, -0.5], [0.5, 0.0]], [[0.0, 1.0], [-0.6, 0.8]],
                              ["free", "free"], 2)
    return x, v, m, walls


def _device_enforce() -> dict:
    """The walls' constraint by the device's kernels (``enforce``, ``enforce_sums``,
    ``enforce_finish``): positions, velocities, the events and the impulse."""
    from numba import cuda

    from impactsph.gpu import SIMULATOR_THREADS_PER_BLOCK, THREADS_PER_BLOCK, simulator_enabled
    from impactsph.gpu_step import BOOKS_WIDTH, EVENTS, step_kernels
    from impactsph.physics.options import PassOptions

    x, v, m, walls = _enforce_input()
    simulated = simulator_enabled()
    tpb = SIMULATOR_THREADS_PER_BLOCK if simulated else THREADS_PER_BLOCK
    k = step_kernels(2, simulated, -1, PassOptions(), tpb)
    n = x.shape[0]
    blocks = (n + tpb - 1) // tpb
    dx, dv, dm = cuda.to_device(x), cuda.to_device(v), cuda.to_device(m)
    points, normals = cuda.to_device(walls.points), cuda.to_device(walls.normals)
    scratch = cuda.device_array((n, 4))
    part = cuda.device_array((blocks, 4))
    books = cuda.to_device(np.zeros(BOOKS_WIDTH))
    k["enforce"][blocks, tpb](n, dx, dv, dm, points, normals, scratch)
    k["enforce_sums"][blocks, tpb](n, scratch, part)
    k["enforce_finish"][1, tpb](blocks, part, True, 1.0, books)
    b = books.copy_to_host()
    return {"x": dx.copy_to_host().tolist(), "v": dv.copy_to_host().tolist(),
            "events": b[EVENTS], "impulse": b[EVENTS + 1: EVENTS + 3].tolist()}


def _survey_input(spoil: bool):
    """:func:`_enforce_input`'s particles (many behind its walls) as a Taylor bar's steel, for
    the survey; ``spoil``: particle 30's energy NaN and particle 35's stress infinite too (a
    bad density would be a domain error in the simulator's Python ``math.sqrt``)."""
    from impactsph.loading import load_case
    from impactsph.problem import build_problem

    x, v, m, walls = _enforce_input()
    n = x.shape[0]
    rng = np.random.default_rng(12)
    # (the problem alone, for its table: with a whole Simulation, 9.4 s a call under the
    # profiler in the worker, whose ``resident`` task took 53 s against 39 s without it)
    table = build_problem(load_case("taylor")).table
    rho = rng.uniform(7000.0, 9000.0, n)
    e = rng.uniform(0.0, 1e4, n)
    S = rng.normal(0.0, 1e8, (n, 3, 3))
    h = rng.uniform(1e-3, 2e-3, n)
    if spoil:
        e[30] = np.nan
        S[35, 0, 1] = np.inf
    return x, v, rho, e, S, m, h, np.zeros(n, np.int32), table, walls


def _device_survey() -> dict:
    """The survey by the device's kernels (``survey``, ``survey_finish``) of
    :func:`_survey_input`, unspoilt and spoilt: ``(dt, sums, bad)`` of each."""
    from numba import cuda

    from impactsph.gpu import SIMULATOR_THREADS_PER_BLOCK, THREADS_PER_BLOCK, simulator_enabled
    from impactsph.gpu_step import NO_BAD, step_kernels
    from impactsph.models.columns import CARRIED
    from impactsph.physics.options import PassOptions

    simulated = simulator_enabled()
    tpb = SIMULATOR_THREADS_PER_BLOCK if simulated else THREADS_PER_BLOCK
    k = step_kernels(2, simulated, -1, PassOptions(), tpb)
    out = {}
    for spoil in (False, True):
        x, v, rho, e, S, m, h, material, table, walls = _survey_input(spoil)
        n = x.shape[0]
        blocks = (n + tpb - 1) // tpb
        part = cuda.device_array((blocks, 6))
        bad = cuda.to_device(np.array([NO_BAD], dtype=np.int64))
        record = cuda.device_array(7)
        # (a material state of thickness ratio 1: the material density is the density)
        st = np.ones((n, CARRIED))
        device = [cuda.to_device(a) for a in (x, v, rho, e, S, st, m, m, h, material, table)]
        k["survey"][blocks, tpb](n, *device, 0.0, cuda.to_device(walls.points),
                                 cuda.to_device(walls.normals), part, bad)
        k["survey_finish"][1, tpb](blocks, part, 0.3, bad, record)
        r = record.copy_to_host()
        out[str(spoil)] = [float(r[0]), r[1:6].tolist(), int(r[6])]
    return out


class _StopHereError(Exception):
    """Stops a run after a chosen step, as an interrupted run stops."""


def _resident_run(name: str, on_gpu: bool, stop_after: int | None = None):
    """A :data:`RESIDENT` run, on the CPU or with the GPU backend (the state on the device);
    ``stop_after``: stopped after that step, as an interrupted run stops."""
    import impactsph.simulation as simulation
    from impactsph.loading import load_case

    case, overrides, steps = {**RESIDENT, **HOST_PATH}[name]
    if on_gpu:
        from impactsph.gpu import GpuRates

        simulation.select_backend = (lambda device, dim, *options, cpu_only=None:
                                     GpuRates(dim, *options))
    sim = simulation.Simulation(load_case(case, [*overrides, f"time.max_steps={steps}"]))
    resident = sim._resident is not None
    sim.state.velocity[:] += np.random.default_rng(5).normal(0.0, 5.0, sim.state.velocity.shape)

    def callback(s) -> None:
        _halve(s)
        if s.step == stop_after:
            raise _StopHereError

    try:
        sim.run(callback=callback)
    except _StopHereError:
        pass
    nl = sim.solver.neighbours
    # each particle's inner entries' count (the CPU's list, with an inner list: its rows'
    # first entries; the device keeps none) and its row
    ends = nl.offsets[:-1] if nl.inner_ends is None else nl.inner_ends
    lists = [[int(ends[p] - nl.offsets[p]),
              nl.order[nl.indices[nl.offsets[p]:nl.offsets[p + 1]]].tolist()]
             for p in np.argsort(nl.order)]
    return sim, resident, lists


# -- shared by the parent and the worker ------------------------------------------------------
def _prefilled_buffers(n: int, dim: int, seed: int, lean: bool = False,
                       hourglass: bool = False, switched: bool = False):
    """Rate buffers filled with noise: rows a backend leaves alone must stay as they were.
    ``lean``: the buffers the solver makes for a run without contact or AC (no rows for the
    contact force and the correction), where ``RateBuffers`` has such."""
    import inspect

    from impactsph.physics.rates import RateBuffers

    options = {"contact": False, "corrected": False} if lean else {}
    if hourglass:
        options["hourglass"] = True
    if switched:
        options["switched"] = True
    b = RateBuffers(n, dim, **{k: v for k, v in options.items()
                               if k in inspect.signature(RateBuffers).parameters})
    rng = np.random.default_rng(seed)
    for arr in vars(b).values():
        arr[...] = rng.integers(-9, 9, arr.shape) if arr.dtype.kind == "i" else rng.normal(
            size=arr.shape)
    return b


def _same_list(a, b) -> bool:
    return all(np.array_equal(getattr(a, k, None), getattr(b, k, None))
               for k in ("offsets", "indices", "order"))


def _load_call(path: Path, previous: dict | None) -> dict:
    """One evaluation's inputs.  Like the solver: the evolving fields are the same arrays as in
    the previous call, overwritten; the others are the same objects where unchanged, new ones
    where changed (a rebuilt neighbour list, new ghosts)."""
    call = pickle.loads(path.read_bytes())
    if previous is not None:
        for k in ("x", "v", "rho", "e", "S"):
            np.copyto(previous[k], call[k])
            call[k] = previous[k]
        for k in ("m", "h", "material", "body", "table"):
            if np.array_equal(previous[k], call[k]):
                call[k] = previous[k]
        if _same_list(previous["neighbours"], call["neighbours"]):
            call["neighbours"] = previous["neighbours"]
    return call


def _evaluate(backend, call: dict, b) -> None:
    backend.evaluate(call["n_active"], tuple(call[k] for k in FIELDS), call["table"],
                     call["neighbours"], call["viscosity"], b, *call.get("extra", ()),
                     **call.get("kwargs", {}))


def _gpu_run(name: str, overrides: list[str], steps: int):
    """Run a case for ``steps`` steps with the rate passes on the GPU backend and the state on
    the host (``compute.resident = false``: the step on the device is
    ``tests/test_gpu_step.py``'s)."""
    import impactsph.simulation as simulation
    from impactsph.gpu import GpuRates
    from impactsph.loading import load_case

    simulation.select_backend = lambda device, dim, *options, cpu_only=None: GpuRates(dim, *options)
    sim = simulation.Simulation(load_case(name, [*overrides, f"time.max_steps={steps}",
                                                 "compute.resident=false"]))
    sim.run()
    return sim


# -- the worker --------------------------------------------------------------------------------
def _yielding_simulator() -> bool:
    """Make numba's CUDA simulator hand the interpreter to its threads instead of holding it.

    The simulator runs each thread of a block as a Python thread, and the launching thread
    polls them (``BlockManager.run``) in a loop that never blocks: each time a simulated
    thread wants the interpreter lock it waits out the whole switch interval (5 ms) of that
    poll.  Profiled on ``resident`` (numba 0.68.1): 145 s, of which 103 s in the poll's
    ``is_alive`` calls, for 48,544 simulated threads.  With the poll's ``is_alive`` sleeping
    for zero seconds first (a release of the lock) the same task takes 34 s.  The simulated
    threads themselves are scheduled as before: a shorter switch interval would also be
    faster, but it interrupts them more often, and at 1e-5 s it exposed a race of the
    simulator's own (its shared arrays are allocated by a check-then-set from every thread),
    which gave a wrong time step.  Returns whether it applied the change (it leaves a
    simulator without that class alone)."""
    try:
        from numba.cuda.simulator import kernel
    except ImportError:
        return False
    thread = getattr(kernel, "BlockThread", None)
    if thread is None or hasattr(thread, "_polls"):  # (already changed: the count is there)
        return thread is not None
    polled = thread.is_alive

    def is_alive(self) -> bool:
        thread._polls += 1
        time.sleep(0)  # releases the interpreter lock: a simulated thread that waits runs
        return polled(self)

    thread.is_alive = is_alive
    thread._polls = 0  # the polls that went through it (the worker reports them)
    return True


#: what a simulated kernel (or a function it calls) names that needs its block's threads at
#: once: a barrier, or memory shared between them
_BLOCK_WIDE = frozenset({"syncthreads", "syncthreads_count", "syncthreads_and",
                         "syncthreads_or", "syncwarp", "shared", "shfl_sync",
                         "shfl_up_sync", "shfl_down_sync", "shfl_xor_sync", "all_sync",
                         "any_sync", "eq_sync", "ballot_sync", "match_any_sync",
                         "match_all_sync", "activemask", "lanemask_lt", "threadfence_block"})


def _block_wide(function, seen=None) -> bool:
    """Whether ``function`` (a simulated kernel's Python function), or anything it names
    that is a function (a device function, a generated pass's helper: plain Python under the
    simulator), names one of :data:`_BLOCK_WIDE`: its code's names, nested code included,
    followed through its globals and closure."""
    seen = set() if seen is None else seen
    function = getattr(function, "fn", function)  # a simulated device function
    function = getattr(function, "py_func", function)  # a compiled one (its Python)
    code = getattr(function, "__code__", None)
    if code is None or id(code) in seen:
        return False
    seen.add(id(code))
    codes, names = [code], set()
    while codes:
        c = codes.pop()
        names.update(c.co_names)
        codes.extend(k for k in c.co_consts if hasattr(k, "co_names"))
    if names & _BLOCK_WIDE:
        return True
    scope = dict(getattr(function, "__globals__", {}))
    for name, cell in zip(code.co_freevars, getattr(function, "__closure__", None) or (),
                          strict=False):
        try:
            scope[name] = cell.cell_contents
        except ValueError:  # (an empty cell)
            continue
    return any(_block_wide(scope[name], seen) for name in names | set(code.co_freevars)
               if name in scope and callable(scope[name]))


def _sequential_simulator() -> bool:
    """Make numba's CUDA simulator run a block's threads one after another in the launching
    thread, for the kernels that need no block-wide step (:func:`_block_wide`: no barrier,
    no shared memory): a valid schedule of such a kernel, as any is, without starting a
    Python thread for each simulated one.  Profiled on ``resident`` (numba 0.68.1): 33 of
    its 82 s went to starting and joining 97,880 of them.  A kernel with a block-wide step
    runs on the simulator's threads as before.  Returns whether it applied the change."""
    import threading

    try:
        from numba.cuda.simulator import kernel
    except ImportError:
        return False
    manager = getattr(kernel, "BlockManager", None)
    if manager is None or not hasattr(kernel, "Dim3") or hasattr(manager, "_sequential"):
        return manager is not None and hasattr(manager, "_sequential")
    threaded, wide = manager.run, {}

    def run(self, grid_point, *args):
        f = self._f
        if id(f) not in wide:
            wide[id(f)] = _block_wide(f)
        if wide[id(f)]:
            return threaded(self, grid_point, *args)
        here = threading.current_thread()
        kept = {k: here.__dict__[k] for k in ("threadIdx", "blockIdx", "thread_id")
                if k in here.__dict__}
        block = kernel.Dim3(*self._block_dim)
        here.blockIdx = kernel.Dim3(*grid_point)
        try:
            for point in np.ndindex(*self._block_dim):
                here.threadIdx = kernel.Dim3(*point)
                here.thread_id = point[0] + block.x * (point[1] + block.y * point[2])
                f(*args)
        finally:
            for k in ("threadIdx", "blockIdx", "thread_id"):
                here.__dict__.pop(k, None)
            here.__dict__.update(kept)
        manager._sequential += 1

    manager.run = run
    manager._sequential = 0  # the blocks run in turn (the worker reports them)
    return True


def _simulator_polls() -> int:
    """How many of the simulator's polls went through :func:`_yielding_simulator`'s change."""
    from numba.cuda.simulator import kernel

    return int(getattr(getattr(kernel, "BlockThread", None), "_polls", 0))


class CudaAPIError(Exception):
    """numba-cuda's driver error, as its refusal of an allocation reads."""

    def __init__(self, code: int, message: str):
        super().__init__(f"[{code}] {message}")
        self.code = code


def _out_of_memory_run() -> dict:
    """``taylor-2d`` with the state on the device and every allocation after its first step
    refused, as a GPU out of memory refuses them (its first rebuild on the device allocates
    the build's buffers): the error, the record's failure, the history's rows and the step."""
    import numba.cuda

    import impactsph.simulation as simulation
    from impactsph.errors import DeviceMemoryError
    from impactsph.gpu import GpuRates
    from impactsph.loading import load_case

    case, overrides, steps = RESIDENT["taylor-2d"]
    simulation.select_backend = (lambda device, dim, *options, cpu_only=None:
                                 GpuRates(dim, *options))
    sim = simulation.Simulation(load_case(case, [*overrides, f"time.max_steps={steps}"]))
    sim.state.velocity[:] += np.random.default_rng(5).normal(0.0, 5.0, sim.state.velocity.shape)
    real, error = numba.cuda.device_array, None

    def refused(*args, **kwargs):
        raise CudaAPIError(2, "Call to cuMemAlloc results in CUDA_ERROR_OUT_OF_MEMORY")

    def refuse_from_step_1(s) -> None:  # (the run's first upload allocates too)
        if s.step == 1:
            numba.cuda.device_array = refused

    try:
        sim.run(callback=refuse_from_step_1)
    except DeviceMemoryError as exc:
        error = str(exc)
    finally:
        numba.cuda.device_array = real
    return {"error": error, "failure": sim.record.failure, "rows": len(sim.record.history),
            "step": sim.step}


def _device_memory(sim) -> dict:
    """A device run's allocations (each once) against :mod:`impactsph.gpu_memory`'s count
    of them from the run's sizes, and the layouts that count reads from the run and from its
    case (:meth:`~impactsph.gpu_memory.DeviceLayout.of_case`, what the preflight reads)."""
    from impactsph.gpu_memory import DeviceLayout

    step = sim._resident
    regions = step.drivers.regions if step.drivers is not None else []
    layout = step.layout()
    parts = layout.parts(step.n, step.n_ghosts, len(sim.solver.neighbours.indices),
                         step.n_cells, table_bytes=int(sim.problem.table.nbytes),
                         clamped=int(sim.state.clamped.sum()),
                         driven=sum(r.rows.shape[0] for r in regions), regions=len(regions),
                         probes=len(sim.problem.probes), gauges=len(sim.case.output.gauges),
                         built=step.n_cells > 0, capacity=step.capacity)
    return {"allocated": sorted(step.allocated().values(), reverse=True),
            "summary": sim.summary()["device_memory_bytes"], "parts": parts,
            "layout": layout.as_dict(),
            "case_layout": DeviceLayout.of_case(sim.case, step.tpb).as_dict()}


def _host_path_memory(sim) -> dict:
    """A host-path run's device arrays (:class:`~impactsph.gpu.GpuRates`'s, each once)
    against :meth:`impactsph.gpu_memory.DeviceLayout.host_path_parts`' count of them."""
    from impactsph.gpu_memory import DeviceLayout, arrays_of

    backend, nl = sim.solver.backend, sim.solver.neighbours
    layout = DeviceLayout.of_case(sim.case)
    parts = layout.host_path_parts(sim.state.n, nl.offsets.shape[0] - 1 - sim.state.n,
                                   nl.indices.shape[0], table_bytes=int(sim.problem.table.nbytes),
                                   count_bytes=sim.solver.buffers.pair_count.itemsize)
    return {"allocated": sorted(arrays_of(backend, "rates", device=True).values(),
                                reverse=True), "parts": parts}


def _worker(task: str, folder: Path) -> int:
    try:
        from numba import cuda  # noqa: F401
    except ImportError as exc:
        print(f"numba.cuda cannot be imported here: {exc}")
        return SKIP_CODE
    from impactsph.gpu import GpuRates, simulator_enabled, unavailable_reason
    from impactsph.physics.options import PassOptions

    reason = unavailable_reason()
    if not simulator_enabled() and reason is not None:
        print(f"no GPU: {reason}")
        return SKIP_CODE
    report = {"simulator": simulator_enabled(), "reason": reason, "seconds": {},
              "yielding": simulator_enabled() and _yielding_simulator(),
              "sequential": simulator_enabled() and _sequential_simulator()}
    if task == "rates":
        for case_dir in sorted(p for p in folder.iterdir() if p.is_dir()):
            t0 = time.perf_counter()
            meta = json.loads((case_dir / "meta.json").read_text())
            backend = GpuRates(meta["dim"], PassOptions(**meta["options"]))
            b = _prefilled_buffers(meta["n_rows"], meta["dim"], meta["seed"], meta["lean"],
                                   meta.get("hourglass", False),
                                   meta.get("switched", False))
            previous = None
            uploads = []
            for k in range(meta["calls"]):
                call = _load_call(case_dir / f"call{k}.pickle", previous)
                before = backend.uploads
                _evaluate(backend, call, b)
                uploads.append(backend.uploads - before)
                np.savez(case_dir / f"gpu{k}.npz", **vars(b))
                previous = call
            report["seconds"][case_dir.name] = time.perf_counter() - t0
            report.setdefault("uploads", {})[case_dir.name] = uploads
            report.setdefault("ordered", {})[case_dir.name] = getattr(
                call["neighbours"], "order", None) is not None
    elif task == "run":
        for name, spec in json.loads((folder / "runs.json").read_text()).items():
            t0 = time.perf_counter()
            sim = _gpu_run(spec["case"], spec["overrides"], spec["steps"])
            np.savez(folder / f"{name}.npz", **sim.state.arrays())
            report[name] = {"device": sim.solver.backend.device, "steps": sim.state.step,
                            "builds": sim.solver.neighbours.builds,
                            "rate_evaluations": sim.solver.rate_evaluations}
            report["seconds"][name] = time.perf_counter() - t0
    elif task == "resident":
        for name in RESIDENT:
            t0 = time.perf_counter()
            sim, resident, lists = _resident_run(name, on_gpu=True)
            np.savez(folder / f"{name}.npz", **sim.state.arrays())
            summary = sim.summary()
            report[name] = {"resident": resident, "history": sim.record.history,
                            "downloads": sim._resident.downloads,
                            "books": [sim.viscous_dissipation, sim.correction_work,
                                      sim.correction_heating, *sim.wall_impulse.tolist(),
                                      sim.integrator.constraint_events],
                            "probes": {k: [[t, v.tolist()] for t, v in rows]
                                       for k, rows in sim.record.probes.items()},
                            "gauges": [row.tolist() for row in sim.record.gauges],
                            "lists": lists, "device": summary["device"],
                            # the host path's device arrays still held (GpuRates.release)
                            "host_path_arrays": sorted(sim.solver.backend._device),
                            "counts": [summary["pair_evaluations"],
                                       sim.solver.rate_evaluations,
                                       summary["neighbour_list_builds"]],
                            "memory": _device_memory(sim)}
            report["seconds"][name] = time.perf_counter() - t0
        for name in HOST_PATH:  # the rates on the device, the state on the host
            sim, resident, _ = _resident_run(name, on_gpu=True)
            np.savez(folder / f"{name}.npz", **sim.state.arrays())
            report[name] = {"resident": resident, "device": sim.summary()["device"],
                            "memory": _host_path_memory(sim)}
        report["out_of_memory"] = _out_of_memory_run()
        report["enforce"] = _device_enforce()
        report["survey"] = _device_survey()
        # a restart: 2 steps, a checkpoint, the rest from it, against the run above
        from impactsph.checkpoint import load_checkpoint, write_checkpoint
        from impactsph.loading import load_case

        case, overrides, steps = RESIDENT["taylor-2d"]
        full = np.load(folder / "taylor-2d.npz")
        first = _resident_run("taylor-2d", on_gpu=True, stop_after=3)[0]
        builds_at_checkpoint = first.solver.neighbours.builds
        write_checkpoint(first, folder / "checkpoint.h5")
        second = load_checkpoint(folder / "checkpoint.h5", load_case(
            case, [*overrides, f"time.max_steps={steps}"]))
        second.run(callback=_halve)
        summary = second.summary()
        report["restart"] = {
            "resident": second._resident is not None, "steps": second.state.step,
            "builds_at_checkpoint": builds_at_checkpoint,
            "differences": {k: int(np.count_nonzero(v != full[k]))
                            for k, v in second.state.arrays().items()},
            "books": [second.viscous_dissipation, second.correction_work,
                      second.correction_heating, *second.wall_impulse.tolist()],
            "counts": [summary["pair_evaluations"], summary["neighbour_list_builds"]],
            "last_row": second.record.history[-1]}
        # the prefix sums over several chunks (the runs' are shorter than one)
        from numba import cuda as _cuda

        from impactsph.gpu import SIMULATOR_THREADS_PER_BLOCK, THREADS_PER_BLOCK
        from impactsph.gpu_step import prefix_sum, step_kernels

        simulated = report["simulator"]
        tpb = SIMULATOR_THREADS_PER_BLOCK if simulated else THREADS_PER_BLOCK
        kernels = step_kernels(1, simulated, -1, PassOptions(), tpb)
        report["scans"] = {}
        for size in (1, 255, 257, 65836):
            values = np.random.default_rng(size).integers(0, 9, size)
            device = _cuda.to_device(values)
            prefix_sum(kernels, device, size, tpb, 0,
                       lambda level, rows: _cuda.device_array(rows, np.int64))
            report["scans"][size] = bool((device.copy_to_host() == np.cumsum(values)).all())
    else:
        raise SystemExit(f"unknown task {task!r}")
    if report["yielding"]:
        report["polls"] = _simulator_polls()
    if report["sequential"]:
        from numba.cuda.simulator import kernel

        report["blocks_in_turn"] = int(kernel.BlockManager._sequential)
    (folder / "report.json").write_text(json.dumps(report))
    return 0


def _run_worker(mode: str, task: str, folder: Path) -> dict:
    # the worker shares the session's numba cache: it loads the CPU kernels the session
    # compiled (28 s of the run comparison's 42, warm).  It had a cache of its own, made
    # after a CI run found the session's neighbour builder unreadable in a worker ("'descr'
    # is NULL"): every dimension's builder then shared one cache index, which concurrent
    # compilations could leave naming another dimension's code (impactsph.jitcache)
    env = dict(os.environ)
    env.setdefault("NUMBA_NUM_THREADS", "1")
    if mode == "simulator":
        env["NUMBA_ENABLE_CUDASIM"] = "1"
    else:
        env.pop("NUMBA_ENABLE_CUDASIM", None)
    res = subprocess.run([sys.executable, __file__, task, str(folder)], env=env,
                         capture_output=True, text=True, timeout=900)
    if res.returncode == SKIP_CODE:
        pytest.skip(res.stdout.strip())
    assert res.returncode == 0, res.stdout[-3000:] + res.stderr[-6000:]
    return json.loads((folder / "report.json").read_text())


# -- the parent: CPU references and comparisons ------------------------------------------------
MODES = ["simulator", "gpu"]


def _skip_without_gpu(mode: str) -> None:
    if mode == "gpu":
        from impactsph.gpu import unavailable_reason

        reason = unavailable_reason()
        if reason is not None:
            pytest.skip(f"no GPU here: {reason}")


class _Recorder:
    """A backend that keeps copies of what the solver hands over, then runs the CPU passes."""

    device = "cpu"

    def __init__(self, inner):
        self.inner = inner
        self.call = None

    def evaluate(self, n_active, arrays, table, neighbours, viscosity, b, *extra, **kwargs):
        self.call = {**{k: np.array(a) for k, a in zip(FIELDS, arrays, strict=True)},
                     "table": np.array(table), "neighbours": copy.deepcopy(neighbours),
                     "n_active": n_active, "viscosity": viscosity,
                     "extra": tuple(np.array(a) if isinstance(a, np.ndarray) else a
                                    for a in extra), "kwargs": dict(kwargs)}
        self.inner.evaluate(n_active, arrays, table, neighbours, viscosity, b, *extra,
                            **kwargs)


def _perturb(state, rng) -> None:
    """A state off the lattice: random velocities, densities, energies and deviators."""
    n, dim = state.n, state.dim
    state.velocity += rng.normal(0.0, 30.0, (n, dim))
    state.density *= 1.0 + rng.normal(0.0, 2e-3, n)
    state.specific_energy[:] = rng.uniform(0.0, 5e3, n)
    if dim > 1:
        s = rng.normal(0.0, 2e8, (n, 3, 3))
        s = 0.5 * (s + s.transpose(0, 2, 1))
        s -= np.einsum("ab,i->iab", np.eye(3), np.trace(s, axis1=1, axis2=2) / 3.0)
        if dim == 2:  # plane strain: no xz, yz shear
            s[:, 2, :2] = s[:, :2, 2] = 0.0
        state.deviatoric_stress[:] = s
    # the thickness ratio (read by the plane-stress passes only)
    from impactsph.models.columns import THICKNESS_RATIO

    state.material_state[:, THICKNESS_RATIO] = rng.uniform(0.8, 1.2, n)
    state.viscosity_factor = rng.uniform(0.0, 1.0, n)  # read by a switch's passes only
    if state.hourglass_acceleration.shape[1]:  # the hourglass control's state
        state.hourglass_acceleration[:] = rng.normal(0.0, 1e3, state.hourglass_acceleration.shape)


def _thinned(offsets: np.ndarray, indices: np.ndarray):
    """Every other neighbour of each particle: a different list, as after a rebuild."""
    rows = [indices[offsets[i]:offsets[i + 1]][::2] for i in range(offsets.size - 1)]
    new_offsets = np.zeros_like(offsets)
    np.cumsum([r.size for r in rows], out=new_offsets[1:])
    return new_offsets, np.concatenate(rows).astype(indices.dtype)


def _rate_calls(name: str, overrides: list[str], seed: int) -> list[dict]:
    """Three evaluations of a perturbed state: the first; a second state with the same
    neighbour list and constant fields; the second state with another neighbour list and
    other masses (so stale device copies would show)."""
    from impactsph.loading import load_case
    from impactsph.physics.options import PassOptions
    from impactsph.physics.rates import CpuRates
    from impactsph.simulation import Simulation

    sim = Simulation(load_case(name, overrides))
    solver, state = sim.solver, sim.state
    rng = np.random.default_rng(seed)
    options = PassOptions.of_case(sim.case)
    recorder = _Recorder(CpuRates(state.dim, options))
    solver.backend = recorder
    _perturb(state, rng)
    solver.rates(state)
    first = recorder.call
    _perturb(state, rng)
    state.position += rng.normal(0.0, 0.01 * float(state.smoothing_length.min()),
                                 state.position.shape)
    solver.rates(state)
    second = recorder.call
    third = dict(second)
    third["neighbours"] = copy.copy(second["neighbours"])
    nl = third["neighbours"]
    nl.offsets, nl.indices = _thinned(nl.offsets, nl.indices)
    nl.inner_ends = None  # (the inner list was the old list's)
    nl.splits = None  # (and so were the rows' splits, 2D and 3D)
    nl.inner_reach = 1.0
    third["m"] = second["m"] * (1.0 + 0.1 * rng.random(second["m"].shape))
    for call in (first, second, third):
        call["options"] = dataclasses.asdict(options)
    return [first, second, third]


def _relative_errors(cpu, gpu) -> dict[str, float]:
    """``max |gpu - cpu| / max |cpu|`` per buffer (absolute where the buffer is zero)."""
    errors = {}
    for name, ref in cpu.items():
        got = np.asarray(gpu[name])
        # a shape that differs is named, with both shapes (once, 2026-12-03, the CPU run's
        # material state here had 8 columns, the worker's 5; not reproduced since)
        assert got.shape == ref.shape, f"{name}: the CPU's {ref.shape}, the device's {got.shape}"
        scale = float(np.abs(ref).max()) if ref.size else 0.0
        diff = float(np.abs(got.astype(float) - ref).max()) if ref.size else 0.0
        errors[name] = diff / scale if scale > 0 else diff
    return errors


@pytest.fixture(scope="module", params=MODES)
def rate_comparison(request, tmp_path_factory):
    """``{case: [per call: {buffer: relative error}]}`` and the worker's report."""
    from impactsph.physics.options import PassOptions
    from impactsph.physics.rates import CpuRates

    mode = request.param
    _skip_without_gpu(mode)
    folder = tmp_path_factory.mktemp(f"rates-{mode}")
    references = {}
    for seed, (case, (name, overrides)) in enumerate(CASES.items()):
        calls = _rate_calls(name, overrides, seed)
        case_dir = folder / case
        case_dir.mkdir()
        dim = calls[0]["x"].shape[1]
        n_rows = calls[0]["rho"].shape[0]
        assert all(c["rho"].shape[0] == n_rows for c in calls)
        options = calls[0]["options"]
        (case_dir / "meta.json").write_text(json.dumps(
            {"dim": dim, "n_rows": n_rows, "seed": seed, "calls": len(calls),
             "lean": case in LEAN, "options": options,
             "hourglass": bool(calls[0]["extra"]), "switched": case in SWITCHED}))
        cpu = CpuRates(dim, PassOptions(**options))
        b = _prefilled_buffers(n_rows, dim, seed, case in LEAN, bool(calls[0]["extra"]),
                               case in SWITCHED)
        references[case] = []
        previous = None
        for k, call in enumerate(calls):
            (case_dir / f"call{k}.pickle").write_bytes(pickle.dumps(call))
            call = _load_call(case_dir / f"call{k}.pickle", previous)
            _evaluate(cpu, call, b)
            references[case].append({name: arr.copy() for name, arr in vars(b).items()})
            previous = call
        references[case].append({"n": int(calls[0]["n_active"]), "rows": n_rows,
                                 "pairs": int(calls[0]["neighbours"].indices.size)})
    report = _run_worker(mode, "rates", folder)
    errors = {}
    for case, refs in references.items():
        errors[case] = []
        for k, ref in enumerate(refs[:-1]):
            with np.load(folder / case / f"gpu{k}.npz") as z:
                errors[case].append(_relative_errors(ref, {n: z[n] for n in z.files}))
    return mode, errors, report, {case: refs[-1] for case, refs in references.items()}


@pytest.mark.parametrize("case", list(CASES))
def test_rates_match_cpu(rate_comparison, case):
    """Every buffer of three successive evaluations (same list; a new list and new masses)
    within 1e-10 of the CPU backend's, rows the CPU leaves alone left alone."""
    mode, errors, report, sizes = rate_comparison
    assert sizes[case]["n"] > 0
    for k, call_errors in enumerate(errors[case]):
        bad = {name: err for name, err in call_errors.items() if not err <= TOL}
        assert not bad, f"{mode}, {case}, evaluation {k}: {bad}"
    if mode == "simulator":
        assert report["simulator"] and report["reason"] is not None


def test_only_changed_inputs_are_uploaded(rate_comparison):
    """After the first evaluation the state (x, v, rho, e, S, the carried material state, and
    the hourglass acceleration where the control is on) is copied every time; the neighbour
    list and the masses only when new arrays come (here: offsets, indices, m, and the list's
    order where it has one)."""
    _, _, report, _ = rate_comparison
    for case, uploads in report["uploads"].items():
        state = 6 + (case in HOURGLASS)
        assert uploads[1:] == [state, state + 3 + report["ordered"][case]], (case, uploads)


@pytest.fixture(scope="module", params=MODES)
def run_comparison(request, tmp_path_factory):
    """Final states of 100-step runs on the CPU (here) and the GPU backend (the worker)."""
    from impactsph.loading import load_case
    from impactsph.simulation import Simulation

    mode = request.param
    _skip_without_gpu(mode)
    folder = tmp_path_factory.mktemp(f"runs-{mode}")
    (folder / "runs.json").write_text(json.dumps(
        {name: {"case": case, "overrides": overrides, "steps": STEPS}
         for name, (case, overrides) in RUNS.items()}))
    report = _run_worker(mode, "run", folder)
    cpu = {}
    for name, (case, overrides) in RUNS.items():
        sim = Simulation(load_case(case, [*overrides, f"time.max_steps={STEPS}"]))
        sim.run()
        cpu[name] = (sim.state.arrays(), sim.solver.neighbours.builds)
    return mode, report, cpu, folder


@pytest.mark.parametrize("name", list(RUNS))
def test_run_matches_cpu(run_comparison, name):
    """100 steps with the rate passes on the GPU (the state on the host) end in the CPU run's
    state to 1e-10."""
    mode, report, cpu, folder = run_comparison
    state, builds = cpu[name]
    info = report[name]
    assert info["device"] == "gpu"
    assert info["steps"] == STEPS
    assert info["builds"] == builds
    with np.load(folder / f"{name}.npz") as z:
        errors = _relative_errors(state, {k: z[k] for k in z.files})
    bad = {k: e for k, e in errors.items() if not e <= TOL}
    assert not bad, f"{mode}, {name}: {bad}"


def test_taylor_run_rebuilds_its_neighbour_list(run_comparison):
    """The 2D run exercises the uploads after a rebuild (new list, new ghosts)."""
    _, report, _, _ = run_comparison
    assert report["taylor-2d"]["builds"] > 2


def test_the_simulator_runs_blocks_in_turn(run_comparison):
    """In the simulator the worker's runs had the blocks of the kernels without a block-wide
    step run their threads in turn (:func:`_sequential_simulator`: the resident runs' worker
    in 35 s instead of 52-53 s; the resident step's reductions still run on the simulator's
    threads, whose poll releases the interpreter lock, :func:`_yielding_simulator`: its test
    is ``tests/test_gpu_step.py``'s): a numba whose simulator no longer has
    ``BlockManager.run`` or ``Dim3`` fails here, not by a slow test run."""
    mode, report, _, _ = run_comparison
    assert report["yielding"] == report["sequential"] == (mode == "simulator")
    if mode == "simulator":
        assert report["blocks_in_turn"] > 1000, report["blocks_in_turn"]


def test_what_keeps_the_state_on_the_host_is_named():
    """:func:`impactsph.gpu_step.resident_unsupported` says why a case's state cannot stay on
    the device, and lets the cases without such a feature through."""
    from impactsph.gpu_step import resident_unsupported
    from impactsph.loading import load_case

    def why(name: str, overrides: list[str] = ()) -> str | None:
        return resident_unsupported(load_case(name, list(overrides)))

    assert why("bars") is None
    assert why("rings") is None
    assert why("taylor") is None  # a rigid wall: its ghosts on the device
    assert why("taylor", ["contact.wall_layer=0.25"]) is None  # the walls that hold too
    assert why("taylor", [  # a symmetry plane: its ghosts' results mirrored on the device
        'boundaries=[{type="wall", point=[0.0, 0.0], normal=[0.0, 1.0]}, '
        '{type="symmetry", point=[0.0, 0.0], normal=[1.0, 0.0]}]']) is None
    assert why("taylor", [  # a wall's friction, on the device
        'boundaries=[{type="wall", point=[0.0, 0.0], normal=[0.0, 1.0], friction=0.1}]']) is None
    assert why("taylor_axisymmetric") is None  # its axis a symmetry plane, on the device
    # an elastic case's stabilisation, friction between bodies and clamps run on the device
    assert why("taylor", ["stabilisation.hourglass=1.0",
                          'stabilisation.gradient_correction="velocity_gradient_and_forces"']) \
        is None
    assert why(str(Path(__file__).parent / "data" / "friction_pair.toml")) is None
    assert why("cantilever") is None
    assert why("cantilever", ['bodies.0.tip_mass.carried_as="added_inertia"']) is None
    assert why("taylor", ['two_dimensional="plane_stress"']) is None  # on the device too
    assert why("taylor", ['bodies.0.driven=[{name="top", origin=[-0.004, 0.02], '
                          'size=[0.008, 0.01], velocity=[0.0, -10.0]}]']) is None
    # gauges take their particles' rows from the device
    assert why("bars", ['output.gauges=[{name="g", body="left", position=[0.0]}]']) is None
    assert why("bars", ["compute.resident=false"]) == "compute.resident = false"
    assert why("bars", ['time.integrator="ssp_rk3"']) is None  # SSP-RK3 on the device too
    assert why("bars", ['time.energy_update="compatible"']) is None  # its work pass too
    assert why("bars", ['viscosity.scheme="balsara"']) is None  # a switch, on the device
    assert why(str(Path(__file__).parents[1] / "examples" / "taylor3d.toml")) is None


# -- falling back to the CPU -------------------------------------------------------------------
def test_device_gpu_without_a_gpu_falls_back_with_a_reason(caplog):
    from impactsph.devices import select_backend
    from impactsph.gpu import unavailable_reason

    reason = unavailable_reason()
    if reason is None:
        pytest.skip("a GPU is present: no fallback")
    with caplog.at_level(logging.WARNING):
        backend = select_backend("gpu", 2)
    assert backend.device == "cpu"
    assert reason in caplog.text and "running on the CPU" in caplog.text


def test_cli_device_gpu_without_a_gpu_runs_on_the_cpu(tmp_path, caplog):
    """``impactsph run CASE --device gpu`` where no GPU is present: exit 0, a warning that
    says why, and the summary records the CPU."""
    from typer.testing import CliRunner

    from impactsph.cli import app
    from impactsph.gpu import unavailable_reason

    reason = unavailable_reason()
    if reason is None:
        pytest.skip("a GPU is present: no fallback")
    out = tmp_path / "bars"
    with caplog.at_level(logging.WARNING):
        res = CliRunner().invoke(app, ["run", "bars", "--device", "gpu", "--quiet", "--out",
                                       str(out), "--set", "time.max_steps=5",
                                       "--set", "output.figures=false"])
    assert res.exit_code == 0, res.output
    assert "compute.device = 'gpu' but" in caplog.text and reason in caplog.text
    summary = json.loads((out / "summary.json").read_text())
    assert summary["device"] == "cpu"


def test_unavailable_reason_names_the_missing_package():
    from impactsph.gpu import unavailable_reason

    if importlib.util.find_spec("numba_cuda") is not None:
        pytest.skip("numba-cuda is installed")
    assert "numba-cuda is not installed" in unavailable_reason()


def test_launch_settings_come_from_the_environment_and_bad_ones_are_named():
    """The tuning knobs for a GPU (threads a block, the pair kernel's register cap): the
    defaults, values taken, and a bad value refused naming the variable, the value and what
    is allowed."""
    from impactsph.gpu import REGISTERS_ENV, THREADS_ENV, launch_settings

    assert launch_settings({}) == (128, 0)
    assert launch_settings({THREADS_ENV: "256", REGISTERS_ENV: "128"}) == (256, 128)
    assert launch_settings({THREADS_ENV: " ", REGISTERS_ENV: "0"}) == (128, 0)
    for name, value, allowed in ((THREADS_ENV, "96", "a power of two from 32 to 512"),
                                 (THREADS_ENV, "1024", "a power of two from 32 to 512"),
                                 (THREADS_ENV, "lots", "a power of two from 32 to 512"),
                                 (REGISTERS_ENV, "16", "0 (the compiler's choice) or 32 to 255"),
                                 (REGISTERS_ENV, "300", "0 (the compiler's choice) or 32 to 255")):
        with pytest.raises(ValueError) as error:
            launch_settings({name: value})
        assert str(error.value) == f"{name} = {value!r}: allowed is {allowed}"


@pytest.mark.parametrize("dim", [1, 2, 3])
def test_the_device_records_are_columns_with_u_only_where_read(dim):
    """The GPU's packed records are stored by column (a warp's neighbours' field in one or two
    lines), unpadded, and carry the viscous acceleration's columns only for a scheme with a
    correction or a switch: as many columns as the CPU's rows."""
    from types import SimpleNamespace

    from impactsph.gpu import RECORD_ORDER, record_columns
    from impactsph.physics.rates import CpuRates

    assert RECORD_ORDER == "F"
    cpu = CpuRates(dim)
    passes = cpu.passes
    assert passes.RECORD_COLUMNS == passes.U + dim  # u last
    for correction, switch in ((None, None), ((1.0,), None), (None, (1.0,))):
        viscosity = SimpleNamespace(correction=correction, switch=switch)
        columns = record_columns(passes.RECORD_COLUMNS, dim, viscosity)
        assert columns == cpu.record_columns(viscosity)
        assert columns == (passes.U if correction is None and switch is None
                           else passes.RECORD_COLUMNS)


def test_a_numpy_that_numba_cuda_cannot_compile_with_is_named(monkeypatch, caplog):
    """numba-cuda 0.30.4 with numpy 2.5 loads its typing with an AttributeError (seen on an
    H200, NVIDIA/numba-cuda#907): the GPU is then said to be unusable, with the fix, and the
    run goes on on the CPU, instead of failing at its first kernel."""
    import logging
    from types import SimpleNamespace

    from impactsph import gpu
    from impactsph.devices import select_backend
    from impactsph.physics.rates import CpuRates

    real_find_spec, real_import = importlib.util.find_spec, importlib.import_module

    def find_spec(name, *args):
        return object() if name == "numba_cuda" else real_find_spec(name, *args)

    def import_module(name, *args):
        if name == "numba.cuda.np.npyimpl":
            raise AttributeError("module 'numpy' has no attribute 'row_stack'")
        return real_import(name, *args)

    monkeypatch.setattr(gpu, "simulator_enabled", lambda: False)
    monkeypatch.setattr(gpu, "cuda", SimpleNamespace(is_available=lambda: True))
    monkeypatch.setattr(importlib.util, "find_spec", find_spec)
    monkeypatch.setattr(importlib, "import_module", import_module)
    reason = gpu.unavailable_reason()
    assert "row_stack" in reason and "pip install 'numpy<2.5'" in reason, reason
    with caplog.at_level(logging.WARNING, logger="impactsph.devices"):
        backend = select_backend("gpu", 2)
    assert isinstance(backend, CpuRates)
    assert "numpy<2.5" in caplog.text and "running on the CPU" in caplog.text


def _kernel_argument_types(dim: int) -> dict:
    """numba types of the kernels' arguments, by name, as the solver hands them over."""
    import numba as nb

    from impactsph.neighbours import NeighbourList
    from impactsph.physics.rates import RateBuffers

    x = np.random.default_rng(0).random((12, dim))
    nl = NeighbourList.build(x, 0.5)
    f1, f2, f3 = nb.float64[::1], nb.float64[:, ::1], nb.float64[:, :, ::1]
    types = {"order": nb.typeof(np.ascontiguousarray(getattr(nl, "order", np.arange(12)))),
             "offsets": nb.typeof(nl.offsets), "indices": nb.typeof(nl.indices),
             "material": nb.int32[::1], "body": nb.int32[::1], "bodies": nb.int32[::1],
             "pair_count": nb.typeof(RateBuffers(2, dim).pair_count), "table": f2}
    types["visc_params"] = types["correction_params"] = nb.types.UniTuple(nb.float64, 4)
    types["zeta"] = nb.float64
    types["carried"] = f2
    types["normal_stress"] = nb.boolean
    for names, t in (("n_rows n_active visc_kind", nb.int64),
                     ("m rho e h drho de_visc de", f1),
                     ("x v contact_force correction_books dv hg dhg dS", f2),
                     ("S L_sorted", f3)):
        types.update(dict.fromkeys(names.split(), t))
    types["P"] = nb.float64[::1, :]  # the records by column (impactsph.gpu.RECORD_ORDER)
    return types


def _as_if_on_sm90(monkeypatch) -> None:
    """numba-cuda compiles a function that a kernel calls (one not inlined) for the current
    device's compute capability; without a GPU there is none, so it is given as sm_90's."""
    from types import SimpleNamespace

    import numba.cuda.dispatcher

    monkeypatch.setattr(numba.cuda.dispatcher, "get_current_device",
                        lambda: SimpleNamespace(compute_capability=(9, 0)))


@pytest.mark.skipif(importlib.util.find_spec("numba_cuda") is None,
                    reason="numba-cuda (the gpu extra) is not installed")
@pytest.mark.parametrize("variant", ["plain", "artificial_stress", "reconstruction", "float32",
                                     "compatible"])
@pytest.mark.parametrize("dim", [1, 2, 3])
def test_kernels_compile_for_a_gpu(dim, variant, monkeypatch):
    """With numba-cuda, every kernel compiles to PTX for an H100 (sm_90), no GPU needed:
    the term functions called from the kernels are accepted as device functions (with the
    artificial stress too: its principal-stress decompositions are scalars only; the
    reconstructing viscosity's gradient kernel and pair term; and float32 records, their
    positions in two parts widened with ``np.float64``; the compatible energy update's
    records, with their work velocity columns)."""
    import inspect

    from numba import cuda

    from impactsph.gpu import gpu_kernels, simulator_enabled
    from impactsph.physics.options import PassOptions

    if simulator_enabled():
        pytest.skip("the CUDA simulator is on")
    _as_if_on_sm90(monkeypatch)
    types = _kernel_argument_types(dim)
    options = {"plain": PassOptions(), "artificial_stress": PassOptions(artificial_stress=0.3),
               "reconstruction": PassOptions(velocity_reconstruction=True),
               "float32": PassOptions(record_precision="float32"),
               "compatible": PassOptions(compatible_energy=True)}[variant]
    if variant == "float32":
        import numba as nb

        types["P"] = nb.float32[::1, :]
    kernels = gpu_kernels(dim, False, -1, options)
    for kernel in (*kernels[:5], kernels[7]):  # the gradient kernel: the moment kernel's args
        names = inspect.signature(kernel.py_func).parameters
        ptx, _ = cuda.compile_ptx(kernel.py_func, tuple(types[k] for k in names), cc=(9, 0))
        assert ".target sm_90" in ptx


#: blocks of 128 threads the pair kernel keeps on an sm_90 multiprocessor (65,536 registers)
#: with the paper's options: 3D 166 registers a thread, 2D 120, as measured on an H200 at
#: 7556287 (benchmarks/README.md, "The GPU pair kernel's registers")
PAIR_KERNEL_BLOCKS = {2: 4, 3: 3}


@pytest.mark.skipif(importlib.util.find_spec("numba_cuda") is None
                    or importlib.util.find_spec("nvidia.cuda_nvcc") is None,
                    reason="numba-cuda with its CUDA toolkit wheels (the gpu extra) is not "
                    "installed")
@pytest.mark.parametrize("precision", ["float64", "float32"])
@pytest.mark.parametrize("dim", [2, 3])
def test_the_pair_kernel_keeps_its_blocks_a_multiprocessor(dim, precision, monkeypatch,
                                                          benchmark_script):
    """ptxas (CUDA 12, sm_90) gives the pair kernel no more registers a thread than keep
    :data:`PAIR_KERNEL_BLOCKS` blocks of 128 threads on a multiprocessor, and no spills: the
    kernel waits on its neighbours' records, so its speed follows the threads resident.  A
    change to the shared pair body that suits the CPU can cost the GPU a block: 4151c80
    put the viscous push across bodies into the contact loop and took the 3D kernel from
    166 to 182 registers, 3 blocks to 2, unseen until this count.  The same with the
    records in float32 (3D 167 registers, 2D 116)."""
    import inspect

    from numba import cuda

    from impactsph.gpu import gpu_kernels, simulator_enabled
    from impactsph.physics.options import PassOptions

    if simulator_enabled():
        pytest.skip("the CUDA simulator is on")
    _as_if_on_sm90(monkeypatch)
    registers = benchmark_script("gpu_registers")
    ptxas = registers.ptxas_path()
    if not Path(ptxas).is_file():
        pytest.skip(f"no ptxas at {ptxas}")
    types = _kernel_argument_types(dim)
    if precision == "float32":
        import numba as nb

        types["P"] = nb.float32[::1, :]
    kernel = gpu_kernels(dim, False, -1, PassOptions(record_precision=precision))[1]
    names = inspect.signature(kernel.py_func).parameters
    ptx, _ = cuda.compile_ptx(kernel.py_func, tuple(types[k] for k in names), cc=(9, 0))
    report = registers.ptxas_report(ptxas, ptx)
    assert report["spills"] == 0, report
    assert registers.blocks_a_multiprocessor(report["registers"]) >= PAIR_KERNEL_BLOCKS[dim], \
        report


def _step_kernel_types(name: str, dim: int) -> tuple:
    """numba types of the arguments of the step kernel ``name``
    (:func:`impactsph.gpu_step.step_kernels`), as :class:`~impactsph.gpu_step.ResidentStep`
    hands them over."""
    import inspect

    import numba as nb

    from impactsph.gpu_step import step_kernels
    from impactsph.physics.options import PassOptions

    f1, f2, f3 = nb.float64[::1], nb.float64[:, ::1], nb.float64[:, :, ::1]
    i64, i32 = nb.int64[::1], nb.int32[::1]
    types = {}
    for names, t in (("n n_blocks n_cells chunk n_ghosts n_real ghost_body0 b slot n_rows "
                      "start stop w u_column c0 region w_column", nb.int64),
                     ("dt courant scale radius front weight share reach layer hourglass "
                      "vx vy vz rate_x rate_y rate_z vel_x vel_y vel_z keep support_per_h skin "
                      "max_stretch",
                      nb.float64),
                     ("corrected store first count_events walls per_radian heating per_pair",
                      nb.boolean),
                     ("x0 v0 x v dv xs v_rate hg0 hg dhg part st0 st correction_books table points "
                      "normals scratch contact_force carried force layer_force x0 S0 dS "
                      "friction_force reactions rate mean sx sx0", f2),
                     ("S", f3),
                     ("rho0 e0 pw0 drho de rho e pw h m de_visc lo hi origin largest "
                      "books factor memory mu inertia fraction work de_work de_pairs sh h0",
                      f1),
                     ("bad ncell key counts ends fill a sums rows offsets src wall "
                      "position sb", i64),
                     ("material order indices body pair_count", i32)):
        types.update(dict.fromkeys(names.split(), t))
    types.update(clamped=nb.boolean[::1], reference=nb.float32[:, ::1], kinds=nb.int8[::1],
                 P=nb.float64[::1, :], gradients=f3)  # (the records by column on the device)
    kernel = step_kernels(dim, False, -1, PassOptions(), 128)[name]
    special = {("survey_finish", "out"): f1, ("take_rows", "out"): f2,
               ("body_finish", "out"): f2, ("gauges", "out"): f2,
               ("mean_velocity", "work"): f2, ("work_columns", "work"): f2,
               ("largest", "a"): f1, ("largest", "out"): f1}
    return kernel, tuple(special.get((name, k), types.get(k))
                         for k in inspect.signature(kernel.py_func).parameters)


@pytest.mark.skipif(importlib.util.find_spec("numba_cuda") is None,
                    reason="numba-cuda (the gpu extra) is not installed")
@pytest.mark.parametrize("dim", [1, 2, 3])
def test_step_kernels_compile_for_a_gpu(dim, monkeypatch):
    """With numba-cuda, every kernel of the step on the device (the stages, the survey, the
    books, the neighbour build, the prefix sums) compiles to PTX for sm_90, no GPU needed.
    (The stage calls the strength and damage models' functions, which numba-cuda compiles as
    device functions for the current device's compute capability: without a GPU it is given
    as sm_90's here.)"""
    from numba import cuda

    _as_if_on_sm90(monkeypatch)

    from impactsph.gpu import simulator_enabled
    from impactsph.gpu_step import step_kernels
    from impactsph.physics.options import PassOptions

    if simulator_enabled():
        pytest.skip("the CUDA simulator is on")
    for name in step_kernels(dim, False, -1, PassOptions(), 128):
        kernel, types = _step_kernel_types(name, dim)
        ptx, _ = cuda.compile_ptx(kernel.py_func, types, cc=(9, 0))
        assert ".target sm_90" in ptx, name


if __name__ == "__main__":
    sys.exit(_worker(sys.argv[1], Path(sys.argv[2])))
