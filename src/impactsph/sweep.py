"""Parameter sweeps: the paper's "numerical experiment", run in parallel with Dask.

A grid is given as ``KEY=V1,V2,...``; several grids make a Cartesian product, and
``KEY1,KEY2=V1,V2,...`` ties keys to the same value (``alpha1 = alpha2``)::

    impactsph sweep bars --grid viscosity.alpha1,viscosity.alpha2=0.05,0.1,0.2,0.3
    impactsph sweep bars --grid viscosity.alpha1=0 --grid viscosity.alpha2=0.5,1,1.5,2

The table's columns and the finding are the case's problem's (:mod:`impactsph.problems`):
the kinetic energy kept, the problem's own columns, the conservation errors and the cost; and,
for a problem with a sweep criterion (the bars: a profile free of spurious oscillation), the
smallest value of the first grid parameter that varies that meets it.

Each run is a task on a Dask cluster: a local one (one single-threaded worker process per
core) by default, or an existing one given its scheduler address.  A run that fails is
retried; a run whose directory already holds a finished summary of the same case is not run
again, so an interrupted sweep restarts where it stopped.  The table ``sweep.csv`` is
rewritten (atomically) as runs finish.

Each run writes into ``OUT/runs/NAME``, its name built from its grid values
(:func:`run_names`: ``alpha1=0.3_alpha2=0.3``), with a short hash of its overrides added only
where two names would be the same or a name would be too long.  A run directory of an
earlier version (named by the hash alone, :func:`run_id`) that holds a summary is used
instead, so older sweeps still resume.

``metrics`` (``impactsph sweep --metric KEY``) adds any value of the runs' ``summary.json``
to the table, a dotted path for nested ones (``bodies.bar.max_displacement``,
``gauges.tip.max_displacement``), and draws each against the grid in ``sweep_KEY.png``.
"""

from __future__ import annotations

import hashlib
import itertools
import json
import logging
import math
import os
import re
from pathlib import Path
from typing import Any

import numpy as np

from .config import Case, CaseError
from .loading import apply_overrides, read_case_dict, validate_case
from .output import (
    _csv_text,
    atomic_write_text,
    finite_or_null,
    write_study,
    write_summary,
)
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
        for raw in _top_level_items(values_text):
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


def _top_level_items(text: str) -> list[str]:
    """``text`` split at the commas outside brackets and quotes: a grid of vectors,
    ``[0, -200],[0, -150]``, is two values (a plain split had cut them at every comma)."""
    items, depth, quote, start = [], 0, "", 0
    for k, char in enumerate(text):
        if quote:
            quote = "" if char == quote else quote
        elif char in "\"'":
            quote = char
        elif char in "[{":
            depth += 1
        elif char in "]}":
            depth -= 1
        elif char == "," and depth == 0:
            items.append(text[start:k])
            start = k + 1
    return [*items, text[start:]]


def run_id(overrides: list[str]) -> str:
    """A short stable name for a parameter set (the run directories' names before
    :func:`run_names`; still the Dask task's key)."""
    return hashlib.sha1("\n".join(overrides).encode()).hexdigest()[:12]


#: the longest run directory name built from the grid values (longer: cut, a hash added)
NAME_LENGTH = 80


def _sanitise(text: str) -> str:
    """``text`` with every character but letters, digits and ``. , + - = _`` replaced by
    ``-`` (runs of them by one), so that it is a portable file name."""
    return re.sub(r"[^A-Za-z0-9.,+=_-]+", "-", text).strip("-") or "run"


def _value_text(value: Any) -> str:
    """A grid value as short text: a number as the shortest form that reads back the same
    (``6e+08``, ``0.3``), a list's items joined by commas, other values as JSON."""
    if isinstance(value, bool):
        return json.dumps(value)
    if isinstance(value, int | float):
        short = f"{value:g}"
        return short if float(short) == value else repr(value)
    if isinstance(value, list):
        return ",".join(_value_text(v) for v in value)
    return value if isinstance(value, str) else json.dumps(value, separators=(",", ":"))


