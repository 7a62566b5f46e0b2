"""Nothing lost on interruption: Ctrl-C and SIGTERM stop a run after a whole step with a
checkpoint, the history and a summary, and the printed command continues it to the same
history byte for byte; outputs are written as the run goes; a run directory belongs to one
run; a damaged checkpoint is refused before any work."""

from __future__ import annotations

import errno
import json
import os
import re
import shlex
import signal
import subprocess
import sys
import time
from pathlib import Path

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

import impactsph
from impactsph.checkpoint import load_checkpoint, verify_checkpoint, write_checkpoint
from impactsph.cli import app
from impactsph.errors import CaseError, OutputError
from impactsph.interrupt import stop_on_signals
from impactsph.loading import load_case
from impactsph.rundir import LOCK, RunLock, check_run_dir
from impactsph.runner import run_case
from impactsph.simulation import Simulation

runner = CliRunner()
#: long enough (about 11 000 steps, seconds) for a signal to land well before the end
END = 150e-6
SETS = [f"time.end={END}", "output.figures=false"]


def one_line(res) -> str:
    lines = [ln for ln in res.output.splitlines() if ln.strip()]
    assert len(lines) == 1, res.output
    assert "Traceback" not in res.output
    return lines[0]


def rows(path: Path) -> int:
    try:
        return len(path.read_text().splitlines())
    except FileNotFoundError:
        return 0


def start_run(out: Path) -> subprocess.Popen:
    cmd = [sys.executable, "-m", "impactsph", "run", "bars", "--quiet", "--out", str(out)]
    for s in SETS:
        cmd += ["--set", s]
    return subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)


def wait_for_rows(proc: subprocess.Popen, out: Path, n: int = 30) -> None:
    """Until the run's history.csv has ``n`` lines (it is written as the run goes)."""
    deadline = time.monotonic() + 300
    while rows(out / "history.csv") < n:
        assert proc.poll() is None, proc.communicate()
        assert time.monotonic() < deadline, "the run wrote no history"
        time.sleep(0.01)


@pytest.fixture(scope="module")
def compiled(tmp_path_factory) -> None:
    """The case's kernels in the cache (three steps of it, here), so that the runs in
    subprocesses print no compile notice: a cold cache's first run says it compiles, in a
    line of its own (``preflight.compile_notice``), and the tests count their lines."""
    run_case(load_case("bars", [*SETS, "time.max_steps=3"]), tmp_path_factory.mktemp("warm"))


@pytest.fixture(scope="module")
def interrupted(tmp_path_factory, compiled):
    """A run in a subprocess, seen while it runs (a second run into its directory at that
    moment), then sent SIGINT; and the same case run whole, here."""
    root = tmp_path_factory.mktemp("interrupt")
    whole = root / "whole"
    run_case(load_case("bars", SETS), whole)
    out = root / "run"
    proc = start_run(out)
    try:
        wait_for_rows(proc, out)
        lock = json.loads((out / LOCK).read_text())
        second = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(out), "--overwrite",
                                     *sum((["--set", s] for s in SETS), [])])
        rows_then = rows(out / "history.csv")
        proc.send_signal(signal.SIGINT)
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    return {"out": out, "whole": whole, "proc": proc, "stdout": stdout, "stderr": stderr,
            "lock": lock, "second": second, "rows_then": rows_then}


def test_sigint_stops_with_exit_130_and_one_line(interrupted):
    r = interrupted
    assert r["proc"].returncode == 130, r["stderr"]
    assert "Traceback" not in r["stderr"] and r["stdout"] == ""
    lines = [ln for ln in r["stderr"].splitlines() if ln.strip()]
    assert len(lines) == 1, r["stderr"]
    out = r["out"]
    summary = json.loads((out / "summary.json").read_text())
    assert lines[0].startswith(f"interrupted at t = {summary['t_end']:.6e} s, step "
                               f"{summary['n_steps']}")
    command = lines[0].split("continue with: ")[1]
    assert shlex.split(command) == [
        "impactsph", "run", "bars", "--out", str(out), "--restart",
        str(out / "checkpoint.h5"), "--set", SETS[0], "--set", SETS[1]]


