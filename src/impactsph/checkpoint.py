"""Checkpoints: everything a run needs to continue exactly where it was, in one HDF5 file.

A checkpoint holds the particle state, the neighbour list and the wall ghosts in use (the
order of the pair sums depends on them, so restoring them makes a restarted run end in
bitwise the same state as an uninterrupted one), the energy and momentum accumulators, the
record so far (history, probes, snapshots) and the resolved case.  It is written to a
temporary file in the same directory and renamed, so a run killed while writing leaves the
previous checkpoint whole.

The root attribute ``sha256`` is the SHA-256 of everything else in the file (every
dataset's name, type, shape and bytes, every attribute, in name order: :func:`digest`).
:func:`verify_checkpoint` recomputes it, and a checkpoint that does not match (a corrupted
byte, a truncated copy, an edited file) is refused with one line naming the file before any
work; a checkpoint of an older version, written before the checksum, is read unverified.
"""

from __future__ import annotations

import hashlib
import json
import logging
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from ._version import __version__
from .atomic import atomic_path
from .errors import CaseError, OutputError
from .loading import validate_case
from .materials import TableLayout
from .models.columns import COMMON_STATE, THICKNESS_RATIO
from .neighbours import NeighbourList, inner_entries_first
from .problem import build_problem
from .simulation import Simulation, Snapshot
from .state import ParticleState

FORMAT = "impactsph-checkpoint-1"
#: the root attribute that holds the checksum (:func:`digest`)
CHECKSUM = "sha256"

log = logging.getLogger("impactsph")


def _attribute_bytes(value: Any) -> bytes:
    if isinstance(value, str):
        return b"s" + value.encode()
    if isinstance(value, bytes):
        return b"b" + value
    arr = np.asarray(value)
    return arr.dtype.str.encode() + repr(arr.shape).encode() + arr.tobytes()


def digest(f: h5py.File) -> str:
    """The SHA-256 (hex) of an open checkpoint: every group's and dataset's name, every
    attribute but :data:`CHECKSUM`, every dataset's type, shape and bytes, in name order."""
    names: list[str] = []
    f.visit(names.append)
    h = hashlib.sha256()
    for name in ["", *sorted(names)]:
        obj = f[name] if name else f
        h.update(b"\0name\0" + name.encode())
        for key in sorted(obj.attrs):
            if name == "" and key == CHECKSUM:
                continue
            h.update(b"\0attr\0" + key.encode() + b"\0" + _attribute_bytes(obj.attrs[key]))
        if isinstance(obj, h5py.Dataset):
            data = np.ascontiguousarray(obj[()])
            h.update(b"\0data\0" + data.dtype.str.encode() + repr(data.shape).encode())
            h.update(data.tobytes())
    return h.hexdigest()