def run_names(runs: list[list[tuple[str, Any]]], overrides: list[list[str]]) -> list[str]:
    """Readable, unique directory names of a sweep's runs, from their grid values
    (``[(key, value), ...]`` each): ``alpha1=0.3_alpha2=0.3``, a key by its last dotted part
    unless two keys of the grid share it (then the whole key), a value as
    :func:`_value_text` writes it, other characters than letters, digits and ``. , + - = _``
    replaced by ``-``.  A name that two runs would share, or of :data:`NAME_LENGTH`
    characters or more, is cut there and gets ``-`` and 6 hex digits of the hash of that
    run's ``overrides`` (:func:`run_id`)."""
    keys = list(dict.fromkeys(k for kv in runs for k, _ in kv))
    tails = [k.rsplit(".", 1)[-1] for k in keys]
    short = {k: (t if tails.count(t) == 1 else k) for k, t in zip(keys, tails, strict=True)}
    names = ["_".join(_sanitise(f"{short[k]}={_value_text(v)}") for k, v in kv) or "run"
             for kv in runs]
    counts = {n: names.count(n) for n in names}
    return [f"{n[:NAME_LENGTH]}-{run_id(ov)[:6]}" if counts[n] > 1 or len(n) >= NAME_LENGTH
            else n for n, ov in zip(names, overrides, strict=True)]


def summary_value(summary: dict[str, Any], key: str) -> Any:
    """The value at the dotted path ``key`` of a summary (``bodies.bar.max_displacement``;
    a list's element by its index), or None; a key that holds dots itself is found too."""
    node: Any = summary
    rest = key
    while rest:
        if isinstance(node, dict) and rest in node:
            return node[rest]
        head, _, rest = rest.partition(".")
        if isinstance(node, dict) and head in node:
            node = node[head]
        elif isinstance(node, list) and head.isdecimal() and int(head) < len(node):
            node = node[int(head)]
        else:
            return None
    return node


def summary_keys(summary: dict[str, Any], prefix: str = "") -> list[str]:
    """Every dotted path of a summary that leads to a number (what ``--metric`` takes)."""
    keys = []
    for k, v in summary.items():
        if k == "provenance":
            continue
        path = f"{prefix}{k}"
        if isinstance(v, dict):
            keys += summary_keys(v, f"{path}.")
        elif isinstance(v, list) and all(isinstance(e, int | float) for e in v):
            keys += [f"{path}.{i}" for i in range(len(v))]
        elif isinstance(v, int | float) and not isinstance(v, bool):
            keys.append(path)
    return keys


def run_one(case_data: dict[str, Any], overrides: list[str], out: str,
            metrics: tuple[str, ...] | list[str] = ()) -> dict[str, Any]:
    """Run one case of a sweep (executed on a Dask worker) and return its table row: the
    problem's columns (:func:`table_keys`) and the summary values ``metrics`` (dotted
    paths, :func:`summary_value`)."""
    import numba

    from .errors import DeviceMemoryError
    from .runner import run_case
    from .simulation import SimulationError

    numba.set_num_threads(1)
    case = validate_case(apply_overrides(case_data, overrides))
    keys = table_keys(case)
    summary_path = Path(out) / "summary.json"
    restart, if_exists = None, "keep"
    if summary_path.exists():
        done = json.loads(summary_path.read_text())
        status = done.get("status", "finished")
        # a run's summary is written from its start on: reuse only a run that ended (a
        # summary without a status is an older version's, written at the end)
        if (done.get("case") == case.model_dump(mode="json")
                and status in ("finished", "unstable")):
            return {"status": "ok" if not done.get("failure") else "unstable",
                    **{k: done.get(k) for k in keys},
                    **{k: summary_value(done, k) for k in metrics}, "reused": True}
        restart = _checkpoint_to_continue(Path(out), case, status)
        if (restart is None and done.get("case") is not None
                and done["case"] != case.model_dump(mode="json")):
            from .checkpoint import case_differences

            differ = case_differences(case.model_dump(mode="json"), done["case"])
            log.warning("%s: held a run of another case (it differs in %s): run again, its "
                        "outputs replaced", out, ", ".join(differ[:4]))
            if_exists = "overwrite"
    try:
        summary = run_case(case, out, figures=False, restart=restart, if_exists=if_exists)
        status = "ok"
    except SimulationError as exc:  # (a run out of GPU memory is run again by a resumed sweep)
        summary = json.loads(summary_path.read_text())
        status = (f"out_of_memory: {exc}" if isinstance(exc, DeviceMemoryError)
                  else f"unstable: {exc}")
    summary["case"] = case.model_dump(mode="json")
    write_summary(out, summary)
    # (a measure not taken: None, as a reused run's summary.json gives it, not NaN)
    return finite_or_null({"status": status, **{k: summary.get(k) for k in keys},
                           **{k: summary_value(summary, k) for k in metrics},
                           "reused": False})