def test_interrupted_run_leaves_history_summary_and_checkpoint(interrupted):
    out = interrupted["out"]
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "interrupted"
    assert 0 < summary["t_end"] < END and summary["n_steps"] > 0
    assert summary["checkpoint"] == str(out / "checkpoint.h5")
    history = (out / "history.csv").read_text().splitlines()
    assert len(history) == 1 + 1 + summary["n_steps"]  # header, t = 0, every step
    assert len(history) >= interrupted["rows_then"]
    last = dict(zip(history[0].split(","), history[-1].split(","), strict=True))
    assert int(last["step"]) == summary["n_steps"]
    assert float(last["time"]) == summary["t_end"]
    # the rows are the uninterrupted run's, byte for byte, as far as they go
    whole = (interrupted["whole"] / "history.csv").read_text().splitlines()
    assert history == whole[: len(history)]
    sim = load_checkpoint(out / "checkpoint.h5")
    assert sim.state.step == summary["n_steps"] and sim.state.time == summary["t_end"]
    # the checkpoint, written during a step, counts the wall time of the steps before it
    # (it held 0 s, and a restarted run's rate was its pairs from t = 0 over its own time)
    assert sim.record.wall_seconds > 0.0
    assert not (out / LOCK).exists()  # released at exit
    # run.log says how the run ended, as the console did
    assert (out / "run.log").read_text().splitlines()[-1].endswith(
        f"WARNING impactsph: stopped: interrupted at t = {summary['t_end']:.6e} s, step "
        f"{summary['n_steps']}; checkpoint {out / 'checkpoint.h5'}")


def test_second_run_into_a_directory_in_use_is_refused(interrupted):
    res = interrupted["second"]
    line = one_line(res)
    assert res.exit_code == 2
    assert "in use" in line and str(interrupted["lock"]["pid"]) in line
    assert interrupted["lock"]["pid"] == interrupted["proc"].pid
    # --overwrite did not clear the running run's outputs: its history went on growing
    assert interrupted["rows_then"] >= 30


def test_restart_with_the_printed_command_reproduces_the_history(interrupted):
    out = interrupted["out"]
    line = interrupted["stderr"].strip()
    args = shlex.split(line.split("continue with: ")[1])
    assert args[0] == "impactsph"
    res = runner.invoke(app, [*args[1:], "--quiet"])  # into the same, non-empty directory
    assert res.exit_code == 0, res.output
    whole = interrupted["whole"]
    for name in ("history.csv", "probes.csv", "snapshots.npz"):
        assert (out / name).read_bytes() == (whole / name).read_bytes(), name
    summary = json.loads((out / "summary.json").read_text())
    assert summary["status"] == "finished" and summary["t_end"] == pytest.approx(END)
    # the history says that two processes made it, and which versions
    [restart] = summary["restarts"]
    assert restart["checkpoint"] == str((out / "checkpoint.h5").resolve())
    assert restart["impactsph"] == restart["continued_by"] == impactsph.__version__
    assert 0 < restart["time"] < END and restart["step"] > 0
    # finished, without output.checkpoint_interval: the checkpoint is not kept
    assert not (out / "checkpoint.h5").exists()


def test_sigterm_stops_the_same_way(tmp_path, compiled):
    out = tmp_path / "run"
    proc = start_run(out)
    try:
        wait_for_rows(proc, out, 10)
        proc.send_signal(signal.SIGTERM)
        _, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
    assert proc.returncode == 130, stderr
    assert stderr.startswith("interrupted at t = ") and len(stderr.strip().splitlines()) == 1
    assert json.loads((out / "summary.json").read_text())["status"] == "interrupted"
    verify_checkpoint(out / "checkpoint.h5", load_case("bars", SETS))


