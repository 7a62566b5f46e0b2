"""ParaView output, checkpoints and restart."""

from __future__ import annotations

import os
import shutil
import signal
import subprocess
import sys
import time
import xml.etree.ElementTree as ET

import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from impactsph.atomic import atomic_path, write_text
from impactsph.checkpoint import load_checkpoint, write_checkpoint
from impactsph.cli import app
from impactsph.errors import CaseError
from impactsph.loading import load_case
from impactsph.neighbours import NeighbourList
from impactsph.runner import run_case
from impactsph.simulation import Simulation

runner = CliRunner()
FIELDS = {"velocity": 3, "density": 1, "pressure": 1, "deviatoric_stress": 9,
          "von_mises_stress": 1, "plastic": 1, "specific_internal_energy": 1, "body": 1,
          "plastic_work": 1}


def read_vtu_ascii(path):
    """An independent reader (the standard library's XML parser) for ASCII .vtu files."""
    root = ET.parse(path).getroot()
    piece = root.find("UnstructuredGrid/Piece")
    n = int(piece.get("NumberOfPoints"))
    data = {}
    for arr in piece.find("PointData"):
        values = np.array(arr.text.split(), dtype=float)
        comps = int(arr.get("NumberOfComponents", "1"))
        data[arr.get("Name")] = values.reshape(n, comps) if comps > 1 else values
    points = np.array(piece.find("Points/DataArray").text.split(), dtype=float).reshape(n, 3)
    return n, points, data


def test_vtk_series_reads_back(tmp_path):
    case = load_case("taylor", ["time.end=4e-6", "output.vtk_interval=1e-6",
                                'output.vtk_format="ascii"', "output.figures=false"])
    run_case(case, tmp_path)
    index = ET.parse(tmp_path / "vtk" / "particles.pvd").getroot()
    entries = [(float(d.get("timestep")), d.get("file")) for d in index.iter("DataSet")]
    assert len(entries) == 5  # t = 0, then at the first step past 1, 2, 3 us, and 4 us (the end)
    assert entries[0][0] == 0.0 and entries[-1][0] == pytest.approx(4e-6)
    n, points, data = read_vtu_ascii(tmp_path / "vtk" / entries[-1][1])
    assert n == 21 * 67
    assert set(FIELDS) <= set(data)
    for name, comps in FIELDS.items():
        assert data[name].shape == ((n, comps) if comps > 1 else (n,)), name
    assert np.all(points[:, 2] == 0.0) and points[:, 1].min() > 0.0
    assert data["density"].min() > 7000 and data["von_mises_stress"].max() <= 600e6 * 1.0001
    assert data["plastic"].sum() > 0  # the impact end has yielded
    # the first snapshot is the initial state
    _, _, first = read_vtu_ascii(tmp_path / "vtk" / entries[0][1])
    np.testing.assert_allclose(first["velocity"][:, 1], -200.0)


def test_vtk_binary_has_the_same_structure(tmp_path):
    import meshio

    case = load_case("bars", ["time.end=2e-6", "output.vtk_interval=1e-6",
                              "output.figures=false"])
    run_case(case, tmp_path)
    files = sorted((tmp_path / "vtk").glob("*.vtu"))
    root = ET.parse(files[-1]).getroot()  # the XML skeleton is readable without meshio
    piece = root.find("UnstructuredGrid/Piece")
    assert int(piece.get("NumberOfPoints")) == 202
    assert {a.get("Name") for a in piece.find("PointData")} >= set(FIELDS)
    mesh = meshio.read(files[-1])
    assert mesh.points.shape == (202, 3)


def final_arrays(sim):
    return {k: v.copy() for k, v in sim.state.arrays().items()}


def _halfway_checkpoint(tmp_path):
    """The shortened Taylor bar run to half its 2 us and checkpointed there: ``(case, sim,
    path)``, the simulation ready to run on to the end."""
    case = load_case("taylor", ["time.end=2e-6"])
    sim = Simulation(case)
    sim.run(t_end=1e-6)
    return case, sim, write_checkpoint(sim, tmp_path / "checkpoint.h5")


