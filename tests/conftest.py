"""Shared helpers: running the bars case with overrides (cached per parameter set)."""

from __future__ import annotations

from functools import cache

import pytest

from impactsph.loading import load_case
from impactsph.problems import analyse
from impactsph.simulation import Simulation


@cache
def _bars(overrides: tuple[str, ...]):
    case = load_case("bars", list(overrides))
    sim = Simulation(case)
    sim.run()
    return sim, {**sim.summary(), **analyse("bars", sim)}


@pytest.fixture(scope="session")
def run_bars():
    """``run_bars(*overrides) -> (simulation, summary)``, each parameter set run once."""

    def run(*overrides: str):
        return _bars(tuple(overrides))

    return run
