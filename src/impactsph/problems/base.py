"""What a problem is: :class:`ProblemKind`, the base class of the problem modules, and the
small records it is described by (:class:`GeometryNeeds`, :class:`SweepCriterion`).

A problem is what a case's ``analysis`` field names: the metrics that compare a finished run
with the problem's theory or reference (added to ``summary.json``), the figures drawn of its
runs, the columns it adds to what ``impactsph run`` prints and to the sweep and paper tables,
and, for the paper's examples, the runner of the paper's figures.  Every hook has a default
that adds nothing, so a new problem overrides only what it has.

This module imports nothing heavy (no matplotlib, no numba): the case validation reads the
registry (see :mod:`impactsph.problems`).  The figure and paper hooks import what they need
when called.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Any

#: a validated case (:class:`impactsph.config.Case`; not imported: the case validation reads
#: this module)
Case = Any


@dataclass(frozen=True)
class GeometryNeeds:
    """What the problem's measures need of the case's leading bodies: at least ``bodies``
    bodies, and for each of the first ``bodies`` a geometry ``type`` among ``types`` (the
    analyses measure a body by its lattice, e.g. the bars by the blocks' lengths).  Checked by
    the case validation (:class:`impactsph.config.Case`)."""

    bodies: int
    types: tuple[str, ...]


@dataclass(frozen=True)
class SweepCriterion:
    """A pass/fail criterion on a column of a sweep's table: a run passes when its status is
    ``ok`` and the column ``key`` is a finite number below the threshold.  ``impactsph sweep``
    reports the smallest value of the first grid parameter among the runs that pass (the
    finding ``smallest_NAME``) and draws ``key`` beside the kinetic energy in ``sweep.png``.

    ``description`` is a format string with ``{threshold}`` (and may use ``{key}``)."""

    key: str  #: the table column the criterion reads
    threshold: float  #: the default threshold (``impactsph sweep --threshold`` overrides it)
    name: str  #: names the finding, ``smallest_NAME``, e.g. ``oscillation_free``
    description: str  #: how the criterion reads, with ``{threshold}``
    label: str  #: y label of its panel in ``sweep.png``

    def passes(self, row: dict[str, Any], threshold: float | None = None) -> bool:
        """Whether the table row ``row`` meets the criterion (``threshold``: the default's
        when None)."""
        limit = self.threshold if threshold is None else threshold
        value = row.get(self.key)
        return (row.get("status") == "ok" and isinstance(value, int | float)
                and math.isfinite(value) and value < limit)

    def describe(self, threshold: float | None = None) -> str:
        """The criterion in words, at ``threshold`` (the default's when None)."""
        limit = self.threshold if threshold is None else threshold
        return self.description.format(threshold=limit, key=self.key)


class ProblemKind:
    """A problem: subclass it, set :attr:`name` (what ``analysis = "NAME"`` in a case file
    selects) and override the hooks the problem has, then register an instance (or the class)
    with :func:`impactsph.problems.register_problem`.

    ``runs`` below are loaded run directories (:func:`impactsph.output.load_run`: dicts with
    ``case``, ``history``, ``snapshots``, ``probes``, ``summary``); a case is a validated
    :class:`impactsph.config.Case`; ``sim`` a finished :class:`impactsph.Simulation`.
    """

    #: What ``analysis = "NAME"`` selects: a Python identifier (letters, digits and ``_``,
    #: not first a digit; :func:`impactsph.problems.register_problem` refuses others).
    name: str = ""
    #: One line saying what the problem is (for listings and the docs).
    title: str = ""
    #: What the problem needs of the case's leading bodies (None: nothing).
    geometry_needs: GeometryNeeds | None = None
    #: The criterion of a sweep's finding (None: a sweep reports its table only).
    sweep_criterion: SweepCriterion | None = None
    #: The field ``impactsph animate`` colours the particles by when ``--field`` is not
    #: given (a name of :func:`impactsph.animate.field_names`).
    animation_field: str = "speed"
    #: Whether the problem is measured part-way through the impact, by design (the plates'
    #: wave profiles, taken while the plates are still in contact): then ``impactsph run``
    #: does not warn that kinetic energy remains at the end time
    #: (:func:`impactsph.preflight.after_run`).
    ends_during_impact: bool = False

    def metrics(self, sim: Any) -> dict[str, Any]:
        """The problem's measures of a finished run, added to ``summary.json``."""
        return {}

    def summary_keys(self, case: Case) -> tuple[str, ...]:
        """The keys of :meth:`metrics` (or of the summary) that ``impactsph run`` prints for a
        run of ``case``, after the generic ones."""
        return ()

    def table_keys(self, case: Case) -> tuple[str, ...]:
        """The problem's columns of a sweep's table (after the kinetic energy kept, before
        the conservation errors and the cost) and of the paper's tables."""
        return ()

    def figures(self, runs: list[dict[str, Any]], labels: list[str], out: Path
                ) -> list[Path]:
        """Draw the problem's figures of ``runs`` (runs of one case, overlaid, with their
        legend ``labels``) into the folder ``out``; return the files written.  The kinetic
        energy is drawn for every problem by :func:`impactsph.figures.draw_figures`."""
        return []

    def paper(self, base: dict[str, Any], out: Path, *, workers: int | None = None,
              scheduler: str | None = None) -> dict[str, Any]:
        """Run and draw the paper's figures and tables of this example from the case dict
        ``base`` into ``out`` (``impactsph paper CASE``): write ``table.csv``, ``table.md``
        and ``paper.json`` and return ``{"figures": [...], "table": [...]}``.
        :mod:`impactsph.paper` has the helpers."""
        raise NotImplementedError(f"analysis = {self.name!r} has no paper figures")

    @property
    def has_paper(self) -> bool:
        """Whether the problem overrides :meth:`paper`."""
        return type(self).paper is not ProblemKind.paper

    def __repr__(self) -> str:
        return f"<{type(self).__name__} {self.name!r}>"