@pytest.mark.parametrize("case_name,overrides", [
    ("bars", ["time.end=12e-6"]),
    # total-Lagrangian bodies in contact: the contact list is rebuilt after a restart
    ("bars", ["time.end=6e-6", 'formulation="total_lagrangian"']),
    ("taylor", ["time.end=6e-6"]),  # walls (ghosts), plasticity, AC
    # the particles renumbered in the list's order: the restart builds the same numbering
    ("taylor", ["time.end=6e-6", 'compute.particle_order="cells"']),
    # a total-Lagrangian body on a wall: the walls' step limit is read from the state
    ("taylor", ["time.end=6e-6", 'formulation="total_lagrangian"', 'viscosity.scheme="av"']),
    # a viscosity switch: its factors are state that the next evaluation reads
    ("taylor", ["time.end=6e-6", 'viscosity.scheme="balsara"']),
    # a kernel that follows the stretch: h is state, set at each list build from the
    # restored list, and h0 comes from the case, not from the restored state
    ("taylor", ["time.end=6e-6", "kernel.max_stretch=1.25"]),
    # the three-stage integrator, with a switch whose memory and clock are state
    ("taylor", ["time.end=6e-6", 'viscosity.scheme="cullen_dehnen"',
                'time.integrator="ssp_rk3"', "time.courant=0.45"]),
    # axisymmetry: the radius in the material state, and the axis's mirror ghosts, whose
    # results are mirrored by the records' places in the restored list's order (before this
    # case was added a restart kept the places of the list built at start-up: 1e-6 apart)
    ("taylor_axisymmetric", ["time.end=6e-6"]),
    # the compatible energy update: its work pass reads the restored list and ghosts
    ("taylor_axisymmetric", ["time.end=6e-6", 'time.energy_update="compatible"']),
    # 3D: the list's rows split where their skin starts (neighbours.py), which the passes
    # read (coarsened to 1,404 particles, as tests/test_taylor3d.py)
    ("taylor3d", ["time.end=4e-6", "bodies.0.geometry.spacing=0.95e-3"]),
])
def test_restart_is_bitwise_identical(tmp_path, case_name, overrides):
    end = float(overrides[0].split("=")[1])
    case = load_case(case_name, [*overrides, f"output.checkpoint_interval={end / 3.5}",
                                 "output.figures=false"])
    whole = tmp_path / "whole"
    run_case(case, whole)
    reference = Simulation(case)
    reference.run()
    ckpt = whole / "checkpoint.h5"
    restarted = load_checkpoint(ckpt, case)
    assert 0 < restarted.state.time < end
    t_ckpt = restarted.state.time
    restarted.run()
    for name, arr in final_arrays(reference).items():
        np.testing.assert_array_equal(restarted.state.arrays()[name], arr, err_msg=name)
    assert restarted.state.step == reference.state.step
    assert restarted.summary()["momentum_drift"] == reference.summary()["momentum_drift"]
    assert len(restarted.record.history) == len(reference.record.history)
    # through the command line, into its own directory
    res = runner.invoke(app, ["run", case_name, "--quiet", "--out", str(tmp_path / "cli"),
                              "--restart", str(ckpt), *sum((["--set", o] for o in overrides),
                                                           [])])
    assert res.exit_code == 0, res.output
    assert t_ckpt < restarted.state.time


def test_restart_refuses_another_case(tmp_path):
    case = load_case("bars", ["time.end=3e-6", "output.checkpoint_interval=1e-6",
                              "output.figures=false"])
    run_case(case, tmp_path)
    res = runner.invoke(app, ["run", "bars", "--quiet", "--out", str(tmp_path / "b"),
                              "--restart", str(tmp_path / "checkpoint.h5"),
                              "--set", "viscosity.alpha1=0.9"])
    assert res.exit_code == 2
    assert "viscosity" in res.output and len(res.output.strip().splitlines()) == 1
    res = runner.invoke(app, ["run", "bars", "--quiet", "--restart",
                              str(tmp_path / "history.csv")])
    assert res.exit_code == 2