def _contents(sim: Simulation) -> tuple[dict[str, dict[str, Any]], dict[str, Any]]:
    """What a checkpoint of ``sim`` holds: the attributes of each group (``""`` the root) and
    the datasets by path, in the order they are written."""
    attrs: dict[str, dict[str, Any]] = {"": {
        "format": FORMAT, "impactsph": __version__,
        "case": json.dumps(sim.case.model_dump(mode="json")), "time": sim.state.time,
        "step": sim.state.step, "viscosity_factor_time": sim.state.viscosity_factor_time}}
    data: dict[str, Any] = {}
    attrs["state"] = {"common_state": json.dumps(list(COMMON_STATE))}
    for name, arr in sim.state.arrays().items():
        data[f"state/{name}"] = arr
    nl = sim.solver.neighbours
    for name in ("offsets", "indices", "reference_positions", "order", "reference_origin"):
        data[f"neighbours/{name}"] = getattr(nl, name)
    attrs["neighbours"] = {"radius": nl.radius, "skin": nl.skin, "builds": nl.builds}
    if nl.inner_ends is not None:  # the inner list: each row's first entries (neighbours.py)
        data["neighbours/inner_ends"] = nl.inner_ends
        attrs["neighbours"].update(inner_reach=nl.inner_reach, inner_radius=nl.inner_radius)
    if nl.splits is not None:  # 2D and 3D: where each row's skin part starts (neighbours.py)
        data["neighbours/splits"] = nl.splits
    data["neighbours/ghost_src"] = sim.solver._ghost_src
    data["neighbours/ghost_wall"] = sim.solver._ghost_wall
    attrs["accumulators"] = {}
    for name, value in accumulators(sim).items():
        data[f"accumulators/{name}"] = np.asarray(value)
    hist = sim.record.history
    columns = list(hist[0]) if hist else []
    rec = attrs["record"] = {"history_columns": json.dumps(columns)}
    data["record/history"] = np.array([[row.get(c, np.nan) for c in columns] for row in hist],
                                      dtype=np.float64)
    for name, samples in sim.record.probes.items():
        data[f"record/probe_{name}/time"] = np.array([t for t, _ in samples])
        data[f"record/probe_{name}/velocity"] = np.array([v for _, v in samples])
    rec["probe_names"] = json.dumps(list(sim.record.probes))
    if sim.gauges is not None:
        rec["gauge_columns"] = json.dumps(sim.gauges.columns)
        data["record/gauges"] = np.array(sim.record.gauges, dtype=np.float64).reshape(
            -1, len(sim.gauges.columns))
    so_far = sim.record_so_far()  # (a checkpoint written during a step: the steps' time)
    rec.update(wall_seconds=so_far.wall_seconds, compile_seconds=so_far.compile_seconds,
               setup_seconds=so_far.setup_seconds,
               thread_changes=json.dumps([list(c) for c in so_far.thread_changes]),
               thread_trials=json.dumps(list(so_far.thread_trials), default=float),
               restarts=json.dumps(so_far.restarts))
    for k, snap in enumerate(sim.record.snapshots):
        # (the fields' order, which h5py reads back by name: snapshots.npz keeps it)
        attrs[f"record/snapshot_{k}"] = {"time": snap.time, "fields": json.dumps(list(snap.fields))}
        for name, arr in snap.fields.items():
            data[f"record/snapshot_{k}/{name}"] = arr
    rec["n_snapshots"] = len(sim.record.snapshots)
    return attrs, data


#: room asked of the disk beyond a checkpoint's data: HDF5's own structures (a few kB a
#: group and dataset) and the attributes
_CHECKPOINT_MARGIN = 1 << 20


def write_checkpoint(sim: Simulation, path: Path | str) -> Path:
    """Write ``sim`` to ``path`` atomically.  Refused (:class:`OutputError`, one line) where
    the disk has less room than the checkpoint needs: HDF5 that runs out of room part-way
    reports it only while it frees its objects, and went on until the process crashed
    (a segmentation fault, 2026-12-08)."""
    import errno
    import shutil

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    attrs, data = _contents(sim)
    need = (sum(np.asarray(a).nbytes for a in data.values()) + _CHECKPOINT_MARGIN
            + sum(len(str(v)) for group in attrs.values() for v in group.values()))
    free = shutil.disk_usage(path.parent).free
    if free < need:
        raise OutputError(errno.ENOSPC, f"cannot write {path}: the disk is full ({free:,} B "
                                        f"free; the checkpoint needs about {need:,} B)")
    try:
        with atomic_path(path) as tmp, h5py.File(tmp, "w") as f:
            for group, values in attrs.items():
                target = f.require_group(group) if group else f
                for key, value in values.items():
                    target.attrs[key] = value
            for name, arr in data.items():
                f.create_dataset(name, data=arr)
            f.attrs[CHECKSUM] = digest(f)
    except RuntimeError as exc:  # (h5py's for a failed write: errno 28 inside its text)
        full = "No space left" in str(exc) or "errno = 28" in str(exc)
        raise OutputError(errno.ENOSPC if full else errno.EIO,
                          f"cannot write {path}: "
                          + ("the disk is full" if full else str(exc).splitlines()[0])) from None
    return path