def _checkpoint_to_continue(out: Path, case: Any, status: str) -> Path | None:
    """The checkpoint a resumed sweep continues a run from: its own, where the run did not
    end (a sweep stopped by Ctrl-C, a worker killed) and the checkpoint is this case's; None
    (run again from t = 0) otherwise, with a warning where a checkpoint could not be used.
    An interrupted run was run again from t = 0 until 2026-12-08, its steps lost."""
    from .checkpoint import verify_checkpoint

    checkpoint = out / "checkpoint.h5"
    if status not in ("running", "interrupted") or not checkpoint.is_file():
        return None
    try:
        verify_checkpoint(checkpoint, case)
    except CaseError as exc:
        log.warning("%s: not continued from its checkpoint (%s): run again from t = 0", out,
                    exc)
        return None
    return checkpoint


def run_dir_name(out: Path, name: str, overrides: list[str]) -> str:
    """The directory of a run under ``out/runs``: ``name``, unless only the directory an
    earlier version named by :func:`run_id` holds this run's summary (an older sweep goes on
    where it stopped)."""
    legacy = run_id(overrides)
    if (not (out / "runs" / name).exists()
            and (out / "runs" / legacy / "summary.json").is_file()):
        return legacy
    return name


def local_cluster(workers: int | None = None) -> Any:
    """A Dask cluster of ``workers`` single-threaded processes on this machine (None: one per
    core), without a dashboard.  The scheduler's own HTTP server (its health and metrics
    routes) listens on a free loopback port: on the default, 8787, a second cluster (another
    sweep, a user's own) would find it taken and warn."""
    from distributed import LocalCluster

    return LocalCluster(n_workers=workers or os.cpu_count() or 1, threads_per_worker=1,
                        processes=True, dashboard_address=None,
                        scheduler_kwargs={"dashboard_address": "127.0.0.1:0"})


def compile_ahead(cases: list[Any]) -> int:
    """Compile (or load) the code of the runs ``cases`` in this process, one
    :func:`~impactsph.simulation.compile_kernels` for each set of them whose compiled code
    differs (:func:`~impactsph.simulation.compile_key`), before a sweep's local workers start
    together; returns how many it ran.  A case whose key cannot be made is compiled ahead on
    its own, with a warning: compiling ahead is never why a sweep fails."""
    from .simulation import compile_kernels, compile_key

    seen = set()
    for case in cases:
        try:
            key = compile_key(case)
        except Exception as exc:  # noqa: BLE001 (an optimisation: log it and go on)
            log.warning("compiling ahead for %r: its key could not be made (%s)",
                        case.name, exc)
            key = ("this case", id(case))
        if key not in seen:
            seen.add(key)
            compile_kernels(case.dimension, case)
    return len(seen)