def test_signals_ask_for_a_stop_and_a_second_one_stops_at_once():
    # what the process had before (Python's handler, or SIG_IGN where the test run was
    # started in the background by a shell without job control): restored on leaving
    before = signal.getsignal(signal.SIGINT)
    with stop_on_signals() as stop:
        with pytest.raises(KeyboardInterrupt):  # while setting up: nothing to save yet
            signal.raise_signal(signal.SIGINT)
        assert not stop.requested
        stop.arm()  # the run is set up
        signal.raise_signal(signal.SIGINT)
        assert stop.requested and stop.signal == signal.SIGINT
        with pytest.raises(KeyboardInterrupt):  # the run has not taken the request up yet
            signal.raise_signal(signal.SIGTERM)
        assert stop()  # taken up: the run now writes its last outputs ...
        signal.raise_signal(signal.SIGINT)  # ... and a further signal does not disturb it
    assert signal.getsignal(signal.SIGINT) is before


def test_a_stop_asked_in_a_library_run_raises_run_interrupted(tmp_path):
    from impactsph.errors import RunInterrupted

    steps: list[int] = []
    case = load_case("bars", ["time.end=3e-6", "output.figures=false"])
    with pytest.raises(RunInterrupted) as info:
        run_case(case, tmp_path, callback=lambda s: steps.append(s.state.step),
                 stop=lambda: len(steps) >= 20)
    assert info.value.step == 20 and info.value.checkpoint == str(tmp_path / "checkpoint.h5")
    assert not info.value.finished
    assert json.loads((tmp_path / "summary.json").read_text())["status"] == "interrupted"
    assert load_checkpoint(tmp_path / "checkpoint.h5").state.step == 20


def test_a_stop_after_the_run_finished_keeps_its_complete_outputs(tmp_path):
    """Stopped during the reference run that the figures need: the run itself is complete."""
    from impactsph.errors import RunInterrupted

    calls = []

    def stop() -> bool:
        calls.append(1)
        # asked before the first step, after each step, and before the figures; then the
        # same in the reference run: the 11th call past the run's steps is its 8th step
        return len(calls) > steps + 10

    case = load_case("bars", ["time.end=1e-6", "viscosity.scheme=ac"])
    steps = Simulation(case).run().history[-1]["step"]
    with pytest.raises(RunInterrupted) as info:
        run_case(case, tmp_path, stop=stop)
    assert info.value.finished and info.value.checkpoint is None
    assert info.value.step == steps
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "finished" and "figures" not in summary
    assert not list(tmp_path.glob("*.png")) and not (tmp_path / "checkpoint.h5").exists()
    reference = json.loads((tmp_path / "reference" / "summary.json").read_text())
    assert reference["status"] == "interrupted" and reference["n_steps"] == 8


# -- outputs as the run goes -------------------------------------------------------------------


def test_history_and_probes_are_on_disk_as_rows_are_recorded(tmp_path):
    seen = []

    def look(sim):
        if sim.state.step in (1, 40):
            seen.append((sim.state.step, rows(tmp_path / "history.csv"),
                         rows(tmp_path / "probes.csv"),
                         json.loads((tmp_path / "summary.json").read_text())["status"]))

    case = load_case("bars", ["time.end=3e-6", "output.figures=false"])
    run_case(case, tmp_path, callback=look)
    # header, t = 0, then one row per step, flushed before the step's callback
    assert seen == [(1, 3, 3, "running"), (40, 42, 42, "running")]
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "finished"


def test_history_every_streams_only_the_recorded_rows(tmp_path):
    case = load_case("bars", ["time.end=3e-6", "output.figures=false",
                              "output.history_every=7"])
    sim = Simulation(case)
    sim.run()
    run_case(case, tmp_path)
    from impactsph.output import _csv_text

    assert (tmp_path / "history.csv").read_text() == _csv_text(sim.record.history)


