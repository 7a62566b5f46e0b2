"""The material library: named materials with their parameters and the published source of
each (``src/impactsph/data/materials.toml``).

A case takes one by name and overrides any field, sub-tables key by key::

    [materials.copper]
    library = "ofhc_copper"
    [materials.copper.johnson_cook]
    yield_stress = 95.0e6          # the rest of the Johnson-Cook table is the library's

:func:`expand` fills the library's fields into the case's material tables before the case is
validated (the ``library`` key is kept, so ``case.json`` says where a material came from);
``impactsph materials`` lists the library with its sources.
"""

from __future__ import annotations

import copy
import tomllib
from functools import cache
from importlib import resources
from typing import Any

from .errors import CaseError

#: keys of a library entry that are not material fields
INFORMATION = ("description", "sources")


@cache
def _library() -> dict[str, dict[str, Any]]:
    text = resources.files("impactsph").joinpath("data/materials.toml").read_text()
    return tomllib.loads(text)


def library() -> dict[str, dict[str, Any]]:
    """Every library material by name: its fields, ``description`` and ``sources`` (a
    copy)."""
    return copy.deepcopy(_library())


def material_fields(name: str) -> dict[str, Any]:
    """The case fields of library material ``name`` (without its description and sources)."""
    entries = _library()
    if name not in entries:
        raise KeyError(name)
    return {k: copy.deepcopy(v) for k, v in entries[name].items() if k not in INFORMATION}


def _merge(base: dict[str, Any], override: dict[str, Any]) -> dict[str, Any]:
    out = dict(base)
    for key, value in override.items():
        if isinstance(value, dict) and isinstance(out.get(key), dict):
            out[key] = _merge(out[key], value)
        else:
            out[key] = value
    return out


def expand(data: dict[str, Any]) -> dict[str, Any]:
    """``data`` (a case dict) with every material that names a ``library`` entry filled in
    from it, the case's own fields overriding; a name not in the library is a
    :class:`CaseError` naming the field."""
    materials = data.get("materials") if isinstance(data, dict) else None
    if not isinstance(materials, dict):
        return data
    out = dict(data)
    out["materials"] = dict(materials)
    for key, material in materials.items():
        if not isinstance(material, dict) or material.get("library") is None:
            continue
        name = material["library"]
        if not isinstance(name, str) or name not in _library():
            raise CaseError(f"materials.{key}.library = {name!r}: not a library material; "
                            f"one of {', '.join(sorted(_library()))} (impactsph materials)")
        out["materials"][key] = _merge(material_fields(name), material)
    return out
