"""Case files: reading a TOML file or a built-in case, ``--set`` overrides, the case's
``plugins``, and validation against the schema (:mod:`impactsph.config`) with one-line errors.

Loading validates the whole case before any computation: an unknown key, a value of the wrong
type or out of range raises :class:`~impactsph.errors.CaseError` whose message is one line
naming the field, the value and what is allowed.
"""

from __future__ import annotations

import copy
import difflib
import os
import re
import tomllib
import types
import typing
from importlib import resources
from pathlib import Path
from typing import Any

from pydantic import BaseModel, ValidationError

from .config import BOUNDARY_TYPES, GEOMETRY_TYPES, Case, ParticleFile, schema
from .errors import CaseError
from .library import expand

BUILTIN_CASES = ("bars", "taylor", "cantilever", "plates", "taylor_axisymmetric", "taylor3d",
                 "rings")


def builtin_case_path(name: str) -> Path:
    """Path of a case shipped with the package."""
    return Path(str(resources.files("impactsph") / "cases" / f"{name}.toml"))


def resolve_paths(data: dict[str, Any], directory: Path) -> dict[str, Any]:
    """Make the relative ``path`` of every ``type = "file"`` geometry, and every plugin given
    as a ``.py`` file, in a case dict relative to ``directory`` (in place; entries that are not
    well formed are left for validation)."""
    plugins = data.get("plugins") if isinstance(data, dict) else None
    if isinstance(plugins, list):
        data["plugins"] = [
            os.path.abspath(os.path.join(directory, os.path.expanduser(p)))
            if isinstance(p, str) and p.endswith(".py")
            and not os.path.isabs(os.path.expanduser(p)) else p for p in plugins]
    bodies = data.get("bodies") if isinstance(data, dict) else None
    for body in bodies if isinstance(bodies, list) else []:
        geometry = body.get("geometry") if isinstance(body, dict) else None
        if not isinstance(geometry, dict) or geometry.get("type") != "file":
            continue
        path = geometry.get("path")
        if isinstance(path, str) and path and not os.path.isabs(os.path.expanduser(path)):
            geometry["path"] = os.path.abspath(os.path.join(directory, path))
    return data


def read_case_dict(source: str | Path) -> dict[str, Any]:
    """Read a case file, or a built-in case by name, into a plain dict (not yet validated).
    The relative paths of particle files are made relative to the case file's directory."""
    path = Path(source)
    if not str(source).strip():  # (Path("") is the current directory)
        raise CaseError(f"case {str(source)!r}: give a case file or a built-in case: "
                        f"{', '.join(BUILTIN_CASES)}")
    if not path.suffix and str(source) in BUILTIN_CASES:
        path = builtin_case_path(str(source))
    elif not path.exists():
        if path.suffix:
            raise CaseError(f"case file {str(source)!r} does not exist")
        raise CaseError(f"case {str(source)!r} is neither a file nor a built-in case; "
                        f"built-in cases: {', '.join(BUILTIN_CASES)}")
    try:
        with open(path, "rb") as fh:
            return resolve_paths(tomllib.load(fh), path.absolute().parent)
    except tomllib.TOMLDecodeError as exc:
        raise CaseError(f"{path}: not valid TOML: {exc}") from None
    except UnicodeDecodeError as exc:
        raise CaseError(f"{path}: not valid UTF-8: {exc}") from None
    except OSError as exc:
        raise CaseError(f"case file {str(path)!r} cannot be read: {exc.strerror or exc}"
                        ) from None


def parse_override(text: str) -> tuple[list[str], Any]:
    """``'a.b.0.c=value'`` -> (['a', 'b', '0', 'c'], value); the value is read as TOML
    (numbers, booleans, strings in quotes, arrays) and otherwise kept as a bare string."""
    if "=" not in text:
        raise CaseError(f"--set {text!r}: expected KEY=VALUE, e.g. viscosity.alpha1=0.3")
    key, raw = text.split("=", 1)
    key = key.strip()
    if not key or any(not part for part in key.split(".")):
        raise CaseError(f"--set {text!r}: the key must be a dotted path such as time.end")
    try:
        value = tomllib.loads(f"v = {raw}")["v"]
    except tomllib.TOMLDecodeError:
        value = raw.strip()
    return key.split("."), value


