"""Parameter sweeps: the paper's "numerical experiment", run in parallel with Dask.

A grid is given as ``KEY=V1,V2,...``; several grids make a Cartesian product, and
``KEY1,KEY2=V1,V2,...`` ties keys to the same value (``alpha1 = alpha2``)::

    impactsph sweep bars --grid viscosity.alpha1,viscosity.alpha2=0.05,0.1,0.2,0.3
    impactsph sweep bars --grid viscosity.alpha1=0 --grid viscosity.alpha2=0.5,1,1.5,2

The table's columns and the finding are the case's problem's (:mod:`impactsph.problems`):
the kinetic energy kept, the problem's own columns, the conservation errors and the cost; and,
for a problem with a sweep criterion (the bars: a profile free of spurious oscillation), the
smallest value of the first grid parameter that meets it.

Each run is a task on a Dask cluster: a local one (one single-threaded worker process per
core) by default, or an existing one given its scheduler address.  A run that fails is
retried; a run whose directory already holds a finished summary of the same case is not run
again, so an interrupted sweep restarts where it stopped.  The table ``sweep.csv`` is
rewritten (atomically) as runs finish.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import logging
import os
from pathlib import Path
from typing import Any

import numpy as np

from .config import Case, CaseError
from .loading import apply_overrides, read_case_dict, validate_case
from .output import _csv_text, atomic_write_text, write_summary
from .problems.base import SweepCriterion
from .problems.registry import get_problem

log = logging.getLogger("impactsph.sweep")


def table_keys(case: Case) -> tuple[str, ...]:
    """The summary entries a sweep's table gives for runs of ``case``: the kinetic energy
    kept, the problem's columns (:meth:`~impactsph.problems.ProblemKind.table_keys`), the
    conservation errors and the cost."""
    return ("kinetic_energy_ratio_final", *get_problem(case.analysis).table_keys(case),
            "total_energy_relative_error", "momentum_drift", "energy_imbalance",
            "n_steps", "wall_seconds")


def parse_grid(specs: list[str]) -> tuple[list[str], list[list[tuple[str, Any]]]]:
    """Grid specifications -> (column names, list of runs as ``[(key, value), ...]``)."""
    axes: list[list[list[tuple[str, Any]]]] = []
    columns: list[str] = []
    for spec in specs:
        if "=" not in spec:
            raise CaseError(f"--grid {spec!r}: expected KEY=V1,V2,... e.g. "
                            f"viscosity.alpha1=0.1,0.2")
        keys_text, values_text = spec.split("=", 1)
        keys = [k.strip() for k in keys_text.split(",") if k.strip()]
        values = []
        for raw in values_text.split(","):
            raw = raw.strip()
            try:
                values.append(json.loads(raw))
            except json.JSONDecodeError:
                values.append(raw)
        if not keys or not values or any(v == "" for v in values):
            raise CaseError(f"--grid {spec!r}: needs at least one key and one value")
        columns += keys
        axes.append([[(k, v) for k in keys] for v in values])
    runs = [[kv for group in combo for kv in group] for combo in itertools.product(*axes)]
    return columns, runs


def run_id(overrides: list[str]) -> str:
    """A short stable name for a parameter set."""
    return hashlib.sha1("\n".join(overrides).encode()).hexdigest()[:12]


def run_one(case_data: dict[str, Any], overrides: list[str], out: str) -> dict[str, Any]:
    """Run one case of a sweep (executed on a Dask worker) and return its table row."""
    import numba

    from .runner import run_case
    from .simulation import SimulationError

    numba.set_num_threads(1)
    case = validate_case(apply_overrides(case_data, overrides))
    keys = table_keys(case)
    summary_path = Path(out) / "summary.json"
    if summary_path.exists():
        done = json.loads(summary_path.read_text())
        # a run's summary is written from its start on: reuse only a run that ended (a
        # summary without a status is an older version's, written at the end)
        if (done.get("case") == case.model_dump(mode="json")
                and done.get("status", "finished") in ("finished", "unstable")):
            return {"status": "ok" if not done.get("failure") else "unstable",
                    **{k: done.get(k) for k in keys}, "reused": True}
    try:
        summary = run_case(case, out, figures=False)
        status = "ok"
    except SimulationError as exc:
        summary = json.loads(summary_path.read_text())
        status = f"unstable: {exc}"
    summary["case"] = case.model_dump(mode="json")
    write_summary(out, summary)
    return {"status": status, **{k: summary.get(k) for k in keys}, "reused": False}


def run_many(base: dict[str, Any], run_overrides: list[list[str]], out: Path, *,
             scheduler: str | None = None, workers: int | None = None,
             on_result: Any = None) -> list[dict[str, Any]]:
    """Run the case ``base`` once per override list on a Dask cluster; each run writes into
    ``out/runs/<id>``.  Returns one row per run, in the order given; ``on_result(i, row)`` is
    called as runs finish."""
    from distributed import Client, LocalCluster, as_completed

    for name in ("distributed", "distributed.nanny", "distributed.scheduler",
                 "distributed.worker", "distributed.core", "distributed.http.proxy"):
        logging.getLogger(name).setLevel(logging.WARNING)
    cases = [validate_case(apply_overrides(base, ov))  # validate every run before any starts
             for ov in run_overrides]
    if not scheduler:  # fill numba's disk cache once, before the workers start together
        from .simulation import compile_kernels

        seen = set()
        for case in cases:  # once per set of compile-time options
            key = (case.dimension, case.stabilisation.model_dump_json(),
                   case.contact.model_dump_json(), case.kernel.model_dump_json())
            if key not in seen:
                seen.add(key)
                compile_kernels(case.dimension, case)
    rows: dict[int, dict[str, Any]] = {}
    cluster = None
    if scheduler:
        client = Client(scheduler)
    else:
        cluster = LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                               processes=True, dashboard_address=None)
        client = Client(cluster)
    try:
        futures = {}
        for i, ov in enumerate(run_overrides):
            rid = run_id(ov)
            fut = client.submit(run_one, base, ov, str((out / "runs" / rid).resolve()),
                                key=f"impactsph-{rid}", retries=3, pure=False)
            futures[fut] = (i, rid)
        for fut in as_completed(list(futures)):
            i, rid = futures[fut]
            try:
                result = fut.result()
            except Exception as exc:  # a run that failed on every try
                result = {"status": f"failed: {exc}"}
            rows[i] = {"run": rid, **result}
            log.info("run %s: %s", rid, result.get("status"))
            if on_result is not None:
                on_result(i, rows[i])
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
    return [rows[i] for i in sorted(rows)]


def sweep(case_source: str, grids: list[str], out: Path | str, *, scheduler: str | None = None,
          workers: int | None = None, overrides: list[str] | None = None,
          threshold: float | None = None) -> dict[str, Any]:
    """Run ``case_source`` over the grids; write ``sweep.csv``, ``sweep.json`` and
    ``sweep.png`` into ``out``.  Returns the result: the grid's ``columns``, the table's
    ``rows`` and the ``finding`` of the problem's sweep criterion (at ``threshold``, the
    criterion's own when None; the finding is None for a problem without a criterion)."""
    out = Path(out)
    base = apply_overrides(read_case_dict(case_source), overrides or [])
    criterion = get_problem(validate_case(base).analysis).sweep_criterion
    columns, runs = parse_grid(grids)
    run_overrides = [[f"{k}={json.dumps(v)}" for k, v in kv] + ["output.figures=false"]
                     for kv in runs]
    out.mkdir(parents=True, exist_ok=True)
    done: dict[int, dict[str, Any]] = {}

    def record(i: int, row: dict[str, Any]) -> None:
        done[i] = {**dict(runs[i]), **row}
        atomic_write_text(out / "sweep.csv", _csv_text([done[k] for k in sorted(done)]))

    run_many(base, run_overrides, out, scheduler=scheduler, workers=workers, on_result=record)
    table = [done[i] for i in sorted(done)]
    first = columns[0]
    finding = None
    if criterion is not None:
        passed = [r for r in table if criterion.passes(r, threshold)]
        finding = {
            "criterion": criterion.describe(threshold),
            "parameter": first,
            f"smallest_{criterion.name}": min((r[first] for r in passed), default=None),
        }
    result = {"columns": columns, "rows": table, "finding": finding}
    atomic_write_text(out / "sweep.json", json.dumps(result, indent=2, default=float))
    sweep_figure(table, columns, out / "sweep.png", criterion, threshold)
    return result