def test_checkpoints_by_wall_time_when_no_interval_is_set(tmp_path):
    """Without output.checkpoint_interval a checkpoint (with a summary that says how far the
    run has got) is written every so much wall time; it is removed when the run finishes."""
    seen = []

    def look(sim):
        path = tmp_path / "checkpoint.h5"
        if path.exists() and not seen:
            summary = json.loads((tmp_path / "summary.json").read_text())
            seen.append((load_checkpoint(path).state.step, summary))

    case = load_case("bars", ["time.end=1e-6", "output.figures=false"])
    run_case(case, tmp_path, callback=look, checkpoint_wall_seconds=0.0)  # at every step
    assert seen, "no checkpoint was written"
    step, summary = seen[0]
    assert summary["status"] == "running" and summary["n_steps"] == step > 0
    assert summary["checkpoint"] == str(tmp_path / "checkpoint.h5")
    assert not (tmp_path / "checkpoint.h5").exists()
    # the default, 5 minutes: none in a short run
    out = tmp_path / "default"
    run_case(case, out, callback=lambda s: seen.append((out / "checkpoint.h5").exists()))
    assert not any(x is True for x in seen[1:])


# -- damaged checkpoints -----------------------------------------------------------------------


@pytest.fixture(scope="module")
def checkpoint(tmp_path_factory):
    out = tmp_path_factory.mktemp("ckpt")
    case = load_case("bars", ["time.end=2e-6", "output.checkpoint_interval=1e-6",
                              "output.figures=false"])
    run_case(case, out)
    return out / "checkpoint.h5"


def refused_restart(path: Path, out: Path) -> str:
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(out), "--restart",
                              str(path), "--set", "time.end=2e-6",
                              "--set", "output.snapshot_times=[]"])
    assert res.exit_code == 2, res.output
    assert not out.exists()  # before any work
    line = one_line(res)
    assert line.startswith(f"error: --restart {path}: "), line
    return line


def test_a_corrupted_checkpoint_is_refused(checkpoint, tmp_path):
    data = bytearray(checkpoint.read_bytes())
    with h5py.File(checkpoint, "r") as f:
        offset = f["state/velocity"].id.get_offset()
    assert offset is not None
    data[offset + 3] ^= 0xFF
    bad = tmp_path / "flipped.h5"
    bad.write_bytes(bytes(data))
    assert "corrupted" in refused_restart(bad, tmp_path / "a")


def test_an_edited_checkpoint_is_refused(checkpoint, tmp_path):
    edited = tmp_path / "edited.h5"
    edited.write_bytes(checkpoint.read_bytes())
    with h5py.File(edited, "a") as f:
        f.attrs["time"] = 1.5e-6
    assert "corrupted" in refused_restart(edited, tmp_path / "b")


