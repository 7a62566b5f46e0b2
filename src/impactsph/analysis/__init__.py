"""Problem-specific analysis: exact solutions and the metrics that compare a run with them."""

from __future__ import annotations

from typing import Any


def analyse(kind: str, sim: Any) -> dict[str, Any]:
    """Metrics of the analysis ``kind`` (the case's ``analysis`` field) for a finished run."""
    if kind == "bars":
        from .bars import bars_metrics

        return bars_metrics(sim)
    if kind == "taylor":
        from .taylor import taylor_metrics

        return taylor_metrics(sim)
    if kind == "cantilever":
        from .cantilever import cantilever_metrics

        return cantilever_metrics(sim)
    return {}