def check_restart_path(path: Path | str) -> None:
    """Refuse (:class:`CaseError`, one line) a ``--restart`` path that is not a file: what
    ``impactsph run`` checks before its preflight, without reading the checkpoint."""
    path = Path(path)
    if not path.is_file():
        raise CaseError(f"--restart {path}: " + ("is not a file" if path.exists()
                                                 else "does not exist"))


#: the checksums this process has verified, by file (:func:`_file_key`)
_VERIFIED: dict[tuple[str, int, int, int], str] = {}


def _file_key(path: Path) -> tuple[str, int, int, int]:
    """A file's identity and version: its resolved path, inode, size and modification time
    (ns); a checkpoint written again (renamed into place) is a new key."""
    stat = path.stat()
    return (str(path.resolve()), stat.st_ino, stat.st_size, stat.st_mtime_ns)


def verify_checkpoint(path: Path | str, case: Any = None) -> float:
    """Refuse (:class:`CaseError`, one line naming the file) a checkpoint that is missing,
    unreadable, truncated, corrupted (its checksum does not match), not impactsph's, or, with
    ``case``, of another case (it may differ only in ``time.end`` and ``output``).  Reads the
    whole file; nothing is built.  Returns the checkpoint's time (s)."""
    path = Path(path)
    check_restart_path(path)
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise CaseError(f"--restart {path}: cannot be read as a checkpoint (truncated, or not "
                        f"an HDF5 file: {exc})") from None
    with f:
        try:
            form, stored = f.attrs.get("format"), f.attrs.get(CHECKSUM)
            # (a file this process has verified already, unchanged since: impactsph run
            # verifies before its preflight, run_case again; a resumed sweep's run likewise)
            seen = _file_key(path)
            actual = (_VERIFIED.get(seen) if stored is not None else None) \
                or (digest(f) if form == FORMAT else None)
            time = float(f.attrs["time"]) if form == FORMAT else None
        except Exception as exc:  # noqa: BLE001 (h5py reports damage in many ways)
            raise CaseError(f"--restart {path}: corrupted: cannot be read ({exc}); it cannot "
                            "be used") from None
        if form != FORMAT:
            raise CaseError(f"--restart {path}: not an impactsph checkpoint")
        if stored is None:
            log.warning("%s: a checkpoint without a checksum (written by an older version); "
                        "read unverified", path)
        elif stored != actual:
            raise CaseError(f"--restart {path}: corrupted: its contents do not match the "
                            f"checksum it was written with (SHA-256 {actual[:12]}..., stored "
                            f"{str(stored)[:12]}...); it cannot be used")
        else:
            _VERIFIED[seen] = actual
        if case is not None:
            try:
                stored_case = _stored_case(f)
            except (KeyError, ValueError) as exc:
                raise CaseError(f"--restart {path}: its case cannot be read ({exc})") from None
            _check_same_case(path, case, stored_case)
            if case.time.end < time:
                raise CaseError(f"--restart {path}: time.end = {case.time.end:g} is before the "
                                f"checkpoint's time, t = {time:g} s; a restart runs forward "
                                f"only (a later time.end extends the run)")
    return time


def _stored_case(f: h5py.File) -> Any:
    """The checkpoint's case, validated.  A checkpoint written before 0.3 has no
    ``added_mass``: that version carried a tip mass in the particle masses, so its tip masses
    read as ``carried_as = "particle_mass"``."""
    data = json.loads(f.attrs["case"])
    if "state" in f and "added_mass" not in f["state"]:
        for body in data.get("bodies", []):
            if body.get("tip_mass") is not None:
                body["tip_mass"].setdefault("carried_as", "particle_mass")
    return validate_case(data)


def _comparable(case: dict[str, Any]) -> dict[str, Any]:
    """A dumped case (``model_dump(mode="json")``, or ``case.json``'s) without what a
    restart may change: the end time, the thread count (the results are the same bits at
    any count) and the outputs but the probes (whose samples from the start the checkpoint
    carries by name and order)."""
    kept = {k: v for k, v in case.items() if k not in ("time", "output", "compute")}
    kept["time"] = {k: v for k, v in case.get("time", {}).items() if k != "end"}
    kept["compute"] = {k: v for k, v in case.get("compute", {}).items() if k != "threads"}
    kept["output"] = {"probes": case.get("output", {}).get("probes")}
    return kept