def test_checkpoint_survives_sigkill_while_writing(tmp_path):
    """A writer killed mid-write leaves the previous checkpoint loadable: checkpoints are
    written to a temporary file and renamed."""
    sim = Simulation(load_case("bars", ["time.end=1e-6"]))
    sim.run()
    path = tmp_path / "checkpoint.h5"
    write_checkpoint(sim, path)
    good = path.read_bytes()
    script = (
        "import time, impactsph.checkpoint as c\n"
        "from impactsph.loading import load_case\n"
        "from impactsph.simulation import Simulation\n"
        "import h5py\n"
        "orig = h5py.File.create_dataset if hasattr(h5py.File, 'create_dataset') else None\n"
        "sim = Simulation(load_case('bars', ['time.end=2e-6'])); sim.run()\n"
        "import h5py._hl.group as g\n"
        "real = g.Group.create_dataset\n"
        "def slow(self, *a, **k):\n"
        "    out = real(self, *a, **k); time.sleep(0.05); return out\n"
        "g.Group.create_dataset = slow\n"
        "print('writing', flush=True)\n"
        f"c.write_checkpoint(sim, {str(path)!r})\n"
    )
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE,
                            env={**os.environ, "PYTHONUNBUFFERED": "1"})
    assert proc.stdout.readline().strip() == b"writing"
    time.sleep(0.3)  # inside the write: datasets are being created slowly
    proc.send_signal(signal.SIGKILL)
    proc.wait()
    assert path.read_bytes() == good  # untouched
    again = load_checkpoint(path)
    assert again.state.time == pytest.approx(1e-6)


def test_atomic_path_writes_whole_or_leaves_the_old_file(tmp_path):
    path = tmp_path / "figure.png"
    write_text(path, "old")
    with pytest.raises(RuntimeError), atomic_path(path) as tmp:
        assert tmp.parent == path.parent and tmp.name.startswith(".")
        assert tmp.suffix == ".png"  # writers that infer the format from it get it right
        tmp.write_text("half")
        raise RuntimeError("killed")
    assert path.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["figure.png"]  # no temporary left
    with atomic_path(path) as tmp:
        tmp.write_text("new")
        assert path.read_text() == "old"  # not before the block ends
    assert path.read_text() == "new" and len(list(tmp_path.iterdir())) == 1
    reference = tmp_path / "plain"
    reference.write_text("")  # written files get the usual permissions (not mkstemp's 0600)
    assert path.stat().st_mode == reference.stat().st_mode


def test_checkpoint_of_an_older_version_with_more_accumulators_loads(tmp_path):
    """Datasets an older version wrote and nothing reads any more are ignored."""
    case = load_case("bars", ["time.end=2e-6"])
    sim = Simulation(case)
    sim.run(t_end=1e-6)
    path = write_checkpoint(sim, tmp_path / "checkpoint.h5")
    with h5py.File(path, "a") as f:
        del f.attrs["sha256"]  # older versions wrote no checksum
        f["accumulators"].create_dataset("initial_kinetic", data=1.0)
        f["accumulators"].create_dataset("initial_internal", data=0.0)
        f["accumulators"].create_dataset("initial_momentum", data=np.zeros(1))
    again = load_checkpoint(path, case)
    again.run()
    sim.run()
    for name, arr in final_arrays(sim).items():
        np.testing.assert_array_equal(again.state.arrays()[name], arr, err_msg=name)