def test_a_truncated_checkpoint_is_refused(checkpoint, tmp_path):
    short = tmp_path / "short.h5"
    short.write_bytes(checkpoint.read_bytes()[: checkpoint.stat().st_size // 2])
    line = refused_restart(short, tmp_path / "c")
    assert "truncated" in line
    with pytest.raises(CaseError, match="does not exist"):
        verify_checkpoint(tmp_path / "nowhere.h5")


def test_a_good_checkpoint_carries_its_checksum(checkpoint):
    with h5py.File(checkpoint, "r") as f:
        assert len(f.attrs["sha256"]) == 64
    verify_checkpoint(checkpoint)


# -- the run directory -------------------------------------------------------------------------


# (no snapshot times: the bars' 5.75 us one, after this end, would add a warning's line)
SHORT = ["--set", "time.end=1e-6", "--set", "output.figures=false",
         "--set", "output.snapshot_times=[]"]


def test_a_non_empty_out_is_refused_and_overwrite_clears_it(tmp_path):
    out = tmp_path / "run"
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(out), *SHORT,
                              "--set", "output.checkpoint_interval=5e-7",
                              "--set", "output.vtk_interval=5e-7"])
    assert res.exit_code == 0, res.output
    assert (out / "checkpoint.h5").exists() and (out / "vtk").is_dir()
    before = (out / "history.csv").read_bytes()
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(out), *SHORT])
    assert res.exit_code == 2
    line = one_line(res)
    assert line.startswith(f"error: --out {out} is not empty (") and "--overwrite" in line
    assert f"--restart {out / 'checkpoint.h5'}" in line
    assert (out / "history.csv").read_bytes() == before  # untouched
    # without --quiet too: refused before the preflight's particle counts and estimates
    res = runner.invoke(app, ["run", "bars", "--out", str(out), *SHORT])
    assert res.exit_code == 2 and one_line(res).startswith(f"error: --out {out} is not empty")
    missing = tmp_path / "nosuch" / "checkpoint.h5"
    res = runner.invoke(app, ["run", "bars", "--out", str(tmp_path / "r"), "--restart",
                              str(missing), *SHORT])
    assert res.exit_code == 2
    assert one_line(res) == f"error: --restart {missing}: does not exist"
    assert not (tmp_path / "r").exists()
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(out), *SHORT,
                              "--overwrite"])
    assert res.exit_code == 0, res.output
    # the previous run's outputs that this one does not write are gone
    assert sorted(p.name for p in out.iterdir()) == [
        "case.json", "history.csv", "probes.csv", "run.log", "snapshots.npz", "summary.json"]
    # --overwrite deletes no file impactsph did not write
    (out / "notes.txt").write_text("mine")
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(out), *SHORT,
                              "--overwrite"])
    assert res.exit_code == 2 and "notes.txt" in one_line(res)
    assert (out / "notes.txt").read_text() == "mine" and (out / "summary.json").exists()
    # an empty directory is fine
    (tmp_path / "empty").mkdir()
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(tmp_path / "empty"),
                              *SHORT])
    assert res.exit_code == 0, res.output


def test_out_is_a_file(tmp_path):
    path = tmp_path / "afile"
    path.write_text("x")
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(path), *SHORT])
    assert res.exit_code == 2
    assert one_line(res) == f"error: --out {path} is a file, not a directory"
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(path / "sub"), *SHORT])
    assert res.exit_code == 2
    assert one_line(res).startswith(f"error: cannot create the output directory {path / 'sub'}")
    assert path.read_text() == "x"


def test_out_without_permission(tmp_path, monkeypatch):
    def denied(self, *args, **kwargs):
        raise PermissionError(errno.EACCES, "Permission denied", str(self))

    monkeypatch.setattr(Path, "mkdir", denied)
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(tmp_path / "x"), *SHORT])
    assert res.exit_code == 2
    assert one_line(res) == (f"error: cannot create the output directory {tmp_path / 'x'}: "
                             "permission denied")


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere")
def test_out_in_a_read_only_directory(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o500)
    try:
        res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(ro / "x"), *SHORT])
        assert res.exit_code == 2 and "permission denied" in one_line(res)
    finally:
        ro.chmod(0o700)


def test_a_full_disk_is_one_line_naming_the_file(tmp_path, monkeypatch):
    def full(fd):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(os, "fsync", full)
    out = tmp_path / "x"
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(out), *SHORT])
    assert res.exit_code == 2
    assert one_line(res) == (f"error: cannot write {out / 'case.json'}: the disk is full "
                             "(No space left on device)")
    assert not out.exists()  # nothing was written: the directory is not left behind


@pytest.mark.skipif(not Path("/dev/full").exists(), reason="needs /dev/full")
def test_the_disk_filling_up_during_the_run(tmp_path, monkeypatch):
    import impactsph.output as output

    def to_dev_full(path, mode="r", *args, **kwargs):
        if Path(path).name == "history.csv" and mode == "ab":
            return open("/dev/full", "ab")  # noqa: SIM115 (every write: ENOSPC)
        return open(path, mode, *args, **kwargs)

    monkeypatch.setattr(output, "open", to_dev_full, raising=False)
    out = tmp_path / "x"
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(out), *SHORT])
    assert res.exit_code == 2
    assert one_line(res).startswith(f"error: cannot write {out / 'history.csv'}: the disk is "
                                    "full")
    assert not (out / LOCK).exists()