def apply_overrides(data: dict[str, Any], overrides: list[str], flag: str = "--set"
                    ) -> dict[str, Any]:
    """Apply ``--set`` overrides to a case dict (a copy is returned); ``flag`` is the
    option the messages name (a sweep's grid values: ``--grid``)."""
    data = copy.deepcopy(data)
    for text in overrides:
        path, value = parse_override(text)
        node: Any = data
        for depth, part in enumerate(path[:-1]):
            where = ".".join(path[: depth + 1])
            if isinstance(node, list):
                if not part.isdecimal() or int(part) >= len(node):
                    raise CaseError(f"{flag} {text}: {where} is not an index of a list of "
                                    f"{len(node)}")
                node = node[int(part)]
            elif isinstance(node, dict):
                node = node.setdefault(part, {})
            else:
                raise CaseError(f"{flag} {text}: {where} is not a table")
        last = path[-1]
        if isinstance(node, list):
            if not last.isdecimal() or int(last) >= len(node):
                raise CaseError(f"{flag} {text}: index {last} is out of range")
            node[int(last)] = value
        elif isinstance(node, dict):
            node[last] = value
        else:
            raise CaseError(f"{flag} {text}: {'.'.join(path[:-1])} is not a table")
    return data


_TYPE_TAGS = {"constrained-float", "constrained-int", "float", "int", "str", "bool", "list",
              "dict", "nullable"}


def _is_type_tag(part: object) -> bool:
    """Pydantic's names of union members in an error location (not field names)."""
    return isinstance(part, str) and (part in _TYPE_TAGS
                                      or re.match(r"^[a-z-]+\[", part) is not None)


def _location(loc: tuple[Any, ...]) -> str:
    """The dotted field path of an error location, without pydantic's names of union members
    (``constrained-float``, ...) and of the geometry's type (``bodies.0.geometry.disk.radius``
    is ``bodies.0.geometry.radius``) or a boundary's (``boundaries.0.wall.friction`` is
    ``boundaries.0.friction``)."""
    parts = [p for k, p in enumerate(loc) if not _is_type_tag(p)
             and not (k > 0 and loc[k - 1] == "geometry" and p in GEOMETRY_TYPES)
             and not (k > 1 and loc[k - 2] == "boundaries" and p in BOUNDARY_TYPES)]
    return ".".join(str(p) for p in parts)


def _members(annotation: Any) -> list[Any]:
    """The types an annotation may hold: through ``Annotated``, unions and ``Optional``."""
    origin = typing.get_origin(annotation)
    if origin is typing.Annotated:
        return _members(typing.get_args(annotation)[0])
    if origin is typing.Union or origin is types.UnionType:
        return [m for a in typing.get_args(annotation) for m in _members(a)]
    return [annotation]


def allowed_keys(loc: tuple[Any, ...]) -> list[str]:
    """The keys the case schema allows in the table at the error location ``loc`` (the
    path of pydantic's error, union members' names included), e.g. ``("viscosity",)`` ->
    the fields of ``[viscosity]``; ``[]`` where the path leads to no table."""
    nodes: list[Any] = [schema().Case]
    for part in loc:
        following: list[Any] = []
        for node in (m for n in nodes for m in _members(n)):
            origin = typing.get_origin(node)
            if isinstance(node, type) and issubclass(node, BaseModel):
                fields = node.model_fields
                if isinstance(part, str) and part in fields:
                    info = fields[part]
                    following.append(info.annotation)
                elif getattr(fields.get("type"), "default", None) == part:
                    following.append(node)  # a union member's tag (the geometry's type)
            elif origin is list and isinstance(part, int):
                following.append(typing.get_args(node)[0])
            elif origin is dict and isinstance(part, str):
                following.append(typing.get_args(node)[1])
        nodes = following
    keys: dict[str, None] = {}
    for node in (m for n in nodes for m in _members(n)):
        if isinstance(node, type) and issubclass(node, BaseModel):
            keys.update(dict.fromkeys(node.model_fields))
    return list(keys)


