"""Animations of a run's particles (``impactsph animate RUN --field NAME``): one frame per
snapshot of ``snapshots.npz`` (``output.snapshot_times``), the particles coloured by a field,
with a colour bar in the field's unit and the time in the title.

- 1D: the field along x, one line per body;
- 2D: the particles in the plane, coloured;
- 3D: a mid-plane section, the material points within one spacing of the plane through the
  bodies' centre normal to ``section`` (``y`` by default), chosen at t = 0 and followed.

Written as MP4 by matplotlib's ffmpeg writer where ffmpeg is installed, else as a GIF by the
Pillow writer (Pillow comes with matplotlib); ``out``'s suffix (``.mp4``, ``.gif``) chooses.
The colour scale is the same in every frame (the field's range over all of them); a field
that takes both signs is drawn on a diverging map centred on 0.

Fields (:func:`field_names`): the stored arrays (``density``, ``pressure``,
``specific_energy``, ``plastic_work``, ...), a vector's magnitude or component (``velocity``,
``velocity_x``, ...), and the derived ``displacement`` (``|x - x0|``, and its components),
``speed`` (``|v|``), ``von_mises_stress`` and the deviatoric stress components
(``deviatoric_stress_xy``, ...), and each state of the strength models by its name.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from .errors import CaseError

#: vector fields stored in a snapshot, and their unit
VECTORS = {"position": "m", "initial_position": "m", "velocity": "m/s",
           "hourglass_acceleration": "m/s^2"}
#: scalar fields stored in a snapshot, and their unit (masses per unit depth in 2D, per unit
#: cross-section in 1D)
SCALARS = {"density": "kg/m^3", "specific_energy": "J/kg", "pressure": "Pa",
           "plastic_work": "J/kg", "mass": "kg", "smoothing_length": "m", "body": "",
           "material": "", "clamped": ""}
#: the mass's unit by dimension
MASS_UNITS = {1: "kg/m^2", 2: "kg/m", 3: "kg"}
AXES = "xyz"


def field_names(snapshot: dict[str, Any], case: Any) -> list[str]:
    """The names :func:`field_values` takes for a run's snapshots."""
    dim = case.dimension
    names = ["displacement", *[f"displacement_{a}" for a in AXES[:dim]], "speed"]
    for v in VECTORS:
        if v in snapshot and np.ndim(snapshot[v]) == 2 and snapshot[v].shape[1] > 0:
            names += [v, *[f"{v}_{a}" for a in AXES[: snapshot[v].shape[1]]]]
    names += [s for s in SCALARS if s in snapshot]
    if "deviatoric_stress" in snapshot:
        names += ["von_mises_stress",
                  *[f"deviatoric_stress_{a}{b}" for a in AXES for b in AXES if a <= b]]
    names += list(_state_columns(case))
    return names


def _state_columns(case: Any) -> dict[str, int]:
    """The material state's fields of the case's materials: name -> column."""
    from .materials import TableLayout

    layout = TableLayout.registered()
    columns: dict[str, int] = {}
    for material in case.materials.values():
        for name, c in layout.state_names(material).items():
            columns.setdefault(name, c)
    return columns


def field_values(snapshot: dict[str, Any], name: str, case: Any) -> tuple[np.ndarray, str]:
    """The values of the field ``name`` (one per particle) in a snapshot, and its unit.
    :class:`CaseError` for a name that is not a field, with the names that are close."""
    dim = case.dimension
    base, _, axis = name.rpartition("_")
    if name == "speed":
        return np.linalg.norm(snapshot["velocity"], axis=1), "m/s"
    if name == "displacement":
        return np.linalg.norm(snapshot["position"] - snapshot["initial_position"], axis=1), "m"
    if base == "displacement" and axis in AXES[:dim]:
        k = AXES.index(axis)
        return snapshot["position"][:, k] - snapshot["initial_position"][:, k], "m"
    if name in VECTORS and name in snapshot and np.ndim(snapshot[name]) == 2 \
            and snapshot[name].shape[1] > 0:
        return np.linalg.norm(snapshot[name], axis=1), VECTORS[name]
    if base in VECTORS and base in snapshot and axis in AXES[: np.shape(snapshot[base])[1]]:
        return snapshot[base][:, AXES.index(axis)], VECTORS[base]
    if name in SCALARS and name in snapshot:
        unit = MASS_UNITS[dim] if name == "mass" else SCALARS[name]
        return np.asarray(snapshot[name], dtype=np.float64), unit
    if name == "von_mises_stress" and "deviatoric_stress" in snapshot:
        from .models.strength.von_mises import von_mises_stress

        return von_mises_stress(snapshot["deviatoric_stress"]), "Pa"
    if base == "deviatoric_stress" and len(axis) == 2 and set(axis) <= set(AXES):
        a, b = AXES.index(axis[0]), AXES.index(axis[1])
        return snapshot["deviatoric_stress"][:, a, b], "Pa"
    states = _state_columns(case)
    if name in states and snapshot["material_state"].shape[1] > states[name]:
        return snapshot["material_state"][:, states[name]], ""
    from .loading import did_you_mean

    names = field_names(snapshot, case)
    raise CaseError(f"--field {name!r} is not a field of the snapshots{did_you_mean(name, names)}"
                    f" (fields: {', '.join(names)})")


