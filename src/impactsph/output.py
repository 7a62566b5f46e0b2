"""Run outputs: files written atomically (:mod:`.atomic`), read back by
:func:`load_run`, so figures can always be redrawn from a run directory.

A run directory holds:

- ``case.json``: the fully resolved case (every default filled in) and the impactsph version;
- ``history.csv``: one row per recorded step (time, energies, momentum, contact forces);
- ``probes.csv``: the velocity of each probe particle at every step;
- ``gauges.csv``: the fields of each gauge's material point at every step (with gauges);
- ``run.log``: the run's log lines (:mod:`impactsph.runlog`);
- ``snapshots.npz``: the particle fields at each snapshot time;
- ``summary.json``: run-wide numbers and the problem's metrics, and the run's ``status``;
- ``checkpoint.h5``: where the run can continue from (:mod:`.checkpoint`), when it has one;
- ``*.png``: the problem's figures.

``history.csv`` and ``probes.csv`` grow as the run goes (:class:`HistoryStream`: appended
and flushed as rows are recorded), and are written whole, atomically, at the end; the other
files are only ever replaced whole (:mod:`.atomic`).  ``summary.json`` is written when the run
starts, at each checkpoint (``status`` ``running``) and at the end (``finished``,
``interrupted``, ``unstable`` or ``out_of_memory``); see :data:`STATUSES`.
"""

from __future__ import annotations

import contextlib
import csv
import io
import json
import os
import platform
from pathlib import Path
from typing import Any

import numpy as np

from ._version import __version__
from .atomic import output_error, write_bytes, write_text

#: ``summary.json``'s ``status``: ``running`` (written when the run starts and at each
#: checkpoint: ``t_end`` and ``n_steps`` are the time and step reached), ``interrupted``
#: (stopped on request after a whole step; continue from ``checkpoint``), ``unstable``
#: (stopped by an instability; ``failure`` says where), ``out_of_memory`` (the GPU ran out
#: of memory; ``failure`` says where and what the run held on it), ``finished``
STATUSES = ("running", "interrupted", "unstable", "out_of_memory", "finished")

#: :func:`.atomic.write_text`, under the name paper.py and sweep.py import from here
atomic_write_text = write_text


def provenance() -> dict[str, Any]:
    """Version information recorded in every output, and the registered models (by the module
    that defines each: a model of one's own shows where it came from)."""
    import numba

    from .models import EOS, STRENGTH, VISCOSITY
    from .physics.options import parallel_default
    from .vectors import cpu_name, vector_width

    def where(model: Any) -> str:
        f = getattr(model, "pressure", None) or getattr(model, "return_map", None) or getattr(
            model, "pair_viscosity", None)
        return getattr(f, "__module__", "") if f is not None else ""

    return {"impactsph": __version__, "numpy": np.__version__, "numba": numba.__version__,
            "python": platform.python_version(),
            # the passes compiled with numba's threads or serial ($IMPACTSPH_PARALLEL): the
            # same results to the bit (tests/test_parallel_passes.py)
            "parallel_passes": parallel_default(),
            # the vectors the compiled loops were built for (impactsph.vectors): the last
            # digits of a vectorised sum depend on their width
            "cpu": cpu_name(), "vectors": vector_width(),
            "models": {kind: {m.name: where(m) or "impactsph" for m in registry}
                       for kind, registry in (("eos", EOS), ("strength", STRENGTH),
                                              ("viscosity", VISCOSITY))}}


def _csv_text(rows: list[dict[str, Any]], header: bool = True) -> str:
    """``rows`` as CSV, floats written exactly (``repr``); with ``header``, preceded by the
    line of the first row's keys."""
    buf = io.StringIO()
    if rows:
        writer = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
        if header:
            writer.writeheader()
        for r in rows:
            writer.writerow({k: repr(v) if isinstance(v, float) else v for k, v in r.items()})
    return buf.getvalue()


def write_case(out: Path, case: Any) -> None:
    """``case.json``: the resolved case and the versions that produced the run."""
    write_text(out / "case.json", json.dumps(
        {"provenance": provenance(), "case": case.model_dump(mode="json")}, indent=2))


def _probe_rows(sim: Any, start: int = 0) -> list[dict[str, Any]]:
    """The rows of ``probes.csv`` from the ``start``-th sample on."""
    dims = "xyz"[: sim.case.dimension]  # not sim.state: no download of a GPU state
    rows = []
    probes = sim.record.probes
    if probes:
        names = list(probes)
        for k in range(start, len(probes[names[0]])):
            row: dict[str, Any] = {"time": probes[names[0]][k][0]}
            for name in names:
                for a, d in enumerate(dims):
                    row[f"{name}_v{d}"] = float(probes[name][k][1][a])
            rows.append(row)
    return rows