def run_many(base: dict[str, Any] | list[dict[str, Any]], run_overrides: list[list[str]],
             out: Path, *,
             scheduler: str | None = None, workers: int | None = None,
             on_result: Any = None, names: list[str] | None = None,
             metrics: tuple[str, ...] | list[str] = (), flag: str = "--set"
             ) -> list[dict[str, Any]]:
    """Run the case ``base`` once per override list on a Dask cluster (or, ``base`` a list,
    each run its own case: runs of several cases share the cluster and run side by side);
    each run writes into
    ``out/runs/NAME`` (``names``, else :func:`run_id`; see :func:`run_dir_name`).  Returns
    one row per run, in the order given (``run``: the directory's name; ``metrics``: summary
    values added, :func:`run_one`); ``on_result(i, row)`` is called as runs finish.  A run
    that an earlier call left unfinished continues from its checkpoint; one of another case
    is run again, its outputs replaced (with a warning).  ``flag``: the option the
    overrides' errors name (a sweep's: ``--grid``)."""
    from distributed import Client, as_completed

    for name in ("distributed", "distributed.nanny", "distributed.scheduler",
                 "distributed.worker", "distributed.core", "distributed.http.proxy"):
        logging.getLogger(name).setLevel(logging.WARNING)
    out = Path(out)
    bases = base if isinstance(base, list) else [base] * len(run_overrides)
    if len(bases) != len(run_overrides):
        raise ValueError(f"run_many: {len(bases)} cases for {len(run_overrides)} runs")
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 1):
        raise CaseError(f"--workers {workers}: an integer >= 1 (default: one per core)")
    if out.exists() and not out.is_dir():
        raise CaseError(f"--out {out} is a file, not a directory")
    cases = [validate_case(apply_overrides(b, ov, flag))  # every run, before any starts
             for b, ov in zip(bases, run_overrides, strict=True)]
    Path(out).mkdir(parents=True, exist_ok=True)  # (not before: a refused case writes nothing)
    if not scheduler:  # fill numba's disk cache once, before the workers start together
        compile_ahead(cases)
    rows: dict[int, dict[str, Any]] = {}
    cluster = None
    if scheduler:
        client = Client(scheduler)
    else:
        cluster = local_cluster(workers)
        client = Client(cluster)
    try:
        futures = {}
        for i, ov in enumerate(run_overrides):
            rid = run_id(ov)
            name = run_dir_name(out, names[i], ov) if names else rid
            # the key names the run's directory too: two cases' runs may share overrides
            fut = client.submit(run_one, bases[i], ov, str((out / "runs" / name).resolve()),
                                tuple(metrics), key=f"impactsph-{name}-{rid}", retries=3,
                                pure=False)
            futures[fut] = (i, name)
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
          threshold: float | None = None, metrics: list[str] | None = None
          ) -> dict[str, Any]:
    """Run ``case_source`` over the grids; write ``sweep.csv``, ``sweep.json`` and
    ``sweep.png`` into ``out``, and per metric ``sweep_KEY.png``.  Returns the result: the
    grid's ``columns``, the table's ``rows`` (with the ``metrics``: values of the runs'
    summaries by dotted path), the ``finding`` of the problem's sweep criterion (at
    ``threshold``, the criterion's own when None; None for a problem without a criterion),
    the ``figures`` written and ``notes`` (a metric that no run has, with the keys close
    to it)."""
    out = Path(out)
    base = apply_overrides(read_case_dict(case_source), overrides or [])
    criterion = get_problem(validate_case(base).analysis).sweep_criterion
    columns, runs = parse_grid(grids)
    run_overrides = [[f"{k}={json.dumps(v)}" for k, v in kv] + ["output.figures=false"]
                     for kv in runs]
    done: dict[int, dict[str, Any]] = {}

    def record(i: int, row: dict[str, Any]) -> None:
        done[i] = {**dict(runs[i]), **row}
        atomic_write_text(out / "sweep.csv", _csv_text([done[k] for k in sorted(done)]))

    metrics = list(dict.fromkeys(metrics or []))
    run_many(base, run_overrides, out, scheduler=scheduler, workers=workers, on_result=record,
             names=run_names(runs, run_overrides), metrics=metrics, flag="--grid")
    table = [done[i] for i in sorted(done)]
    # the parameter the finding and the figures run along: the first that takes more than
    # one value (a grid of alpha1=0 and alpha2=0.5,1,... is a sweep of alpha2)
    varying = [c for c in columns if len({json.dumps(r.get(c)) for r in table}) > 1]
    columns_drawn = [*varying, *[c for c in columns if c not in varying]]
    first = columns_drawn[0]
    finding = None
    if criterion is not None:
        passed = [r for r in table if criterion.passes(r, threshold)]
        finding = {
            "criterion": criterion.describe(threshold),
            "parameter": first,
            f"smallest_{criterion.name}": min((r[first] for r in passed), default=None),
        }
    figures = [sweep_figure(table, columns_drawn, out / "sweep.png", criterion, threshold)]
    notes = []
    for key in metrics:
        if not any(_is_number(r.get(key)) for r in table):
            notes.append(f"--metric {key}: no run's summary has a number there"
                         + _metric_hint(out, table, key))
            log.warning("%s", notes[-1])
            continue
        figures.append(sweep_figure(table, columns_drawn,
                                    out / f"sweep_{_sanitise(key)}.png", panels=[(key, key)]))
    result = {"columns": columns, "rows": table, "finding": finding, "metrics": metrics,
              "figures": [str(f) for f in figures], "notes": notes}
    # with what made it: the versions, the command, the grids and the base case as resolved
    write_study(out / "sweep.json", {"grids": grids, "overrides": overrides or [],
                                     "base_case": validate_case(base).model_dump(mode="json"),
                                     **result})
    return result