def sweep_figure(table: list[dict[str, Any]], columns: list[str], path: Path,
                 criterion: SweepCriterion | None = None, threshold: float | None = None
                 ) -> Path:
    """Kinetic energy kept against the first grid parameter, one line per value of the
    others, and beside it the column of the problem's sweep ``criterion`` (if any) with its
    ``threshold`` (the criterion's own when None)."""
    from .plotting import plt, save_figure

    first = columns[0]
    others = [c for c in columns[1:] if not all(r.get(c) == r.get(first) for r in table)]
    panels = [("kinetic_energy_ratio_final", "kinetic energy kept at the end")]
    if criterion is not None:
        panels.append((criterion.key, criterion.label))
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 4), squeeze=False)
    axes = list(axes[0])
    groups: dict[tuple, list[dict[str, Any]]] = {}
    for r in table:
        groups.setdefault(tuple(r.get(c) for c in others), []).append(r)
    for key, rs in groups.items():
        rs = sorted(rs, key=lambda r: r[first])
        x = [r[first] for r in rs]
        label = ", ".join(f"{c}={v}" for c, v in zip(others, key, strict=True)) or None
        for ax, (col, _) in zip(axes, panels, strict=True):
            y = [r.get(col) if r.get(col) is not None else np.nan for r in rs]
            ax.plot(x, y, "o-", label=label)
    for ax, (_, ylabel) in zip(axes, panels, strict=True):
        ax.set_ylabel(ylabel)
        ax.set_xlabel(first)
        ax.grid(alpha=0.3)
    if criterion is not None:
        axes[-1].axhline(criterion.threshold if threshold is None else threshold, color="k",
                         ls=":", label="criterion")
    if axes[-1].get_legend_handles_labels()[0]:
        axes[-1].legend()
    return save_figure(fig, path)