def _probe_samples(sim: Any) -> int:
    probes = sim.record.probes
    return len(next(iter(probes.values()))) if probes else 0


def _gauge_rows(sim: Any, start: int = 0) -> list[dict[str, Any]]:
    """The rows of ``gauges.csv`` from the ``start``-th on."""
    from .gauges import gauge_rows

    gauges = getattr(sim, "gauges", None)
    return [] if gauges is None else gauge_rows(gauges.columns, sim.record.gauges, start)


def write_history(out: Path, sim: Any) -> None:
    """``history.csv``, ``probes.csv`` and (with gauges) ``gauges.csv`` as far as the run
    has got, each written whole."""
    write_text(out / "history.csv", _csv_text(sim.record.history))
    write_text(out / "probes.csv", _csv_text(_probe_rows(sim)))
    if getattr(sim, "gauges", None) is not None:
        write_text(out / "gauges.csv", _csv_text(_gauge_rows(sim)))


def _plain_row(fields: list[str], row: dict[str, Any]) -> str | None:
    """The CSV line of ``row``'s ``fields`` (``nan`` for one it lacks) where every value is a
    ``float`` (written by ``repr``) or an ``int``: the text :class:`csv.DictWriter` writes,
    without its per-row dictionary; None for a row with any other value."""
    cells = []
    for k in fields:
        v = row.get(k, "nan")
        kind = type(v)
        if kind is float or kind is int:
            cells.append(repr(v))
        elif v == "nan" and kind is str:
            cells.append(v)
        else:
            return None
    return ",".join(cells) + "\n"


class HistoryStream:
    """``history.csv``, ``probes.csv`` and ``gauges.csv`` (with gauges) written while a run
    goes: created with the rows
    recorded so far (a restarted run's, from its checkpoint), then appended and flushed to the
    operating system by :meth:`update` whenever the run has recorded more, so a run that is
    killed leaves every row up to its last step; :meth:`close` flushes them to disk (fsync).
    The text is :func:`write_history`'s, byte for byte.

    Rows are not fsynced one by one: those the operating system had not yet stored are lost
    in a power cut (the checkpoints, fsynced, are not)."""

    def __init__(self, out: Path, sim: Any) -> None:
        self.out = Path(out)
        write_history(self.out, sim)
        self._names = ("history.csv", "probes.csv") + (
            ("gauges.csv",) if getattr(sim, "gauges", None) is not None else ())
        self._done = {"history.csv": len(sim.record.history),
                      "probes.csv": _probe_samples(sim), "gauges.csv": len(sim.record.gauges)}
        # the columns of a file that already has rows (a restarted run's): rows of a later
        # version with more columns keep to that header
        self._fields = {"history.csv": list(sim.record.history[0])
                        if sim.record.history else None}
        self._files: dict[str, Any] = {}
        self._buffers = {name: io.StringIO() for name in self._names}
        self._writers: dict[str, csv.DictWriter] = {}
        for name in self._names:
            try:
                self._files[name] = open(self.out / name, "ab")  # noqa: SIM115 (see close)
            except OSError as exc:
                self.close()
                raise output_error(exc, self.out / name) from exc

    def _append(self, name: str, rows: list[dict[str, Any]]) -> None:
        buf = self._buffers[name]
        writer = self._writers.get(name)
        if writer is None:
            fields = self._fields.get(name) if self._done[name] else None
            writer = self._writers[name] = csv.DictWriter(
                buf, fieldnames=fields or list(rows[0]), lineterminator="\n",
                extrasaction="ignore", restval="nan")
            if self._done[name] == 0:
                writer.writeheader()
        fields = writer.fieldnames
        lines = []
        for r in rows:
            line = _plain_row(fields, r)
            if line is None:  # a value that csv may quote: its writer
                writer.writerow({k: repr(v) if isinstance(v, float) else v
                                 for k, v in r.items()})
                lines.append(buf.getvalue())
                buf.seek(0)
                buf.truncate()
            else:
                lines.append(line)
        try:
            fh = self._files[name]
            fh.write((buf.getvalue() + "".join(lines)).encode())
            fh.flush()
        except OSError as exc:
            raise output_error(exc, self.out / name) from exc
        buf.seek(0)
        buf.truncate()

    def update(self, sim: Any) -> None:
        """Append the rows recorded since the last call."""
        history = sim.record.history
        done = self._done["history.csv"]
        if len(history) > done:
            self._append("history.csv", history[done:])
            self._done["history.csv"] = len(history)
        samples = _probe_samples(sim)
        done = self._done["probes.csv"]
        if samples > done:
            self._append("probes.csv", _probe_rows(sim, done))
            self._done["probes.csv"] = samples
        if "gauges.csv" in self._names:
            done = self._done["gauges.csv"]
            if len(sim.record.gauges) > done:
                self._append("gauges.csv", _gauge_rows(sim, done))
                self._done["gauges.csv"] = len(sim.record.gauges)

    def close(self, sync: bool = True) -> None:
        """Close the files (with ``sync``, after storing them on disk); the text appended
        so far stays.  Calling it again does nothing."""
        files, self._files = self._files, {}
        for name, fh in files.items():
            try:
                if sync:
                    fh.flush()
                    os.fsync(fh.fileno())
                fh.close()
            except OSError as exc:
                with contextlib.suppress(OSError):
                    fh.close()
                raise output_error(exc, self.out / name) from exc


