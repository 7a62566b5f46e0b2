"""Run outputs: files written atomically (:mod:`.atomic`), read back by
:func:`load_run`, so figures can always be redrawn from a run directory.

A run directory holds:

- ``case.json``: the fully resolved case (every default filled in) and the impactsph version;
- ``history.csv``: one row per recorded step (time, energies, momentum, contact forces);
- ``probes.csv``: the velocity of each probe particle at every step;
- ``snapshots.npz``: the particle fields at each snapshot time;
- ``summary.json``: run-wide numbers and the problem's metrics;
- ``*.png``: the problem's figures.
"""

from __future__ import annotations

import csv
import io
import json
import platform
from pathlib import Path
from typing import Any

import numpy as np

from ._version import __version__
from .atomic import write_bytes, write_text

#: :func:`.atomic.write_text`, under the name paper.py and sweep.py import from here
atomic_write_text = write_text


def provenance() -> dict[str, Any]:
    """Version information recorded in every output, and the registered models (by the module
    that defines each: a model of one's own shows where it came from)."""
    import numba

    from .models import EOS, STRENGTH, VISCOSITY

    def where(model: Any) -> str:
        f = getattr(model, "pressure", None) or getattr(model, "return_map", None) or getattr(
            model, "pair_viscosity", None)
        return getattr(f, "__module__", "") if f is not None else ""

    return {"impactsph": __version__, "numpy": np.__version__, "numba": numba.__version__,
            "python": platform.python_version(),
            "models": {kind: {m.name: where(m) or "impactsph" for m in registry}
                       for kind, registry in (("eos", EOS), ("strength", STRENGTH),
                                              ("viscosity", VISCOSITY))}}


def _csv_text(rows: list[dict[str, Any]]) -> str:
    buf = io.StringIO()
    if rows:
        writer = csv.DictWriter(buf, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        for r in rows:
            writer.writerow({k: repr(v) if isinstance(v, float) else v for k, v in r.items()})
    return buf.getvalue()


def write_case(out: Path, case: Any) -> None:
    """``case.json``: the resolved case and the versions that produced the run."""
    write_text(out / "case.json", json.dumps(
        {"provenance": provenance(), "case": case.model_dump(mode="json")}, indent=2))


def write_history(out: Path, sim: Any) -> None:
    """``history.csv`` and ``probes.csv`` as far as the run has got."""
    write_text(out / "history.csv", _csv_text(sim.record.history))
    dims = "xyz"[: sim.state.dim]
    rows = []
    probes = sim.record.probes
    if probes:
        names = list(probes)
        for k in range(len(probes[names[0]])):
            row: dict[str, Any] = {"time": probes[names[0]][k][0]}
            for name in names:
                for a, d in enumerate(dims):
                    row[f"{name}_v{d}"] = float(probes[name][k][1][a])
            rows.append(row)
    write_text(out / "probes.csv", _csv_text(rows))


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


def write_summary(out: Path | str, summary: dict[str, Any]) -> None:
    """``summary.json``: ``summary`` and the provenance.  The only writer of that file, for
    runs and for the runs of a sweep (which add the case)."""
    write_text(Path(out) / "summary.json", json.dumps(
        {**summary, "provenance": provenance()}, indent=2, default=float))


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