def _shown(differ: list[str]) -> str:
    return ", ".join(differ[:4]) + (f" and {len(differ) - 4} more" if len(differ) > 4 else "")


def _check_same_case(path: Path, case: Any, stored: Any) -> None:
    differ = case_differences(_comparable(case.model_dump(mode="json")),
                              _comparable(stored.model_dump(mode="json")))
    if differ:
        raise CaseError(f"--restart {path}: the case differs from the checkpoint's in "
                        f"{_shown(differ)} (only time.end, compute.threads and output but its "
                        f"probes may change)")


def check_restart_out(out: Path | str, case: Any) -> None:
    """Refuse (:class:`OutputError`, one line) a restart's ``--out`` that holds something
    other than this case's run: a directory that holds files but no ``case.json``, or
    another case's run (their outputs mixed, the other run's figures beside this one's
    history, before 2026-12-08)."""
    import errno

    out = Path(out)
    if not out.is_dir() or not any(p.name != ".lock" for p in out.iterdir()):
        return
    record = out / "case.json"
    try:
        held = json.loads(record.read_text())["case"]
    except FileNotFoundError:
        raise OutputError(errno.EEXIST, f"--out {out} holds files but no run (no case.json): "
                                        f"a restart writes into its own run's directory or an "
                                        f"empty one") from None
    except (OSError, ValueError, KeyError, TypeError) as exc:
        raise OutputError(errno.EEXIST, f"--out {out}: its case.json cannot be read "
                                        f"({type(exc).__name__}: {exc})") from None
    try:  # (validated, as the checkpoint's case is: an older version's case.json lacks
        held = validate_case(held).model_dump(mode="json")  # the fields added since)
    except CaseError:
        pass  # (compared as it is: a case that no longer validates differs anyway)
    differ = case_differences(_comparable(case.model_dump(mode="json")), _comparable(held))
    if differ:
        raise OutputError(errno.EEXIST, f"--out {out} holds another run (its case.json "
                                        f"differs in {_shown(differ)}): a restart writes into "
                                        f"its own run's directory or an empty one")


def case_differences(a: Any, b: Any, where: str = "") -> list[str]:
    """The dotted keys where two dumped cases differ (a list or a value as a whole)."""
    if isinstance(a, dict) and isinstance(b, dict):
        out: list[str] = []
        for key in sorted(set(a) | set(b), key=str):
            out += case_differences(a.get(key), b.get(key), f"{where}.{key}" if where else key)
        return out
    return [] if a == b else [where]


def accumulators(sim: Simulation) -> dict[str, Any]:
    """Run-wide running totals that the next steps add to."""
    i, s = sim.integrator, sim.solver
    return {
        "viscous_dissipation": sim.viscous_dissipation,
        "correction_work": sim.correction_work,
        "correction_heating": sim.correction_heating,
        "wall_impulse": sim.wall_impulse,
        "constraint_impulse": i.constraint_impulse,
        "constraint_events": i.constraint_events,
        "clamp_impulse": i.clamp_impulse,
        "pair_evaluations": s.pair_evaluations,
        "rate_evaluations": s.rate_evaluations,
        "abs_momentum0": sim._abs_momentum0,
        "max_displacement": sim.max_displacement,
        # the driven regions' supports (zeros without any)
        "driven_impulse": (i.drivers.impulse if i.drivers is not None
                           else np.zeros(sim.state.dim)),
        "driven_work": i.drivers.work if i.drivers is not None else 0.0,
    }