def test_a_disk_without_room_for_the_checkpoint_is_one_line(tmp_path, monkeypatch):
    """HDF5 that runs out of room part-way through a checkpoint reports it only while it
    frees its objects, and went on until the process crashed (a segmentation fault on a
    full tmpfs, an audit, 2026-12-08): the room is asked of the disk first."""
    import shutil

    real = shutil.disk_usage
    monkeypatch.setattr(shutil, "disk_usage",
                        lambda path: real(path)._replace(free=100_000))
    out = tmp_path / "x"
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(out), *SHORT,
                              "--set", "output.checkpoint_interval=5e-7"])
    assert res.exit_code == 2
    assert re.fullmatch(rf"error: cannot write {re.escape(str(out / 'checkpoint.h5'))}: the "
                        r"disk is full \(100,000 B free; the checkpoint needs about [\d,]+ B\)",
                        one_line(res))
    assert not (out / LOCK).exists() and not list(out.glob(".checkpoint*"))
    assert (out / "history.csv").exists()  # what was written is kept


def test_a_stale_lock_is_taken_over_and_a_live_one_refuses(tmp_path):
    dead = subprocess.Popen([sys.executable, "-c", "pass"])
    dead.wait()
    out = tmp_path / "run"
    out.mkdir()
    (out / LOCK).write_text(json.dumps({"pid": dead.pid}))
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(out), *SHORT])
    assert res.exit_code == 0, res.output
    assert not (out / LOCK).exists()
    # a live process's lock (here: this test's parent process)
    other = tmp_path / "other"
    other.mkdir()
    (other / LOCK).write_text(json.dumps({"pid": os.getppid()}))
    with pytest.raises(OutputError, match="in use by another run"):
        check_run_dir(other)
    with pytest.raises(OutputError, match="in use by another run"):
        RunLock(other).acquire()
    # a run killed but not yet reaped by its parent (a zombie, e.g. a Dask worker) is gone
    killed = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(60)"])
    try:
        killed.kill()
        time.sleep(0.2)
        (other / LOCK).write_text(json.dumps({"pid": killed.pid}))
        with RunLock(other):
            assert json.loads((other / LOCK).read_text())["pid"] == os.getpid()
    finally:
        killed.wait()
    # another machine's lock cannot be checked from here: refused, with what to do
    (other / LOCK).write_text(json.dumps({"pid": 1, "host": "elsewhere.example"}))
    with pytest.raises(OutputError, match=r"process 1 on elsewhere.example.*if no run is "):
        check_run_dir(other)
    # this process's own lock, held: a second run here at once is refused too
    with RunLock(out), pytest.raises(OutputError, match="in use"):
        RunLock(out).acquire()
    assert not (out / LOCK).exists()
    # a lock left by an earlier process with this process's id is stale
    (out / LOCK).write_text(json.dumps({"pid": os.getpid()}))
    with RunLock(out):
        assert json.loads((out / LOCK).read_text())["pid"] == os.getpid()


def test_data_files_respect_the_umask(tmp_path):
    case = load_case("bars", ["time.end=1e-6", "output.figures=false",
                              "output.checkpoint_interval=5e-7", "output.vtk_interval=5e-7"])
    old = os.umask(0o027)
    try:
        run_case(case, tmp_path / "run")
    finally:
        os.umask(old)
    paths = list((tmp_path / "run").rglob("*"))
    assert {p.name for p in paths} >= {"checkpoint.h5", "history.csv", "summary.json",
                                       "particles.pvd", "particles_00000.vtu", "vtk"}
    for p in paths:
        assert p.stat().st_mode & 0o777 == (0o750 if p.is_dir() else 0o640), p


