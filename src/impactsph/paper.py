"""The paper's figures for its three examples, with AC overlaid, and the comparison tables.

``impactsph paper CASE --out DIR`` runs every case the figures need (in parallel, through
:func:`~impactsph.sweep.run_many`), then draws them.  For the bars (Example 1):

- ``fig3_alpha2_only.png``: profiles at 5.75 us with alpha1 = 0, alpha2 = 0.5, 1, 1.5, 2;
- ``fig4_alpha_ladder.png``: profiles with alpha1 = alpha2 = 0.05 ... 0.3;
- ``fig5_profiles.png`` and ``fig6_kinetic_energy.png``: AV1, AV2, AV3 and AV (0.3, 0.3);
- ``fig7_profile_ac.png``, ``fig8_mid_velocity_ac.png``, ``fig9_kinetic_energy_ac.png``: AC
  against AV (0.3, 0.3) and theory;
- ``fig7_profile_ac_variants.png``: every reading of AC;

AC (the default reading) is overlaid on Figs 3-6 as well.  ``table.csv`` and ``table.md`` give,
for AV (0.3, 0.3), AV1, AV2, AV3 and every AC reading: kinetic energy kept, profile L1 error and
oscillation, momentum drift, energy error and imbalance, and the surviving viscosity fraction.

For the Taylor bar (Example 2): ``fig11_shapes_av.png`` (AV1, AV2, AV3 at 50 us),
``fig12_kinetic_energy.png`` (AV1, AV2, AV3, AV (0.5, 0.5), AC), ``fig13_shapes.png``
(AV (0.5, 0.5) against AC).  For the cantilever (Example 3): ``fig15_shapes_av.png`` (AV1, AV2,
AV3 at 15.8 ms), ``fig16_low_viscosity.png`` (alpha1 = 0.05, 0.075, 0.1 with alpha2 = 0),
``fig17_shapes.png`` (AV (0.1, 0.1) against AC), and the kinetic energy.  Their tables give the
problem's measures for every run.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from .config import Viscosity, read_case_dict, validate_case
from .output import _csv_text, atomic_write_text, load_run
from .physics.correction import VARIANTS, surviving_fraction
from .sweep import run_many

DEFAULT_AC = Viscosity.model_fields["correction"].default


def _av(a1: float, a2: float) -> list[str]:
    return ["viscosity.scheme=\"av\"", f"viscosity.alpha1={a1}", f"viscosity.alpha2={a2}"]


def _ac(variant: str, energy: str = "work") -> list[str]:
    return ["viscosity.scheme=\"ac\"", f"viscosity.correction=\"{variant}\"",
            f"viscosity.energy_correction=\"{energy}\""]


def bars_runs() -> dict[str, list[str]]:
    """Label -> overrides of every run the bars' figures and table need."""
    runs = {f"AV (0, {a2:g})": _av(0.0, a2) for a2 in (0.5, 1.0, 1.5, 2.0)}
    runs |= {f"AV ({a:g}, {a:g})": _av(a, a) for a in (0.05, 0.1, 0.15, 0.2, 0.25, 0.3)}
    runs |= {"AV1 (1, 1)": _av(1, 1), "AV2 (1, 2)": _av(1, 2), "AV3 (2.5, 2.5)": _av(2.5, 2.5)}
    for variant in VARIANTS:
        for energy in ("work", "paper"):
            runs[f"AC {variant} / {energy}"] = _ac(variant, energy)
    return runs