def choose_writer(out: Path | None, run_dir: Path, field: str) -> tuple[Path, str]:
    """The file and the writer (``ffmpeg`` or ``pillow``): ``out``'s suffix decides, else
    MP4 where ffmpeg is installed, else GIF, as ``RUN/animation_FIELD.mp4|gif``."""
    from matplotlib import animation

    ffmpeg = animation.writers.is_available("ffmpeg")
    if out is None:
        out = run_dir / f"animation_{field}.{'mp4' if ffmpeg else 'gif'}"
    suffix = out.suffix.lower()
    if suffix == ".gif":
        return out, "pillow"
    if suffix == ".mp4":
        if not ffmpeg:
            raise CaseError(f"--out {out}: an MP4 needs ffmpeg, which is not installed "
                            f"(give a .gif)")
        return out, "ffmpeg"
    raise CaseError(f"--out {out}: the animation is written as .mp4 or .gif")


def _spacing(snapshot: dict[str, Any], case: Any) -> np.ndarray | float:
    """Each particle's spacing: its body's (:func:`impactsph.preflight.body_spacing`, the
    spacing its smoothing length was scaled from at t = 0; the snapshot's h may have grown
    since, ``kernel.max_stretch``)."""
    from .preflight import body_spacing

    spacings = np.array([body_spacing(b.geometry) for b in case.bodies])
    if "body" not in snapshot:
        return float(spacings.min())
    return spacings[np.asarray(snapshot["body"], dtype=np.int64)]


def _frames(run: dict[str, Any], case: Any, field: str, section: str
            ) -> tuple[list[dict[str, Any]], str, list[str]]:
    """Per snapshot: time, plot coordinates (m) and values; the unit; the axes' names."""
    snaps = run["snapshots"]
    dim = case.dimension
    first = snaps[0]
    keep = np.ones(first["position"].shape[0], dtype=bool)
    plotted = list(range(dim))
    if dim == 3:
        normal = AXES.index(section)
        plotted = [a for a in range(3) if a != normal]
        x0 = first["initial_position"]
        dx = _spacing(first, case)
        centre = 0.5 * (x0[:, normal].min() + x0[:, normal].max())
        keep = np.abs(x0[:, normal] - centre) < dx
    frames, unit = [], ""
    for snap in snaps:
        values, unit = field_values(snap, field, case)
        frames.append({"time": snap["time"], "x": snap["position"][keep][:, plotted],
                       "values": np.asarray(values, dtype=np.float64)[keep],
                       "body": snap["body"][keep]})
    return frames, unit, [AXES[a] for a in plotted]