def _material_state_now(path: Path, stored: np.ndarray, width: int,
                        common: str | None) -> np.ndarray:
    """The stored material state in today's column layout, ``width`` columns (the case's:
    :meth:`~impactsph.materials.TableLayout.state_width_of`).  Checkpoints of 0.2.0 written
    before the thickness ratio joined the common state (no ``common_state`` attribute, one
    column short of the registered width) get the ratio 1 inserted; checkpoints written
    before the state was sized to the case's models (the registered width) lose the trailing
    columns that no model of the case uses; any other difference is refused."""
    registered = TableLayout.registered().state_width
    if common is None and stored.shape[1] == registered - 1:
        stored = np.insert(stored, THICKNESS_RATIO, 1.0, axis=1)
    if stored.shape[1] == width:
        return stored
    if width < stored.shape[1] == registered:
        return np.ascontiguousarray(stored[:, :width])
    raise CaseError(f"--restart {path}: its material state has {stored.shape[1]} columns, "
                    f"this version's case needs {width}; continue it with the version that "
                    "wrote it")


def load_checkpoint(path: Path | str, case: Any = None, *, verify: bool = True
                    ) -> Simulation:
    """A :class:`Simulation` continued from a checkpoint.  ``case`` (validated) may differ
    from the stored one only in ``time.end`` and ``output``.  The file is first checked by
    :func:`verify_checkpoint` (``verify=False``: the caller has just done so)."""
    path = Path(path)
    if verify:
        verify_checkpoint(path, case)
    try:
        f = h5py.File(path, "r")
    except OSError as exc:
        raise CaseError(f"--restart {path}: cannot be read as a checkpoint ({exc})") from None
    with f:
        if f.attrs.get("format") != FORMAT:
            raise CaseError(f"--restart {path}: not an impactsph checkpoint")
        stored = _stored_case(f)
        old_masses = "added_mass" not in f["state"]
        if case is None:
            case = stored
        else:
            for k, (given, kept) in enumerate(zip(case.bodies, stored.bodies, strict=False)):
                if (old_masses and given.tip_mass is not None and kept.tip_mass is not None
                        and given.tip_mass.carried_as != kept.tip_mass.carried_as):
                    raise CaseError(
                        f"--restart {path}: this checkpoint carries bodies.{k}.tip_mass in "
                        f"the particle masses (written before 0.3); set bodies.{k}.tip_mass."
                        f"carried_as = \"particle_mass\" in the case to continue it")
            _check_same_case(path, case, stored)
        arrays = {name: f["state"][name][()] for name in f["state"]}
        problem = build_problem(case)
        arrays["material_state"] = _material_state_now(
            path, arrays["material_state"], problem.state.material_state.shape[1],
            f["state"].attrs.get("common_state"))
        state = ParticleState(**arrays, time=float(f.attrs["time"]),
                              step=int(f.attrs["step"]),
                              viscosity_factor_time=float(f.attrs.get("viscosity_factor_time",
                                                                      f.attrs["time"])))
        sim = Simulation(case, problem=problem, state=state)
        g = f["neighbours"]
        offsets, indices = g["offsets"][()], g["indices"][()]
        # the inner list, where written (without one the passes read the whole list): each
        # row's first entries, or (a checkpoint written before 2026-12-07) a list of its own,
        # whose entries are moved to their rows' starts as a build now puts them
        inner = {}
        if "inner_ends" in g:
            inner["inner_ends"] = g["inner_ends"][()]
        elif "inner_offsets" in g:
            indices, inner["inner_ends"] = inner_entries_first(
                offsets, indices, g["inner_offsets"][()], g["inner_indices"][()])
        if inner:
            inner["inner_reach"] = float(g.attrs["inner_reach"])
            inner["inner_radius"] = float(g.attrs["inner_radius"])
        nl = NeighbourList(offsets, indices, float(g.attrs["radius"]),
                           float(g.attrs["skin"]), g["reference_positions"][()],
                           int(g.attrs["builds"]),
                           order=g["order"][()] if "order" in g else None,
                           reference_origin=(g["reference_origin"][()]
                                             if "reference_origin" in g else None),
                           # (a 2D or 3D checkpoint written before the rows were split: the passes
                           # test whole rows, the same pairs at round-off)
                           splits=g["splits"][()] if "splits" in g else None, **inner)
        sim.solver.restore(state, nl, g["ghost_src"][()], g["ghost_wall"][()])
        # read by name: datasets of older checkpoints that nothing reads any more (their
        # initial_kinetic, initial_internal, initial_momentum) are ignored
        acc = {name: f["accumulators"][name][()] for name in f["accumulators"]}
        sim.viscous_dissipation = float(acc["viscous_dissipation"])
        sim.correction_work = float(acc["correction_work"])
        sim.correction_heating = float(acc["correction_heating"])
        sim.wall_impulse = np.array(acc["wall_impulse"])
        sim.integrator.constraint_impulse = np.array(acc["constraint_impulse"])
        sim.integrator.constraint_events = int(acc["constraint_events"])
        sim.integrator.clamp_impulse = np.array(acc["clamp_impulse"])
        sim.solver.pair_evaluations = int(acc["pair_evaluations"])
        sim.solver.rate_evaluations = int(acc["rate_evaluations"])
        sim._abs_momentum0 = float(acc["abs_momentum0"])
        if sim.integrator.drivers is not None and "driven_work" in acc:
            sim.integrator.drivers.impulse = np.array(acc["driven_impulse"], dtype=np.float64)
            sim.integrator.drivers.work = float(acc["driven_work"])
        if "max_displacement" in acc:  # not in the checkpoints of earlier versions
            sim.max_displacement = np.array(acc["max_displacement"], dtype=np.float64)
        else:  # the largest displacement now, the best an older checkpoint tells
            from .simulation import body_totals

            sim.max_displacement = np.sqrt(body_totals(
                state.body, state.mass, state.inertial_mass, state.velocity,
                state.specific_energy,
                state.plastic_work, state.position, state.initial_position,
                len(sim.problem.body_names))[:, 3])
        rec = f["record"]
        columns = json.loads(rec.attrs["history_columns"])
        sim.record.history = [dict(zip(columns, map(float, row), strict=True))
                              for row in rec["history"][()]]
        for row in sim.record.history:
            row["step"] = int(row["step"])
        for name in json.loads(rec.attrs["probe_names"]):
            p = rec[f"probe_{name}"]
            sim.record.probes[name] = list(zip(p["time"][()].tolist(), list(p["velocity"][()]),
                                               strict=True))
        # the gauges' rows, when the checkpoint's gauges are the case's (a gauge added on
        # restart records from the restart on)
        if (sim.gauges is not None and "gauges" in rec
                and json.loads(rec.attrs["gauge_columns"]) == sim.gauges.columns):
            sim.record.gauges = list(rec["gauges"][()])
        sim.record.snapshots = []
        for k in range(int(rec.attrs["n_snapshots"])):
            group = rec[f"snapshot_{k}"]
            names = (json.loads(group.attrs["fields"]) if "fields" in group.attrs
                     else list(group))  # (a checkpoint before 2026-12-08: by name)
            sim.record.snapshots.append(Snapshot(float(group.attrs["time"]),
                                                 {n: group[n][()] for n in names}))
        sim.record.wall_seconds = float(rec.attrs["wall_seconds"])
        # (a checkpoint written before runs counted their compile time: none counted)
        sim.record.compile_seconds = float(rec.attrs.get("compile_seconds", 0.0))
        sim.record.setup_seconds = float(rec.attrs["setup_seconds"])
        # (written since 2026-12-08: before, a restarted run's summary lost them)
        sim.record.thread_changes = [tuple(c) for c in
                                     json.loads(rec.attrs.get("thread_changes", "[]"))]
        sim.record.thread_trials = list(json.loads(rec.attrs.get("thread_trials", "[]")))
        sim.record.restarts = [*json.loads(rec.attrs.get("restarts", "[]")), {
            "checkpoint": str(path.resolve()), "time": sim.state.time, "step": sim.state.step,
            "impactsph": str(f.attrs.get("impactsph", "unknown")),
            "continued_by": __version__}]
    return sim