def test_checkpoint_before_the_thickness_ratio_loads(tmp_path):
    """A 0.2.0 checkpoint written before the thickness ratio joined the common material state
    (the registered width less one column, no ``common_state`` attribute, no viscosity
    factors) continues with ratio 1 and factors 1, as the run it came from; a state of
    another width is refused."""
    from impactsph.materials import TableLayout
    from impactsph.models.columns import THICKNESS_RATIO

    case, sim, path = _halfway_checkpoint(tmp_path)
    with h5py.File(path, "a") as f:
        del f.attrs["sha256"]
        ms = f["state"]["material_state"][()]
        del f["state"]["material_state"], f["state"]["viscosity_factor"]
        del f["state"].attrs["common_state"]
        # 0.2.0 stored the registered models' union of columns
        old = np.zeros((ms.shape[0], TableLayout.registered().state_width - 1))
        old[:, :ms.shape[1] - 1] = np.delete(ms, THICKNESS_RATIO, 1)
        f["state"].create_dataset("material_state", data=old)
    again = load_checkpoint(path, case)
    again.run()
    sim.run()
    for name, arr in final_arrays(sim).items():
        np.testing.assert_array_equal(again.state.arrays()[name], arr, err_msg=name)
    with h5py.File(path, "a") as f:
        ms = f["state"]["material_state"][()]
        del f["state"]["material_state"]
        f["state"].create_dataset("material_state", data=ms[:, :2])
    with pytest.raises(CaseError, match=r"material state has 2 columns, this version's case "
                                        r"needs \d+"):
        load_checkpoint(path, case)


def test_checkpoint_of_the_registered_width_loads(tmp_path):
    """A checkpoint written before the material state was sized to the case's models (the
    registered models' union of columns, the trailing ones unused) continues as the run it
    came from, which now carries fewer columns."""
    from impactsph.materials import TableLayout

    case, sim, path = _halfway_checkpoint(tmp_path)
    assert sim.state.material_state.shape[1] < TableLayout.registered().state_width
    with h5py.File(path, "a") as f:
        del f.attrs["sha256"]
        ms = f["state"]["material_state"][()]
        del f["state"]["material_state"]
        wide = np.zeros((ms.shape[0], TableLayout.registered().state_width))
        wide[:, :ms.shape[1]] = ms
        f["state"].create_dataset("material_state", data=wide)
    again = load_checkpoint(path, case)
    assert again.state.material_state.shape == sim.state.material_state.shape
    again.run()
    sim.run()
    for name, arr in final_arrays(sim).items():
        np.testing.assert_array_equal(again.state.arrays()[name], arr, err_msg=name)


def test_checkpoint_keeps_the_inner_list_and_loads_without_one(tmp_path):
    """The neighbour list's inner list (AC's correction pass reads it: its rows' ends) is
    written and read back; a checkpoint of a version that wrote none continues on the whole
    rows, and one that wrote it as a list of its own (before 2026-12-07) on the rows' inner
    entries, to the same bits."""
    case, sim, path = _halfway_checkpoint(tmp_path)
    kept = load_checkpoint(path, case).solver.neighbours
    nl = sim.solver.neighbours
    assert kept.inner_reach == nl.inner_reach == 0.5
    np.testing.assert_array_equal(kept.inner_ends, nl.inner_ends)
    np.testing.assert_array_equal(kept.indices, nl.indices)
    # as written before 2026-12-07: the inner entries a list of their own (the rows here
    # already hold them first, which the reader's move leaves as they are)
    old = tmp_path / "old.h5"
    shutil.copy(path, old)
    with h5py.File(old, "a") as f:
        del f.attrs["sha256"]
        g = f["neighbours"]
        counts = g["inner_ends"][()] - g["offsets"][()][:-1]
        g.create_dataset("inner_offsets", data=np.concatenate([[0], np.cumsum(counts)])
                         .astype(np.int32))
        g.create_dataset("inner_indices", data=np.concatenate(
            [g["indices"][a:a + c] for a, c in zip(g["offsets"][()][:-1], counts,
                                                    strict=True)]))
        del g["inner_ends"]
    before = load_checkpoint(old, case)
    np.testing.assert_array_equal(before.solver.neighbours.inner_ends, nl.inner_ends)
    np.testing.assert_array_equal(before.solver.neighbours.indices, nl.indices)
    with h5py.File(path, "a") as f:
        del f.attrs["sha256"]
        g = f["neighbours"]
        del g["inner_ends"], g.attrs["inner_reach"], g.attrs["inner_radius"]
    again = load_checkpoint(path, case)
    assert again.solver.neighbours.inner_ends is None
    again.run()
    before.run()
    sim.run()
    for name, arr in final_arrays(sim).items():
        np.testing.assert_array_equal(again.state.arrays()[name], arr, err_msg=name)
        np.testing.assert_array_equal(before.state.arrays()[name], arr, err_msg=name)


