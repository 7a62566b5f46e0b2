"""Resolution study for the paper's 2D examples: the same case at two (or more) particle
counts per direction, for several schemes, with the measured quantities and how much they
move.  Writes ``runs/validation/resolution-<case>/resolution.json`` and prints a Markdown
table.

    .venv/bin/python validation/resolution.py taylor [--workers 2]
    .venv/bin/python validation/resolution.py taylor --schemes AC "AC stabilised" --factors 1 2 4
    .venv/bin/python validation/resolution.py cantilever
    .venv/bin/python validation/resolution.py taylor --schemes "AC walls" --set kernel.h_over_dx=1.6
    .venv/bin/python validation/resolution.py taylor --schemes "AC pairwise walls, h 1.6 dx" \
        --factors 1 2 4

Schemes: the paper's AC and AV references; "defaults": a case of one's own (the tables the
paper's examples set, at their defaults); "AC walls": AC with the normal-stress contact and
the walls' penalty layer; "AC pairwise walls, h 1.6 dx": the correction's pairwise form
(``ac_pairwise``) with those and ``kernel.h_over_dx = 1.6``; "AC pairwise walls, stretch
1.23": the same at the paper's 1.3 dx with a smoothing length that follows the local stretch
up to 1.6 dx (``kernel.max_stretch = 1.23``; on the cantilever, whose clamp is no wall, the
walls' options change nothing); "AC pairwise": the pairwise form alone; "AC stabilised": the walls'
options and the kernel gradient correction of the velocity gradient and forces
(docs/stabilisation.md); "AC plane stress" and "AV (0.1, 0.1) plane stress": the cantilever
as a beam of square section (``two_dimensional = "plane_stress"``, issue 14).  The
cantilever at twice the resolution runs about 8 times as long as at the paper's (4080
particles, twice the steps).
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from _args import positive_int

from impactsph.errors import CaseError
from impactsph.loading import read_case_dict
from impactsph.output import load_run, write_study
from impactsph.sweep import run_many

KEYS = {
    "taylor": ["final_length_ratio", "footprint_half_width_ratio",
               "footprint_half_width_ratio_fixed", "plastic_work",
               "kinetic_energy_ratio_final", "total_energy_relative_error"],
    "cantilever": ["tip_deflection", "tip_deflection_ratio", "plastic_work",
                   "max_neighbour_gap_over_h", "kinetic_energy_ratio_final",
                   "total_energy_relative_error"],
}
#: the wall options of "AC walls" and "AC stabilised" (docs/stabilisation.md)
WALLS = ['contact.traction="normal_stress"', "contact.wall_layer=0.25"]
#: the minmod reconstruction with the artificial stress and the walls (the scheme that came
#: nearest the finite-element bar, docs/validation.md)
MINMOD_AS = ['viscosity.scheme="reconstruction"', 'viscosity.limiter="minmod"',
             "stabilisation.artificial_stress=0.3", *WALLS]
#: the stabilisation options of "AC stabilised"
STABILISED = ['stabilisation.gradient_correction="velocity_gradient_and_forces"', *WALLS]
#: AC's pairwise form with the walls and a kernel that follows the stretch (h from 1.3 dx up to
#: 1.6 dx where the body has spread: kernel.max_stretch = 1.6 / 1.3)
STRETCH = ['viscosity.scheme="ac_pairwise"', *WALLS, "kernel.max_stretch=1.23"]
#: a case of one's own: every table the paper's examples set back at its defaults (AV (1, 1),
#: the stabilisation's and the stretch's "auto" choices, the walls' options, h = 1.3 dx;
#: docs/stabilisation.md, "Defaults"); tests/test_stretch.py checks that it is the defaults
DEFAULTS = ['viscosity.scheme="av"', "viscosity.alpha1=1.0", "viscosity.alpha2=1.0",
            'stabilisation.gradient_correction="auto"', 'stabilisation.hourglass="auto"',
            *WALLS, "kernel.h_over_dx=1.3", 'kernel.max_stretch="auto"']
SCHEMES = {
    "taylor": {"AC": ['viscosity.scheme="ac"'],
               "defaults": DEFAULTS,
               "AV (0.5, 0.5)": ['viscosity.scheme="av"', "viscosity.alpha1=0.5",
                                 "viscosity.alpha2=0.5"],
               "AC walls": ['viscosity.scheme="ac"', *WALLS],
               # the correction's pairwise form with a wider kernel: the footprint moves -11%
               # (one spacing) and -7% (fixed band) from x1 to x2 (docs/validation.md)
               "AC pairwise walls, h 1.6 dx": ['viscosity.scheme="ac_pairwise"', *WALLS,
                                               "kernel.h_over_dx=1.6"],
               # the paper's kernel, growing where the bar spreads to at most 1.6 dx
               "AC pairwise walls, stretch 1.23": STRETCH,
               "AC stabilised": ['viscosity.scheme="ac"', *STABILISED],
               "minmod, artificial stress": MINMOD_AS,
               # the same with a wider kernel: the footprint's change from x1 to x2 halves
               "minmod, artificial stress, h 1.6 dx": [*MINMOD_AS, "kernel.h_over_dx=1.6"]},
    "cantilever": {"AC": ['viscosity.scheme="ac"'],
                   "defaults": DEFAULTS,
                   "AC pairwise": ['viscosity.scheme="ac_pairwise"'],
                   "AC pairwise walls, stretch 1.23": STRETCH,
                   "AV (0.1, 0.1)": ['viscosity.scheme="av"', "viscosity.alpha1=0.1",
                                     "viscosity.alpha2=0.1"],
                   "AC stabilised": ['viscosity.scheme="ac"', *STABILISED],
                   "AC plane stress": ['viscosity.scheme="ac"', 'two_dimensional="plane_stress"'],
                   "AV (0.1, 0.1) plane stress": ['viscosity.scheme="av"', "viscosity.alpha1=0.1",
                                                  "viscosity.alpha2=0.1",
                                                  'two_dimensional="plane_stress"']},
}


def main() -> None:
    parser = argparse.ArgumentParser(description=" ".join(__doc__.split("\n\n")[0].split()))
    parser.add_argument("case", choices=sorted(KEYS))
    parser.add_argument("--workers", type=int, default=None)
    parser.add_argument("--schemes", nargs="+", default=None,
                        help="schemes to run (default: AC and the AV reference)")
    parser.add_argument("--factors", nargs="+", type=positive_int, default=[1, 2],
                        help="particle-count multipliers per direction (default: 1 2)")
    parser.add_argument("--set", dest="sets", action="append", default=[],
                        help="an override for every run (key=value), after the scheme's")
    parser.add_argument("--out", type=Path, default=None)
    args = parser.parse_args()
    out = args.out or Path("runs/validation") / f"resolution-{args.case}"
    base = read_case_dict(args.case)
    count = base["bodies"][0]["geometry"]["count"]
    labels, overrides = [], []
    schemes = args.schemes or [k for k in SCHEMES[args.case]
                               if (k.startswith("AV") and "plane" not in k) or k == "AC"]
    for scheme in schemes:
        if scheme not in SCHEMES[args.case]:
            parser.error(f"--schemes: {scheme!r} is not one of {sorted(SCHEMES[args.case])}")
    for scheme in schemes:
        ov = SCHEMES[args.case][scheme]
        for factor in args.factors:
            refined = [c * factor for c in count]
            labels.append((scheme, factor))
            overrides.append([*ov, *args.sets,
                              f"bodies.0.geometry.count={json.dumps(refined)}",
                              "output.figures=false"])
    try:
        rows = run_many(base, overrides, out, workers=args.workers)
    except CaseError as exc:  # a --set the case refuses: before any run
        parser.error(str(exc))
    result = []
    for (scheme, factor), row in zip(labels, rows, strict=True):
        summary = load_run(out / "runs" / row["run"]).get("summary", {})
        result.append({"scheme": scheme, "resolution": f"x{factor}",
                       "n_particles": summary.get("n_particles"),
                       "wall_seconds": summary.get("wall_seconds"),
                       "wall_constraint_events": summary.get("wall_constraint_events"),
                       "status": row.get("status"),
                       **{k: summary.get(k) for k in KEYS[args.case]}})
    write_study(out / "resolution.json", result)
    cols = ["scheme", "resolution", "n_particles", "wall_seconds", "wall_constraint_events",
            *KEYS[args.case]]
    print("| " + " | ".join(cols) + " |")
    print("|" + "---|" * len(cols))
    for r in result:
        print("| " + " | ".join(f"{r[c]:.4g}" if isinstance(r[c], float) else str(r[c])
                                for c in cols) + " |")
    for scheme in schemes:
        rows_of = [r for r in result if r["scheme"] == scheme]
        for a, b in zip(rows_of, rows_of[1:], strict=False):
            moves = {k: (b[k] - a[k]) / a[k] for k in KEYS[args.case]
                     if isinstance(a.get(k), float) and isinstance(b.get(k), float) and a[k]}
            print(f"{scheme}: relative change {a['resolution']} -> {b['resolution']}: " +
                  ", ".join(f"{k} {v:+.1%}" for k, v in moves.items()))


if __name__ == "__main__":
    main()