def paper_figures(case_source: str, out: Path | str, *, workers: int | None = None,
                  scheduler: str | None = None) -> dict[str, Any]:
    """Run and draw the paper's figures and table of the case's example into ``out``."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    base = read_case_dict(case_source)
    analysis = validate_case(base).analysis
    if analysis == "bars":
        return _bars_figures(base, out, workers, scheduler)
    if analysis in ("taylor", "cantilever"):
        return _shape_figures(analysis, base, out, workers, scheduler)
    raise ValueError(f"paper figures exist for the bars, taylor and cantilever examples; this "
                     f"case has analysis = {analysis!r}")


TAYLOR_KEYS = ("final_length_ratio", "footprint_half_width_ratio", "plastic_work",
               "kinetic_energy_ratio_final", "total_energy_relative_error", "momentum_drift")
#: The Taylor bar as a 3D cylinder: the footprint is a radius.
TAYLOR_3D_KEYS = tuple("footprint_radius_ratio" if k == "footprint_half_width_ratio" else k
                       for k in TAYLOR_KEYS)
CANTILEVER_KEYS = ("tip_deflection", "tip_deflection_ratio", "plastic_work",
                   "max_neighbour_gap_over_h", "kinetic_energy_ratio_final",
                   "total_energy_relative_error", "momentum_drift")


def shape_runs(analysis: str) -> dict[str, list[str]]:
    """Label -> overrides of the runs of Figs 11-13 (taylor) or 15-17 (cantilever)."""
    runs = {"AV1 (1, 1)": _av(1, 1), "AV2 (1, 2)": _av(1, 2), "AV3 (2.5, 2.5)": _av(2.5, 2.5)}
    if analysis == "taylor":
        runs["AV (0.5, 0.5)"] = _av(0.5, 0.5)
    else:
        runs |= {f"AV ({a:g}, 0)": _av(a, 0.0) for a in (0.05, 0.075, 0.1)}
        runs["AV (0.1, 0.1)"] = _av(0.1, 0.1)
    runs[f"AC {DEFAULT_AC}"] = _ac(DEFAULT_AC)
    return runs


def _shape_figures(analysis: str, base: dict[str, Any], out: Path, workers: int | None,
                   scheduler: str | None) -> dict[str, Any]:
    from .figures import deformed_shapes_figure
    from .plotting import kinetic_energy_figure

    dimension = validate_case(base).dimension
    runs = shape_runs(analysis)
    labels = list(runs)
    rows = run_many(base, [[*runs[k], "output.figures=false"] for k in labels], out,
                    workers=workers, scheduler=scheduler)
    by_label = dict(zip(labels, rows, strict=True))
    loaded = {lab: load_run(out / "runs" / row["run"]) for lab, row in by_label.items()
              if row.get("status") == "ok"}
    ac = f"AC {DEFAULT_AC}"

    def shapes(names: list[str], name: str, title: str) -> list[Path]:
        sel = [{"label": n, "x": loaded[n]["snapshots"][-1]["position"],
                "x0": loaded[n]["snapshots"][-1]["initial_position"],
                "case": validate_case(loaded[n]["case"])}
               for n in names if n in loaded and loaded[n]["snapshots"]]
        return [deformed_shapes_figure(sel, out / f"{name}.png", title,
                                       separate=analysis == "taylor")] if sel else []

    av = ["AV1 (1, 1)", "AV2 (1, 2)", "AV3 (2.5, 2.5)"]
    if analysis == "taylor":
        ref = "AV (0.5, 0.5)"
        paths = shapes(av, "fig11_shapes_av", "Taylor bar at 50 us: AV1, AV2, AV3")
        paths += shapes([ref, ac], "fig13_shapes", "Taylor bar at 50 us: AV (0.5, 0.5) and AC")
        ke_name = "fig12_kinetic_energy"
        keys = TAYLOR_3D_KEYS if dimension == 3 else TAYLOR_KEYS
    else:
        ref = "AV (0.1, 0.1)"
        paths = shapes(av, "fig15_shapes_av", "Cantilever at 15.8 ms: AV1, AV2, AV3")
        paths += shapes([f"AV ({a:g}, 0)" for a in (0.05, 0.075, 0.1)], "fig16_low_viscosity",
                        "Cantilever at 15.8 ms: alpha2 = 0")
        paths += shapes([ref, ac], "fig17_shapes", "Cantilever at 15.8 ms: AV (0.1, 0.1) and AC")
        ke_name, keys = "kinetic_energy", CANTILEVER_KEYS
    ke_labels = [*av, ref, ac]
    paths.append(kinetic_energy_figure(
        [{"label": n, "time": loaded[n]["history"]["time"],
          "kinetic_energy": loaded[n]["history"]["kinetic_energy"]}
         for n in ke_labels if n in loaded], out / f"{ke_name}.png",
        title=f"Kinetic energy: {analysis}", dimension=dimension))
    table = []
    for lab in labels:
        summary = loaded[lab]["summary"] if lab in loaded else {}
        table.append({"run": lab, "status": by_label[lab].get("status", "?").split(":")[0],
                      **{k: summary.get(k) for k in keys}})
    atomic_write_text(out / "table.csv", _csv_text(table))
    atomic_write_text(out / "table.md", markdown_table(table, ["run", "status", *keys]))
    result = {"figures": [str(p) for p in paths], "table": table}
    atomic_write_text(out / "paper.json", json.dumps(result, indent=2, default=float))
    return result


def _bars_figures(base: dict[str, Any], out: Path, workers: int | None,
                  scheduler: str | None) -> dict[str, Any]:
    from .figures import draw_overlays

    runs = bars_runs()
    labels = list(runs)
    overrides = [[*runs[k], "output.figures=false"] for k in labels]
    rows = run_many(base, overrides, out, workers=workers, scheduler=scheduler)
    by_label = {lab: row for lab, row in zip(labels, rows, strict=True)}
    loaded = {lab: load_run(out / "runs" / row["run"]) for lab, row in by_label.items()}
    ac = f"AC {DEFAULT_AC} / work"

    def pick(*names: str) -> list[tuple[str, dict[str, Any]]]:
        return [(n, loaded[n]) for n in names if n in loaded]

    ladder = [f"AV ({a:g}, {a:g})" for a in (0.05, 0.1, 0.15, 0.2, 0.25, 0.3)]
    figures = {
        "fig3_alpha2_only": pick(*[f"AV (0, {a:g})" for a in (0.5, 1, 1.5, 2)], ac),
        "fig4_alpha_ladder": pick(*ladder, ac),
        "fig5_profiles": pick("AV1 (1, 1)", "AV2 (1, 2)", "AV3 (2.5, 2.5)", "AV (0.3, 0.3)",
                              ac),
        "fig7_profile_ac": pick(ac, "AV (0.3, 0.3)"),
        "fig7_profile_ac_variants": pick(*[f"AC {v} / work" for v in VARIANTS],
                                         "AV (0.3, 0.3)"),
    }
    paths = []
    for name, sel in figures.items():
        paths += draw_overlays(sel, out, name, kinds=("profile",))
    paths += draw_overlays(pick("AV1 (1, 1)", "AV2 (1, 2)", "AV3 (2.5, 2.5)", "AV (0.3, 0.3)",
                                ac), out, "fig6_kinetic_energy", kinds=("kinetic_energy",))
    paths += draw_overlays(pick(ac, "AV (0.3, 0.3)"), out, "fig8_mid_velocity_ac",
                           kinds=("mid_velocity",))
    paths += draw_overlays(pick(ac, "AV (0.3, 0.3)"), out, "fig9_kinetic_energy_ac",
                           kinds=("kinetic_energy",))

    table_labels = ["AV (0.3, 0.3)", "AV1 (1, 1)", "AV2 (1, 2)", "AV3 (2.5, 2.5)",
                    *[k for k in labels if k.startswith("AC ")]]
    table = []
    for lab in table_labels:
        row = by_label[lab]
        variant = lab.split()[1] if lab.startswith("AC ") else None
        table.append({
            "run": lab, "status": row.get("status", "?").split(":")[0],
            "kinetic_energy_ratio_final": row.get("kinetic_energy_ratio_final"),
            "velocity_profile_l1_error": row.get("velocity_profile_l1_error"),
            "velocity_profile_oscillation": row.get("velocity_profile_oscillation"),
            "momentum_drift": row.get("momentum_drift"),
            "total_energy_relative_error": row.get("total_energy_relative_error"),
            "energy_imbalance": row.get("energy_imbalance"),
            "surviving_fraction_1d": surviving_fraction(variant, 1) if variant else None,
        })
    atomic_write_text(out / "table.csv", _csv_text(table))
    atomic_write_text(out / "table.md", markdown_table(table))
    result = {"figures": [str(p) for p in paths], "table": table}
    atomic_write_text(out / "paper.json", json.dumps(result, indent=2, default=float))
    return result


BARS_HEAD = ["run", "status", "KE kept", "profile L1", "oscillation", "momentum drift",
             "energy error", "energy imbalance", "1 - sum w (1D)"]
BARS_KEYS = ["run", "status", "kinetic_energy_ratio_final", "velocity_profile_l1_error",
             "velocity_profile_oscillation", "momentum_drift", "total_energy_relative_error",
             "energy_imbalance", "surviving_fraction_1d"]


def markdown_table(rows: list[dict[str, Any]], keys: list[str] | None = None,
                   head: list[str] | None = None) -> str:
    """A comparison table in Markdown (the bars' columns by default)."""
    keys = keys or BARS_KEYS
    head = head or (BARS_HEAD if keys is BARS_KEYS else keys)

    def fmt(v: Any) -> str:
        if v is None:
            return "-"
        if isinstance(v, float):
            return f"{v:.3g}" if abs(v) >= 1e-3 or v == 0 else f"{v:.1e}"
        return str(v)

    lines = ["| " + " | ".join(head) + " |", "|" + "---|" * len(head)]
    lines += ["| " + " | ".join(fmt(r.get(k)) for k in keys) + " |" for r in rows]
    return "\n".join(lines) + "\n"