def test_checkpoint_checksum_covers_every_array(tmp_path):
    sim = Simulation(load_case("bars", ["time.end=1e-6"]))
    sim.run()
    path = write_checkpoint(sim, tmp_path / "c.h5")
    with h5py.File(path, "a") as f:
        names = []
        f.visititems(lambda n, o: names.append(n) if isinstance(o, h5py.Dataset) else None)
    assert len(names) > 20
    for name in ("state/density", "neighbours/indices", "record/history"):
        copy = tmp_path / "x.h5"
        copy.write_bytes(path.read_bytes())
        with h5py.File(copy, "a") as f:
            data = f[name][()]
            data.flat[0] = data.flat[0] + 1 if data.dtype.kind in "iu" else np.nextafter(
                data.flat[0], np.inf)
            f[name][...] = data
        with pytest.raises(CaseError, match="corrupted"):
            verify_checkpoint(copy)


def test_a_checkpoint_damaged_near_its_end_is_refused_as_such(checkpoint, tmp_path):
    """A bit flipped in HDF5's own structures near the end of the file made reading the
    checksum's attribute fail, and that was reported as the output directory's write error
    (an audit, 2026-12-08)."""
    def damaged(self, name, default=None):  # what h5py raised for that file's attributes
        raise OSError("Can't synchronously read data (address of object past end of "
                      "allocation)")

    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(h5py.AttributeManager, "get", damaged)
        line = refused_restart(checkpoint, tmp_path / "e")
    assert line.endswith(": corrupted: cannot be read (Can't synchronously read data (address "
                         "of object past end of allocation)); it cannot be used"), line


def restart_line(checkpoint: Path, out: Path, *sets: str) -> tuple[int, str]:
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(out), "--restart",
                              str(checkpoint), "--set", "output.snapshot_times=[]",
                              "--set", "output.figures=false",
                              *(a for s in sets for a in ("--set", s))])
    return res.exit_code, (one_line(res) if res.exit_code else res.output)


def test_what_a_restart_may_change_and_what_it_may_not(checkpoint, tmp_path):
    """A restart continues its run: an end time before the checkpoint's, a change of the
    probes (whose samples from t = 0 the checkpoint carries by name) or of the physics are
    refused before any work, each naming its field; the thread count may change (the same
    bits at any count)."""
    code, line = restart_line(checkpoint, tmp_path / "a", "time.end=1e-6")
    assert code == 2 and line.endswith("time.end = 1e-06 is before the checkpoint's time, "
                                       "t = 2e-06 s; a restart runs forward only (a later "
                                       "time.end extends the run)"), line
    code, line = restart_line(checkpoint, tmp_path / "b", "time.end=3e-6", "output.probes=[]")
    assert code == 2 and "differs from the checkpoint's in output.probes (only" in line, line
    code, line = restart_line(checkpoint, tmp_path / "c", "time.end=3e-6",
                              "viscosity.alpha1=0.5")
    assert code == 2 and "in viscosity.alpha1 (only" in line, line
    assert not any((tmp_path / d).exists() for d in "abc")
    code, line = restart_line(checkpoint, tmp_path / "d", "time.end=2.2e-6", "compute.threads=1")
    assert code == 0, line


def test_a_restart_into_another_runs_directory_is_refused(checkpoint, tmp_path):
    """A restart writes into its own run's directory or an empty one: another case's run
    there had its figures left beside this run's history (an audit, 2026-12-08)."""
    other = tmp_path / "other"
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(other), *SHORT,
                              "--set", "name=not_the_bars"])
    assert res.exit_code == 0, res.output
    before = sorted(p.name for p in other.iterdir())
    code, line = restart_line(checkpoint, other, "time.end=3e-6")
    assert code == 2 and line == (f"error: --out {other} holds another run (its case.json "
                                  f"differs in name): a restart writes into its own run's "
                                  f"directory or an empty one"), line
    assert sorted(p.name for p in other.iterdir()) == before
    mine = tmp_path / "mine"
    mine.mkdir()
    (mine / "notes.txt").write_text("mine\n")
    code, line = restart_line(checkpoint, mine, "time.end=3e-6")
    assert code == 2 and "holds files but no run (no case.json)" in line, line
    # its own run's directory (a copy: the module's checkpoint stays for the other tests)
    import shutil

    own = tmp_path / "own"
    shutil.copytree(checkpoint.parent, own)
    code, line = restart_line(own / "checkpoint.h5", own, "time.end=2.1e-6")
    assert code == 0, line