def _other_types_key(loc: tuple[Any, ...]) -> str:
    """``"; radius is a field of type = 'disk', ... (this geometry's type is 'block')"`` for a
    key of a geometry (or boundary) table that belongs to its other types; ``""`` else.  The
    error's location names the table's type before the key (pydantic's union tag)."""
    if len(loc) < 2 or not isinstance(loc[-1], str):
        return ""
    for tags in (GEOMETRY_TYPES, BOUNDARY_TYPES):
        if loc[-2] not in tags:
            continue
        others = [t for t in tags if t != loc[-2] and loc[-1] in allowed_keys((*loc[:-2], t))]
        if others:
            names = " or ".join([", ".join(map(repr, others[:-1])), repr(others[-1])]
                                if len(others) > 1 else [repr(others[0])])
            return (f"; {loc[-1]} is a field of type = {names} (this table's type is "
                    f"{loc[-2]!r})")
    return ""


def did_you_mean(key: str, allowed: list[str]) -> str:
    """``"; did you mean 'alpha1'?"`` (or two or three names) for a misspelt ``key`` among
    the ``allowed`` ones (:func:`difflib.get_close_matches`); ``""`` when none is close."""
    close = difflib.get_close_matches(str(key), allowed, n=3, cutoff=0.6)
    if not close:
        return ""
    *rest, last = map(repr, close)
    return f"; did you mean {', '.join(rest) + ' or ' if rest else ''}{last}?"


def _misspelt_first(errors: list[Any]) -> list[Any]:
    """The errors with an unknown key put first when it is a misspelling of a required
    field missing from the same table (``positon`` for ``position``): the cause first."""
    for k, err in enumerate(errors):
        if err["type"] != "extra_forbidden" or not err["loc"]:
            continue
        parent, key = err["loc"][:-1], err["loc"][-1]
        missing = [e["loc"][-1] for e in errors if e["type"] == "missing"
                   and e["loc"][:-1] == parent and isinstance(e["loc"][-1], str)]
        if difflib.get_close_matches(str(key), missing, n=1, cutoff=0.6):
            return [err, *errors[:k], *errors[k + 1:]]
    return errors


#: how pydantic begins most of its messages, which :func:`_union_error` says once
SHOULD_BE = "Input should be "


def _member_position(err: Any, errors: list[Any]) -> int | None:
    """Where in ``err``'s location pydantic names the member of a union field that the error
    is of: the first part that is one of its type tags (``constrained-int``,
    ``list[constrained-float]``), or a name in whose place another error at the same path has
    a type tag (a model member: ``Region`` beside ``list[Region]``); None for an error of no
    union."""
    loc = err["loc"]
    for k, part in enumerate(loc):
        if not isinstance(part, str):
            continue
        if _is_type_tag(part) or any(len(e["loc"]) > k and e["loc"][:k] == loc[:k]
                                     and _is_type_tag(e["loc"][k]) for e in errors):
            return k
    return None


def _field_of(err: Any, errors: list[Any]) -> tuple[Any, ...]:
    """The location of the field an error is of (a union field's, for its members')."""
    k = _member_position(err, errors)
    return tuple(err["loc"]) if k is None else tuple(err["loc"][:k])