def _is_number(value: Any) -> bool:
    return (isinstance(value, int | float) and not isinstance(value, bool)
            and math.isfinite(value))


def _metric_hint(out: Path, table: list[dict[str, Any]], key: str) -> str:
    """``; did you mean ...?`` among the numeric keys of the first run's summary."""
    from .loading import did_you_mean

    for row in table:
        path = out / "runs" / str(row.get("run")) / "summary.json"
        if path.is_file():
            try:
                return did_you_mean(key, summary_keys(json.loads(path.read_text())))
            except (OSError, ValueError):
                return ""
    return ""


def sweep_figure(table: list[dict[str, Any]], columns: list[str], path: Path,
                 criterion: SweepCriterion | None = None, threshold: float | None = None,
                 panels: list[tuple[str, str]] | None = None) -> Path:
    """Kinetic energy kept against the first of ``columns`` (the sweep puts the first that
    varies first), one line per value of the
    others, and beside it the column of the problem's sweep ``criterion`` (if any) with its
    ``threshold`` (the criterion's own when None); or, given ``panels`` (column, y label),
    those columns instead."""
    from .plotting import plt, save_figure

    first = columns[0]
    others = [c for c in columns[1:] if not all(r.get(c) == r.get(first) for r in table)]
    tied = [c for c in columns[1:] if c not in others]  # (a,b=0.3,1: the same values)
    if panels is None:
        panels = [("kinetic_energy_ratio_final", "kinetic energy kept at the end")]
        if criterion is not None:
            panels.append((criterion.key, criterion.label))
    else:
        criterion = None
    fig, axes = plt.subplots(1, len(panels), figsize=(5 * len(panels), 4), squeeze=False)
    axes = list(axes[0])
    groups: dict[tuple, list[dict[str, Any]]] = {}
    for r in table:  # (keyed by the values' JSON: a grid value may be a list)
        groups.setdefault(json.dumps([r.get(c) for c in others]), []).append(r)
    for key_text, rs in groups.items():
        key = json.loads(key_text)
        rs = sorted(rs, key=lambda r: (not _is_number(r[first]), r[first]
                                       if _is_number(r[first]) else json.dumps(r[first])))
        # a value that is not a number (a list, a name) is placed as a category
        x = [r[first] if _is_number(r[first]) else json.dumps(r[first]) for r in rs]
        label = ", ".join(f"{c}={v}" for c, v in zip(others, key, strict=True)) or None
        for ax, (col, _) in zip(axes, panels, strict=True):
            y = [r.get(col) if _is_number(r.get(col)) else np.nan for r in rs]
            ax.plot(x, y, "o-", label=label)
    for ax, (_, ylabel) in zip(axes, panels, strict=True):
        ax.set_ylabel(ylabel)
        ax.set_xlabel(" = ".join([first, *tied]))
        ax.grid(alpha=0.3)
    if criterion is not None:
        axes[-1].axhline(criterion.threshold if threshold is None else threshold, color="k",
                         ls=":", label="criterion")
    if axes[-1].get_legend_handles_labels()[0]:
        axes[-1].legend()
    return save_figure(fig, path)