def animate_run(run_dir: Path | str, field: str | None = None, out: Path | str | None = None,
                *, fps: float = 4.0, section: str = "y") -> Path:
    """Write the animation of the run in ``run_dir`` coloured by ``field`` (None: the case's
    problem's :attr:`~impactsph.problems.ProblemKind.animation_field`) into ``out`` (see
    :func:`choose_writer`); return its path.  :class:`CaseError` for a run without
    snapshots, an unknown field or an unusable ``out``."""
    from matplotlib import animation, colors

    from .atomic import atomic_path
    from .loading import validate_case
    from .output import load_run
    from .plotting import plt
    from .problems.registry import get_problem

    run_dir = Path(run_dir)
    run = load_run(run_dir)
    case = validate_case(run["case"])
    if not run["snapshots"]:
        times = case.output.snapshot_times
        reached = run.get("summary", {}).get("t_end")
        if not times:
            why = "the case has no output.snapshot_times"
        elif min(times) > case.time.end * (1 + 1e-9):
            why = (f"its output.snapshot_times ({', '.join(f'{t:g}' for t in times)} s) all "
                   f"lie after its end, time.end = {case.time.end:g} s")
        elif isinstance(reached, int | float) and reached < min(times):
            status = run.get("summary", {}).get("status")
            why = (f"the run stopped at t = {reached:g} s" + (f" ({status})" if status else "")
                   + f", before its first snapshot time, {min(times):g} s")
        else:
            why = "none of its output.snapshot_times was reached"
        raise CaseError(f"{run_dir} has no snapshots to animate (snapshots.npz is empty: "
                        f"{why}): run the case with snapshot times within the run, e.g. "
                        f"--set 'output.snapshot_times=[1e-6, 2e-6, 3e-6]'")
    field = field or get_problem(case.analysis).animation_field
    if section not in AXES:
        raise CaseError(f"--section {section!r}: give x, y or z")
    path, writer_name = choose_writer(None if out is None else Path(out), run_dir, field)
    frames, unit, names = _frames(run, case, field, section)
    label = f"{field} ({unit})" if unit else field
    values = np.concatenate([f["values"] for f in frames])
    values = values[np.isfinite(values)]
    lo, hi = (float(values.min()), float(values.max())) if values.size else (0.0, 1.0)
    if lo < 0 < hi:
        top = max(-lo, hi)
        norm, cmap = colors.Normalize(-top, top), "coolwarm"
    else:
        if hi <= lo:
            lo, hi = lo - (abs(lo) or 1.0) * 1e-3, hi + (abs(hi) or 1.0) * 1e-3
        norm, cmap = colors.Normalize(lo, hi), "viridis"
    xs = np.concatenate([f["x"] for f in frames]) * 1e3
    lower, upper = xs.min(axis=0), xs.max(axis=0)
    pad = 0.05 * np.maximum(upper - lower, 1e-9) + 1e-6

    dim = case.dimension
    fig, ax = plt.subplots(figsize=(7, 5) if dim > 1 else (7, 4))
    title = (f"{case.name}: {field}" + (f", section normal to {section} through the middle"
                                        if dim == 3 else ""))
    if dim == 1:
        bodies = np.unique(frames[0]["body"])
        lines = [ax.plot([], [], ".-", ms=3, label=f"body {int(b)}")[0] for b in bodies]
        ax.set_xlim(lower[0] - pad[0], upper[0] + pad[0])
        span = norm.vmax - norm.vmin
        ax.set_ylim(norm.vmin - 0.05 * span, norm.vmax + 0.05 * span)
        ax.set_xlabel("x (mm)")
        ax.set_ylabel(label)
        ax.grid(alpha=0.3)
        names_of = {k: b.name for k, b in enumerate(case.bodies)}
        for line, b in zip(lines, bodies, strict=True):
            line.set_label(names_of.get(int(b), f"body {int(b)}"))
        ax.legend(fontsize=8)

        def draw(k: int) -> list[Any]:
            f = frames[k]
            for line, b in zip(lines, bodies, strict=True):
                sel = f["body"] == b
                order = np.argsort(f["x"][sel, 0])
                line.set_data(f["x"][sel, 0][order] * 1e3, f["values"][sel][order])
            ax.set_title(f"{title}, t = {f['time'] * 1e6:.4g} us", fontsize=10)
            return lines
    else:
        ax.set_xlim(lower[0] - pad[0], upper[0] + pad[0])
        ax.set_ylim(lower[1] - pad[1], upper[1] + pad[1])
        ax.set_aspect("equal")
        ax.set_xlabel(f"{names[0]} (mm)")
        ax.set_ylabel(f"{names[1]} (mm)")
        ax.grid(alpha=0.2)
        fig.canvas.draw()
        # markers 0.8 of a particle spacing across
        box = ax.get_window_extent()
        points_per_mm = min(box.width / (upper[0] - lower[0] + 2 * pad[0]),
                            box.height / (upper[1] - lower[1] + 2 * pad[1])) * 72 / fig.dpi
        first = run["snapshots"][0]
        dx = float(np.median(_spacing(first, case)))
        size = float(np.clip((0.8 * dx * 1e3 * points_per_mm) ** 2, 0.5, 200.0))
        scatter = ax.scatter(frames[0]["x"][:, 0] * 1e3, frames[0]["x"][:, 1] * 1e3, s=size,
                             c=frames[0]["values"], cmap=cmap, norm=norm, linewidths=0)
        fig.colorbar(scatter, ax=ax, label=label)

        def draw(k: int) -> list[Any]:
            f = frames[k]
            scatter.set_offsets(f["x"] * 1e3)
            scatter.set_array(f["values"])
            ax.set_title(f"{title}, t = {f['time'] * 1e6:.4g} us", fontsize=10)
            return [scatter]

    anim = animation.FuncAnimation(fig, draw, frames=len(frames), blit=False)
    writer = (animation.PillowWriter(fps=fps) if writer_name == "pillow"
              else animation.FFMpegWriter(fps=fps))
    try:
        with atomic_path(path) as tmp:
            anim.save(tmp, writer=writer, dpi=100)
    finally:
        plt.close(fig)
    return path
