"""Sweeps on Dask and the paper's figures command."""

from __future__ import annotations

import csv
import json

import pytest
from typer.testing import CliRunner

from impactsph.cli import app
from impactsph.config import CaseError
from impactsph.sweep import parse_grid

runner = CliRunner()


def test_parse_grid_product_and_tied_keys():
    cols, runs = parse_grid(["viscosity.alpha1,viscosity.alpha2=0.1,0.2", "time.end=1e-6,2e-6"])
    assert cols == ["viscosity.alpha1", "viscosity.alpha2", "time.end"]
    assert len(runs) == 4
    assert runs[0] == [("viscosity.alpha1", 0.1), ("viscosity.alpha2", 0.1), ("time.end", 1e-6)]
    with pytest.raises(CaseError):
        parse_grid(["viscosity.alpha1"])


def test_sweep_runs_in_parallel_and_names_the_smallest_stable_alpha(tmp_path):
    out = tmp_path / "sw"
    res = runner.invoke(app, ["sweep", "bars", "--grid",
                              "viscosity.alpha1,viscosity.alpha2=0.05,0.3,1.0",
                              "--out", str(out), "--workers", "2"])
    assert res.exit_code == 0, res.output
    with open(out / "sweep.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [float(r["viscosity.alpha1"]) for r in rows] == [0.05, 0.3, 1.0]
    assert all(r["status"] == "ok" for r in rows)
    ke = [float(r["kinetic_energy_ratio_final"]) for r in rows]
    assert ke[0] > ke[1] > ke[2]
    finding = json.loads((out / "sweep.json").read_text())["finding"]
    assert finding["smallest_oscillation_free"] == 0.3
    assert (out / "sweep.png").stat().st_size > 10_000
    # a second sweep over the same grid reuses the finished runs
    res = runner.invoke(app, ["sweep", "bars", "--grid",
                              "viscosity.alpha1,viscosity.alpha2=0.05,0.3,1.0",
                              "--out", str(out), "--workers", "1"])
    assert res.exit_code == 0
    rows = json.loads((out / "sweep.json").read_text())["rows"]
    assert all(r["reused"] for r in rows)


def test_a_sweep_run_is_reused_only_when_it_ended(tmp_path):
    """A run's summary is written from its start on (status running, interrupted): only a
    finished (or unstable) run is reused."""
    import numba

    from impactsph.loading import read_case_dict
    from impactsph.sweep import run_one

    threads = numba.get_num_threads()
    base, overrides, out = read_case_dict("bars"), ["time.end=1e-6"], str(tmp_path / "r")
    try:
        assert run_one(base, overrides, out)["reused"] is False
        assert run_one(base, overrides, out)["reused"] is True
        path = tmp_path / "r" / "summary.json"
        for status in ("running", "interrupted"):
            summary = json.loads(path.read_text())
            path.write_text(json.dumps({**summary, "status": status}))
            row = run_one(base, overrides, out)
            assert row["reused"] is False and row["status"] == "ok"
            assert json.loads(path.read_text())["status"] == "finished"
    finally:
        numba.set_num_threads(threads)


def test_sweep_rejects_a_bad_grid_before_running(tmp_path):
    res = runner.invoke(app, ["sweep", "bars", "--grid", "viscosity.alpha1=-1,0.3",
                              "--out", str(tmp_path / "bad")])
    assert res.exit_code == 2
    assert "viscosity.alpha1" in res.output
    assert not (tmp_path / "bad").exists()  # nothing written, not even the directory
    res = runner.invoke(app, ["sweep", "bars", "--grid", "viscosity.alpah1=0.1,0.3",
                              "--out", str(tmp_path / "misspelt")])
    assert res.exit_code == 2
    assert "viscosity.alpah1: unknown key; did you mean" in res.output, res.output
    assert not (tmp_path / "misspelt").exists()


def test_paper_command_draws_figs_3_to_9_and_the_table(tmp_path):
    out = tmp_path / "paper"
    res = runner.invoke(app, ["paper", "bars", "--out", str(out), "--workers", "2"])
    assert res.exit_code == 0, res.output
    for name in ("fig3_alpha2_only", "fig4_alpha_ladder", "fig5_profiles",
                 "fig6_kinetic_energy", "fig7_profile_ac", "fig8_mid_velocity_ac",
                 "fig9_kinetic_energy_ac"):
        assert (out / f"{name}.png").stat().st_size > 10_000, name
    paper_json = json.loads((out / "paper.json").read_text())
    assert paper_json["provenance"]["impactsph"]  # (the versions and the command)
    table = {r["run"]: r for r in paper_json["table"]}
    assert all((out / r["directory"] / "summary.json").is_file() for r in table.values())
    assert table["AV3 (2.5, 2.5)"]["kinetic_energy_ratio_final"] < table["AV1 (1, 1)"][
        "kinetic_energy_ratio_final"] < table["AV (0.3, 0.3)"]["kinetic_energy_ratio_final"]
    assert "AC neighbours_only / work" in (out / "table.md").read_text()


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_sweep_on_an_existing_cluster_survives_a_lost_worker(tmp_path):
    """A scheduler and two single-threaded worker processes on this machine (loopback); one
    worker is killed once the first run has finished: every run still finishes, once."""
    import subprocess
    import sys
    import threading
    import time
    from pathlib import Path

    from impactsph.sweep import sweep

    bindir = Path(sys.executable).parent
    port = _free_port()
    address = f"tcp://127.0.0.1:{port}"
    procs = [subprocess.Popen([str(bindir / "dask"), "scheduler", "--host", "127.0.0.1",
                               "--port", str(port), "--no-dashboard",
                               "--dashboard-address", "127.0.0.1:0"],
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)]
    try:
        time.sleep(2.0)
        for _ in range(2):
            procs.append(subprocess.Popen(
                [str(bindir / "dask"), "worker", address, "--nthreads", "1",
                 "--nworkers", "1", "--no-dashboard", "--no-nanny"],
                stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL))
        out = tmp_path / "sw"
        values = "0.2,0.3,0.4,0.6,0.8,1.0"

        def kill_one_worker():
            deadline = time.time() + 120
            while time.time() < deadline:
                if (out / "sweep.csv").exists():
                    procs[1].kill()
                    return
                time.sleep(0.05)

        killer = threading.Thread(target=kill_one_worker)
        killer.start()
        result = sweep("bars", [f"viscosity.alpha1,viscosity.alpha2={values}"], out,
                       scheduler=address)
        killer.join()
        assert procs[1].poll() is not None  # the worker really died mid-sweep
        rows = result["rows"]
        alphas = [r["viscosity.alpha1"] for r in rows]
        assert sorted(alphas) == [0.2, 0.3, 0.4, 0.6, 0.8, 1.0]  # each once
        assert all(r["status"] == "ok" for r in rows)
        with open(out / "sweep.csv") as fh:
            assert len(list(csv.DictReader(fh))) == 6
    finally:
        for p in procs:
            p.kill()
            p.wait()


def test_local_cluster_leaves_port_8787_alone():
    """With the default HTTP port, 8787, held by another process (a second sweep, a user's
    own Dask cluster), a sweep's local cluster starts without the warning that it moved: its
    scheduler's HTTP server (its health route) answers on a free loopback port."""
    import socket
    import urllib.request
    import warnings

    from impactsph.sweep import local_cluster

    holder = socket.socket()
    try:
        holder.bind(("0.0.0.0", 8787))
        holder.listen()
    except OSError:  # something already holds it: the same situation
        pass
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            cluster = local_cluster(1)
            try:
                ports = [s.getsockname() for s in cluster.scheduler.http_server._sockets.values()]
                with urllib.request.urlopen(f"http://127.0.0.1:{ports[0][1]}/health") as reply:
                    health = reply.status
            finally:
                cluster.close()
    finally:
        holder.close()
    assert not [w for w in caught if "already in use" in str(w.message)], \
        [str(w.message) for w in caught]
    assert ports and all(host == "127.0.0.1" and port != 8787 for host, port in ports), ports
    assert health == 200


def test_parse_grid_takes_vectors():
    """A grid of vectors: the commas inside brackets are the vectors' own (the grid was cut
    at every comma, an audit, 2026-12-08)."""
    cols, runs = parse_grid(["bodies.0.velocity=[0, -200],[0,-150]", "name=\"a,b\",c"])
    assert cols == ["bodies.0.velocity", "name"]
    assert [dict(r)["bodies.0.velocity"] for r in runs] == [[0, -200], [0, -200], [0, -150],
                                                             [0, -150]]
    assert [dict(r)["name"] for r in runs][:2] == ["a,b", "c"]


def test_a_sweep_run_left_unfinished_continues_from_its_checkpoint(tmp_path):
    """A sweep stopped part-way (Ctrl-C, a worker killed) left its runs' checkpoints: a
    resumed sweep continues each from its own, and runs again one whose checkpoint is
    another case's; it ran them all again from t = 0 (an audit, 2026-12-08)."""
    import numba

    from impactsph.loading import read_case_dict
    from impactsph.sweep import run_one

    threads = numba.get_num_threads()
    base, out = read_case_dict("bars"), tmp_path / "r"
    first = ["time.end=1e-6", "output.checkpoint_interval=1e-6"]
    try:
        run_one(base, first, str(out))
        path = out / "summary.json"
        summary = json.loads(path.read_text())
        t, step = summary["t_end"], summary["n_steps"]
        del summary["case"]  # as a run stopped part-way leaves it
        path.write_text(json.dumps({**summary, "status": "running"}))
        row = run_one(base, ["time.end=2e-6", "output.checkpoint_interval=1e-6"], str(out))
        assert row["reused"] is False and row["status"] == "ok"
        summary = json.loads(path.read_text())
        [restart] = summary["restarts"]
        assert (restart["time"], restart["step"]) == (t, step)
        assert summary["status"] == "finished" and summary["t_end"] == pytest.approx(2e-6)
        # a checkpoint of another case: run again from t = 0, its outputs replaced
        path.write_text(json.dumps({**summary, "status": "interrupted"}))
        row = run_one(base, ["time.end=2e-6", "output.checkpoint_interval=1e-6",
                             "viscosity.alpha1=0.5"], str(out))
        summary = json.loads(path.read_text())
        assert row["status"] == "ok" and summary["restarts"] == []
        assert summary["case"]["viscosity"]["alpha1"] == 0.5
    finally:
        numba.set_num_threads(threads)


def test_a_sweep_runs_along_its_varying_parameter_and_records_what_made_it(tmp_path):
    """The README's second sweep (alpha1 = 0, alpha2 varied) named alpha1 in its finding and
    drew against it; sweep.json had neither the version nor the grid (an audit,
    2026-12-08)."""
    import impactsph

    out = tmp_path / "sw"
    res = runner.invoke(app, ["sweep", "bars", "--grid", "viscosity.alpha1=0", "--grid",
                              "viscosity.alpha2=0.5,1", "--set", "time.end=2e-6",
                              "--out", str(out), "--workers", "1"])
    assert res.exit_code == 0, res.output
    result = json.loads((out / "sweep.json").read_text())
    assert result["finding"]["parameter"] == "viscosity.alpha2"
    assert result["provenance"]["impactsph"] == impactsph.__version__
    assert result["grids"] == ["viscosity.alpha1=0", "viscosity.alpha2=0.5,1"]
    assert result["overrides"] == ["time.end=2e-6"]
    assert result["base_case"]["time"]["end"] == 2e-6
    for args, line in ((["--workers", "0"], "error: --workers 0: an integer >= 1"),
                       (["--out", str(tmp_path / "a_file")], "is a file, not a directory")):
        (tmp_path / "a_file").write_text("")
        res = runner.invoke(app, ["sweep", "bars", "--grid", "viscosity.alpha1=0.3",
                                  "--out", str(out / "x"), *args])
        assert res.exit_code == 2 and line in res.output, res.output
    res = runner.invoke(app, ["sweep", "bars", "--grid", "bodies.5.velocity=[1.0]",
                              "--out", str(out / "y")])
    assert res.exit_code == 2 and "error: --grid bodies.5.velocity=[1.0]: " in res.output


def test_the_sweep_figure_takes_a_vector_beside_the_parameter_it_runs_along(tmp_path):
    """A grid of vectors in a column other than the one drawn along: the lines are grouped
    by it (its lists were made dict keys, and the sweep failed after all its runs, a review,
    2026-12-08)."""
    from impactsph.sweep import sweep_figure

    table = [{"viscosity.alpha1": a, "bodies.0.velocity": v, "kinetic_energy_ratio_final": k}
             for (a, v), k in zip([(0.3, [50.0]), (0.5, [50.0]), (0.3, [40.0]), (0.5, [40.0])],
                                  [0.9, 0.8, 0.85, 0.75], strict=True)]
    path = sweep_figure(table, ["viscosity.alpha1", "bodies.0.velocity"], tmp_path / "s.png")
    assert path.stat().st_size > 10_000