def _union_error(errors: list[Any]) -> tuple[Any, tuple[Any, ...], str, list[Any]]:
    """The error to report, its location (without pydantic's member names), its message and
    the errors of other fields.  The errors of one union field's members (its value matched
    none) are one: where a member's error lies inside the value (``spacing = [1, 'x']``: the
    list's item 1), the value has that member's shape and that error is told; else the
    members' messages are joined (``compute.threads = 0``: ``Input should be greater than or
    equal to 1 or 'auto'``), not the first member's alone and "1 more error"."""
    first = errors[0]
    k = _member_position(first, errors)
    if k is None:
        return first, tuple(first["loc"]), first["msg"], errors[1:]
    field = tuple(first["loc"][:k])
    group = [e for e in errors if tuple(e["loc"][:k]) == field and len(e["loc"]) > k]
    others = [e for e in errors if not any(e is g for g in group)]
    inside = [e for e in group if len(e["loc"]) > k + 1]
    if inside:  # the value took a member's shape: that member's error
        err = inside[0]
        return err, (*field, *err["loc"][k + 1:]), err["msg"], others
    messages = [e["msg"] for e in group]
    if all(m.startswith(SHOULD_BE) for m in messages):
        messages = [messages[0], *(m[len(SHOULD_BE):] for m in messages[1:])]
    return first, field, " or ".join(messages), others


def _format_error(exc: ValidationError) -> str:
    errors = _misspelt_first(exc.errors())
    err, where, msg, others = _union_error(errors)
    loc = _location(where)
    if msg.startswith("Value error, "):
        msg = msg[len("Value error, "):]
    value = err.get("input")
    if err["type"] in ("geometry_type", "boundary_type") and isinstance(value, dict):
        loc, value = f"{loc}.type", value.get("type")  # (the table's type, not the table)
    # the other fields in error (a union field's members' errors are one field's)
    fields = len({_location(_field_of(e, errors)) for e in others})
    more = f" (and {fields} more error{'s' if fields > 1 else ''})" if fields else ""
    if err["type"] == "extra_forbidden":
        hint = did_you_mean(err["loc"][-1], allowed_keys(err["loc"][:-1])) if err["loc"] else ""
        hint = hint or _other_types_key(tuple(err["loc"]))
        return f"{loc}: unknown key{hint}{more}"
    if err["type"] == "missing":
        return f"{loc}: required field is missing{more}"
    if loc and not isinstance(value, dict):
        shown = ("true" if value else "false") if isinstance(value, bool) else repr(value)
        return f"{loc} = {shown}: {msg}{more}"  # (a boolean as the case file writes it)
    return f"{loc + ': ' if loc else ''}{msg}{more}"


_LOADED_PLUGINS: dict[str, Any] = {}


def _plugin_module(path: Path) -> Any:
    """Import the plugin file ``path`` as the module its stem names (``my_models.py``:
    ``my_models``), as ``import my_models`` beside it would, or return that module where it
    is imported already (by a case's ``plugins`` or by the caller: importing it again would
    register its models twice).  numba's disk cache keys a compiled function on its source
    file and stores its module's name, so a file imported under another name in another
    process (until 2026-12-08, a name from its place in the list) found its cached code naming
    a module that did not exist.  A stem that names another module (imported, or found on the
    path: ``json.py``, a second ``my_models.py`` in another folder) gets a name of its own
    made from the file's path."""
    import importlib.util
    import sys

    name, target = path.stem, path.resolve()

    def file_of(module_or_spec: Any) -> Path | None:
        file = getattr(module_or_spec, "__file__", None) or getattr(module_or_spec, "origin",
                                                                    None)
        try:
            return Path(file).resolve() if file else None
        except OSError:
            return None

    for module in list(sys.modules.values()):  # imported already, under any name
        if getattr(module, "__file__", None) and file_of(module) == target:
            return module
    other = sys.modules.get(name)
    if other is None:
        try:
            other = importlib.util.find_spec(name)
        except (ImportError, ValueError):
            other = None
    if other is not None and file_of(other) != target:
        # the stem names another module (json.py; a second my_models.py in another folder;
        # a folder of that name on the path): a name of its own, the same for this file in
        # every process where the stem is taken
        import hashlib

        name = f"impactsph_plugin_{name}_{hashlib.sha256(str(target).encode()).hexdigest()[:12]}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    sys.modules[name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        del sys.modules[name]
        raise
    return module


