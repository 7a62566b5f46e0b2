"""A plane-strain elasticity reference for the clamped beam and plate of issue 11: the first
bending period of the same 2D solid that the SPH runs of ``validation/beam.py`` model, from a
finite-element eigenvalue problem (scikit-fem), to settle how much of the SPH error against
Timoshenko's beam theory is the theory's own.

The solid: a rectangle ``[0, L] x [-H/2, H/2]`` in plane strain (E, nu, rho of
``validation/beam.py``), every displacement held at the face ``x = 0`` (the SPH beam's root:
its held columns lie behind ``x = 0``, its free particles fill ``[0, L]``), the other faces
free.  Biquadratic (9-node) quadrilaterals, consistent mass, ``K phi = omega^2 M phi``
for the lowest mode; the mesh refined until the period settles.

Timoshenko's beam with a clamped root holds the section's rotation and deflection at
``x = 0`` but lets it warp; the 2D face holds every point of it, and its corners carry the
stress singularity of a clamped elastic corner.  The two differ by a fraction of a per cent
at these slendernesses, the difference measured here.

Usage::

    .venv/bin/python validation/beam_fem.py                     # nu = 0.3, L = 12 H
    .venv/bin/python validation/beam_fem.py --nu 0.4 --slenderness 10
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from _args import positive_int

sys.path.insert(0, str(Path(__file__).resolve().parent))
import beam  # noqa: E402  (validation/beam.py: the beam's data and the beam theories)


def first_period(n_depth: int, nu: float | None = None, slenderness: float | None = None
                 ) -> float:
    """First-mode period (s) of the clamped plane-strain solid of ``validation/beam.py``
    (its current ``NU`` and ``LENGTH`` unless ``nu``, ``slenderness = L / H`` are given) with
    ``n_depth`` biquadratic elements through the depth and square elements along it."""
    from scipy.sparse.linalg import eigsh
    from skfem import (
        Basis,
        BilinearForm,
        ElementQuad2,
        ElementVector,
        MeshQuad,
        asm,
        condense,
    )
    from skfem.helpers import dot
    from skfem.models.elasticity import lame_parameters, linear_elasticity

    nu = beam.NU if nu is None else float(nu)
    length = beam.LENGTH if slenderness is None else float(slenderness) * beam.DEPTH
    n_length = max(1, round(n_depth * length / beam.DEPTH))
    mesh = MeshQuad.init_tensor(np.linspace(0.0, length, n_length + 1),
                                np.linspace(-beam.DEPTH / 2, beam.DEPTH / 2, n_depth + 1))
    basis = Basis(mesh, ElementVector(ElementQuad2()), intorder=4)
    # plane strain: the 2D Lame parameters are the 3D ones
    stiffness = asm(linear_elasticity(*lame_parameters(beam.E, nu)), basis)

    @BilinearForm
    def mass(u, v, _):
        return beam.RHO * dot(u, v)

    mass_matrix = asm(mass, basis)
    root = basis.get_dofs(lambda x: np.isclose(x[0], 0.0)).all()
    K, M = condense(stiffness, mass_matrix, D=root, expand=False)[:2]
    omega2 = eigsh(K, k=1, M=M, sigma=0.0, which="LM", return_eigenvectors=False)[0]
    return 2.0 * math.pi / math.sqrt(omega2)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--nu", type=float, default=beam.NU)
    ap.add_argument("--slenderness", type=float, default=beam.LENGTH / beam.DEPTH,
                    help="L / H")
    ap.add_argument("--depths", type=positive_int, nargs="+", default=[2, 4, 8, 16],
                    help="elements through the depth")
    args = ap.parse_args(argv)
    beam.set_beam(args.nu, args.slenderness)
    timoshenko, euler = beam.timoshenko_period(), beam.euler_bernoulli_period()
    for n in args.depths:
        t0 = time.perf_counter()
        period = first_period(n)
        print(json.dumps({
            "nu": beam.NU, "slenderness": beam.LENGTH / beam.DEPTH, "elements_through_depth": n,
            "period": period, "vs_timoshenko": period / timoshenko - 1.0,
            "vs_euler_bernoulli": period / euler - 1.0,
            "seconds": round(time.perf_counter() - t0, 2)}), flush=True)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