def test_checkpoint_without_the_rows_splits_loads_and_a_wrong_split_is_refused(tmp_path):
    """A checkpoint written before the rows were split (no ``splits``) continues with every
    row tested against the support: the same pairs, so the run ends where the uninterrupted
    one does, to round-off; splits of another list's length are refused by name."""
    case, sim, path = _halfway_checkpoint(tmp_path)
    with h5py.File(path, "a") as f:
        del f.attrs["sha256"]
        assert f["neighbours"]["splits"].shape == (sim.solver.neighbours.offsets.shape[0] - 1,)
        del f["neighbours"]["splits"]
    again = load_checkpoint(path, case)
    assert again.solver.neighbours.splits is None
    again.run()
    sim.run()
    for name, arr in final_arrays(sim).items():
        got = again.state.arrays()[name]
        if arr.size == 0 or arr.dtype.kind != "f":
            np.testing.assert_array_equal(got, arr, err_msg=name)
            continue
        np.testing.assert_allclose(got, arr, rtol=0, atol=1e-11 * max(np.abs(arr).max(), 1e-300),
                                   err_msg=name)
    nl = sim.solver.neighbours
    with pytest.raises(ValueError, match=r"splits has shape \(3,\)"):
        NeighbourList(nl.offsets, nl.indices, nl.radius, nl.skin, nl.reference_positions,
                      order=nl.order, splits=nl.splits[:3])


def test_the_history_stream_writes_write_historys_bytes(tmp_path):
    """The stream's rows (floats by ``repr``, ints, and the values csv
    may quote or writes otherwise: a string with a comma, a numpy float, None) are the
    bytes ``write_history`` writes for the same rows."""
    from types import SimpleNamespace

    from impactsph.output import HistoryStream, write_history

    rows = [{"time": 0.0, "step": 0, "energy": 1.0 / 3.0, "note": 1e-300},
            {"time": 1.5e-7, "step": 1, "energy": float("nan"), "note": -0.0},
            {"time": 3e-7, "step": 2, "energy": np.float64(2.5), "note": "a, b"},
            {"time": 4.5e-7, "step": 3, "energy": float("inf"), "note": None}]
    sim = SimpleNamespace(record=SimpleNamespace(history=[rows[0]], probes={}, gauges=[]),
                          case=SimpleNamespace(dimension=2))
    streamed = tmp_path / "streamed"
    whole = tmp_path / "whole"
    streamed.mkdir()
    whole.mkdir()
    stream = HistoryStream(streamed, sim)
    for k in range(1, len(rows)):
        sim.record.history.append(rows[k])
        stream.update(sim)
    stream.close()
    write_history(whole, sim)
    text = (streamed / "history.csv").read_bytes()
    assert text == (whole / "history.csv").read_bytes()
    assert b'"a, b"' in text and b"0.3333333333333333" in text


def test_a_studys_json_records_its_provenance_and_command(tmp_path, monkeypatch):
    """The validation scripts' JSON (resolution.json, taylor3d.json, ...) carried neither the
    version nor the options that made them (an audit, 2026-12-08): ``write_study`` puts the
    provenance and the command before the result, in strict JSON."""
    import json
    import sys

    import impactsph
    from impactsph.output import write_study

    monkeypatch.setattr(sys, "argv", ["validation/resolution.py", "taylor", "--set",
                                      "time.end=2e-5"])
    rows = write_study(tmp_path / "a" / "rows.json", [{"x": 1.0, "y": float("nan")}])
    data = json.loads(rows.read_text())
    assert data["provenance"]["impactsph"] == impactsph.__version__
    assert data["command"] == "validation/resolution.py taylor --set time.end=2e-5"
    assert data["rows"] == [{"x": 1.0, "y": None}]
    table = json.loads(write_study(tmp_path / "t.json", {"runs": {"x1": 2}}).read_text())
    assert table["runs"] == {"x1": 2} and list(table)[:2] == ["provenance", "command"]