def load_plugins(plugins: Any) -> None:
    """Import the case's ``plugins`` (dotted module names, or ``.py`` files), once each per
    process; raise :class:`CaseError` naming the entry that cannot be imported."""
    import importlib
    import importlib.util

    if not isinstance(plugins, list):
        return  # not a list of names: the schema reports it
    for k, plugin in enumerate(plugins):
        if not isinstance(plugin, str) or not plugin or plugin in _LOADED_PLUGINS:
            continue
        try:
            if plugin.endswith(".py"):
                path = Path(os.path.expanduser(plugin))
                if not path.is_file():
                    raise CaseError(f"plugins.{k} = {plugin!r}: file does not exist")
                module = _plugin_module(path)
            else:
                module = importlib.import_module(plugin)
        except CaseError:
            raise
        except Exception as exc:  # noqa: BLE001 - any failure of user code, said in one line
            raise CaseError(f"plugins.{k} = {plugin!r}: cannot be imported "
                            f"({type(exc).__name__}: {exc})".replace("\n", " ")) from None
        _LOADED_PLUGINS[plugin] = module


def validate_case(data: dict[str, Any]) -> Case:
    """Validate a case dict against the :func:`schema` of the registered models (after
    importing its ``plugins`` and filling in its library materials,
    :func:`impactsph.library.expand`); raise :class:`CaseError` with a one-line message."""
    if isinstance(data, dict):
        load_plugins(data.get("plugins"))
        data = expand(data)
    try:
        return schema().Case.model_validate(data)
    except ValidationError as exc:
        raise CaseError(_format_error(exc)) from None


def validated_again(case: Any, where: str) -> Case:
    """``case`` validated once more, as the run will use it: a :class:`Case` changed after
    its validation (``case.time.end = -1.0``; pydantic checks a field when the case is made,
    not when it is assigned) is checked as a case file's would be.  Raise :class:`TypeError`
    where ``case`` is not a :class:`Case` at all (a dict, a case's name) and
    :class:`CaseError` naming the field where a change made it invalid; ``where`` names the
    call (``run_case(case)``).  0.1-0.2 ms for the built-in cases."""
    if not isinstance(case, Case):
        raise TypeError(f"{where}: case is a {type(case).__name__}; it needs a validated "
                        f"case: impactsph.load_case(NAME or FILE) or "
                        f"impactsph.loading.validate_case(DICT)")
    import warnings

    with warnings.catch_warnings():  # (pydantic's warning of a value of another type: the
        warnings.simplefilter("ignore")  # validation below names it)
        data = case.model_dump(mode="json")
    try:
        return validate_case(data)
    except CaseError as exc:
        raise CaseError(f"{where}: the case was changed after its validation and is no longer "
                        f"valid: {exc}") from None


def check_particle_files(case: Case) -> None:
    """Read every particle file of the case's ``type = "file"`` geometries; raise
    :class:`CaseError` naming the field for a file that is missing or malformed."""
    from .geometry import read_particle_file

    for k, body in enumerate(case.bodies):
        if isinstance(body.geometry, ParticleFile):
            read_particle_file(body.geometry.path, case.dimension,
                               where=f"bodies.{k}.geometry.path")


def load_case(source: str | Path, overrides: list[str] | None = None) -> Case:
    """Load and validate a case file or built-in case, with optional ``--set`` overrides (a
    list of ``KEY=VALUE`` strings), and check the particle files it reads."""
    if not isinstance(source, str | Path):
        raise CaseError(f"load_case({source!r}): a case file's path or a built-in case's "
                        f"name ({', '.join(BUILTIN_CASES)})")
    if isinstance(overrides, str):  # (a string would be taken character by character)
        raise CaseError(f"load_case(overrides = {overrides!r}): a list of KEY=VALUE strings, "
                        f"e.g. [{overrides!r}]")
    data = apply_overrides(read_case_dict(source), overrides or [])
    # the case file's own relative paths are its directory's by now; an override's are the
    # current directory's, made absolute as theirs are (case.json, a restart elsewhere)
    case = validate_case(resolve_paths(data, Path.cwd()))
    check_particle_files(case)
    return case