def test_a_restarts_estimate_counts_the_steps_left(checkpoint, tmp_path):
    """The run time of a restart is estimated from its checkpoint's time (it was estimated
    from t = 0, an audit, 2026-12-08)."""
    from impactsph.preflight import estimate

    res = runner.invoke(app, ["run", "bars", "--out", str(tmp_path / "r"), "--restart",
                              str(checkpoint), "--set", "time.end=3e-6",
                              "--set", "output.snapshot_times=[]",
                              "--set", "output.figures=false"])
    assert res.exit_code == 0, res.output
    [line] = [ln for ln in res.output.splitlines() if ln.startswith("estimated run time")]
    assert "from the checkpoint's t = 2e-06 s" in line
    case = load_case("bars", ["time.end=3e-6"])
    whole, left = estimate(case, [101, 101]), estimate(case, [101, 101], start=2e-6)
    assert left.steps == pytest.approx(whole.steps / 3, abs=1)
    assert left.seconds < whole.seconds and left.memory == whole.memory


def test_a_summary_made_while_running_counts_the_time_so_far():
    """``summary.json`` written at a checkpoint (status running) counts the wall time of the
    steps so far, as the checkpoint does (it said 0 s until the run call ended, a review,
    2026-12-08); no timing is asserted, only that the time is counted."""
    sim = Simulation(load_case("bars", ["time.end=1e-6", "output.figures=false"]))
    seen = []
    sim.run(callback=lambda s: seen.append(s.summary()["wall_seconds"])
            if s.state.step == 20 else None)
    assert len(seen) == 1 and seen[0] > 0.0
    assert sim.summary()["wall_seconds"] == sim.record.wall_seconds  # (after the call)


def test_a_restart_into_its_own_run_of_an_older_case_json(checkpoint, tmp_path):
    """A run directory whose case.json an older version wrote (a field added since is not
    in it) is still its own run's: the held case is validated before it is compared, as the
    checkpoint's is (a review, 2026-12-08)."""
    import shutil

    own = tmp_path / "own"
    shutil.copytree(checkpoint.parent, own)
    record = json.loads((own / "case.json").read_text())
    del record["case"]["contact"]["penalty_distance"]
    (own / "case.json").write_text(json.dumps(record))
    code, line = restart_line(own / "checkpoint.h5", own, "time.end=2.1e-6")
    assert code == 0, line


def test_a_checkpoint_is_hashed_once_a_process_while_it_is_unchanged(checkpoint, tmp_path,
                                                                    monkeypatch):
    """``impactsph run --restart`` verifies before its preflight and ``run_case`` again: the
    second skips the SHA-256 of an unchanged file (a review, 2026-12-08); a changed file is
    hashed again, and refused."""
    import shutil

    import impactsph.checkpoint as ck

    copy = tmp_path / "c.h5"
    shutil.copy(checkpoint, copy)
    calls = []
    real = ck.digest
    monkeypatch.setattr(ck, "digest", lambda f: calls.append(1) or real(f))
    verify_checkpoint(copy)
    verify_checkpoint(copy)
    assert len(calls) == 1
    with h5py.File(copy, "a") as f:
        f.attrs["time"] = 1.5e-6
    with pytest.raises(CaseError, match="corrupted"):
        verify_checkpoint(copy)
    assert len(calls) == 2