def write_snapshots(out: Path, sim: Any) -> None:
    """``snapshots.npz``: ``times`` and ``s{k}_{field}`` for snapshot ``k``."""
    arrays: dict[str, np.ndarray] = {
        "times": np.array([s.time for s in sim.record.snapshots])}
    for k, snap in enumerate(sim.record.snapshots):
        for name, arr in snap.fields.items():
            arrays[f"s{k}_{name}"] = arr
    buf = io.BytesIO()
    np.savez_compressed(buf, **arrays)
    write_bytes(out / "snapshots.npz", buf.getvalue())


def json_text(value: Any, indent: int | None = 2) -> str:
    """``value`` as strict JSON: a number that is not finite (a measure that could not be
    taken, a run that went unstable) becomes ``null``, as JSON has no NaN nor infinity
    (Python's ``json`` would write ``NaN``, which other readers refuse); numpy's numbers are
    written as JSON numbers (its integers and booleans as floats, as before).  What every
    JSON output of a run, a sweep, the lab and the paper's tables is written with."""
    return json.dumps(finite_or_null(value), indent=indent, allow_nan=False, default=float)


def finite_or_null(value: Any) -> Any:
    """``value`` with each float that is not finite replaced by None, in dicts, lists and
    tuples at any depth (numpy's floats and 0-d arrays included): a measure not taken as
    ``summary.json`` holds it (``null``), for the rows made from a summary in memory."""
    if isinstance(value, dict):
        return {k: finite_or_null(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [finite_or_null(v) for v in value]
    if isinstance(value, float | np.floating) or (isinstance(value, np.ndarray)
                                                   and value.ndim == 0):
        number = float(value)
        return number if np.isfinite(number) else None
    return value


def write_study(path: Path | str, result: Any) -> Path:
    """A study's JSON (a validation or benchmark script's): ``result`` (a dict, or a list of
    rows, kept under ``rows``) after the :func:`provenance` and the command that made it
    (``sys.argv``, its options included), as every run's outputs record theirs; strict JSON
    (:func:`json_text`), written atomically."""
    import shlex
    import sys

    body = result if isinstance(result, dict) else {"rows": result}
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_text(path, json_text({"provenance": provenance(), "command": shlex.join(sys.argv),
                                **body}) + "\n")
    return path


def write_summary(out: Path | str, summary: dict[str, Any]) -> None:
    """``summary.json``: ``summary`` and the provenance (strict JSON: :func:`json_text`).
    The only writer of that file, for runs and for the runs of a sweep (which add the
    case)."""
    write_text(Path(out) / "summary.json",
               json_text({**summary, "provenance": provenance()}))


def read_csv(path: Path) -> dict[str, np.ndarray]:
    """A CSV written by this module, as columns of floats."""
    with open(path, newline="") as fh:
        rows = list(csv.DictReader(fh))
    if not rows:
        return {}
    return {k: np.array([float(r[k]) for r in rows]) for k in rows[0]}


def load_run(path: Path) -> dict[str, Any]:
    """Everything a run directory holds, as plain Python and numpy objects."""
    path = Path(path)
    run: dict[str, Any] = {"path": path}
    with open(path / "case.json") as fh:
        run["case"] = json.load(fh)["case"]
    run["history"] = read_csv(path / "history.csv")
    run["probes"] = read_csv(path / "probes.csv") if (path / "probes.csv").exists() else {}
    run["gauges"] = read_csv(path / "gauges.csv") if (path / "gauges.csv").exists() else {}
    if (path / "summary.json").exists():
        with open(path / "summary.json") as fh:
            run["summary"] = json.load(fh)
    snaps = []
    if (path / "snapshots.npz").exists():
        with np.load(path / "snapshots.npz") as data:
            for k, t in enumerate(data["times"]):
                prefix = f"s{k}_"
                snaps.append({"time": float(t), **{key[len(prefix):]: data[key]
                                                   for key in data.files
                                                   if key.startswith(prefix)}})
    run["snapshots"] = snaps
    return run
