"""Generated passes: the template :mod:`impactsph.physics.passes` bound to the registered
models and a dimension.

A pass applies every model where its equation belongs (the EOS in the particle pass, the
viscosity in the pair loop, the return map in the integrator), and numba compiles it with
those calls inlined and the dimension a constant.  To get that for any set of registered
models (a user's included) *and* keep numba's disk cache (numba caches a function only if it
captures no compiled function, and does not notice when a function it calls changes), each
set of models is written out as a module of its own:

1. the *binding*: ``DIM``, the material-table layout, and one dispatch function per model
   kind (``eos_pressure(kind, ...)``: an if-chain over the registered models' compiled
   functions, which are injected into the module under the names ``_eos_0``, ``_eos_1``, ...);
2. the template's text, with its stub binding replaced by that one (and, for the serial
   passes, each starting with its arguments borrowed: :mod:`impactsph.physics.borrow`);
3. written once to ``<cache>/passes_<hash>.py`` and imported from there (numba keeps its
   machine code in ``__pycache__`` beside it; the borrowed arguments' rewrite of step 2 is
   kept there too, ``borrowed_<hash>.txt``).

The hash covers the template, the binding and the source files of every model function bound
in (and of the modules the template imports), so a changed model makes a new module instead of
reusing stale machine code.  The cache is ``$IMPACTSPH_CACHE_DIR``, else
``$XDG_CACHE_HOME/impactsph``, else ``~/.cache/impactsph``; a directory that cannot be written
falls back to a temporary one, one a process, removed when the process ends (the code is
then compiled in every process).

``simulated=True`` builds the same module for numba's CUDA simulator: nothing is compiled for
the CPU (``JIT`` does nothing and every compiled function bound in is replaced by its Python
source), since the simulator's arrays cannot be passed to compiled functions.
"""

from __future__ import annotations

import atexit
import hashlib
import importlib.util
import inspect
import os
import shutil
import sys
import tempfile
import types
import warnings
from functools import cache
from pathlib import Path
from types import ModuleType
from typing import Any

from . import atomic
from .materials import TableLayout
from .models import DAMAGE, EOS, STRENGTH, VISCOSITY
from .models import registry as _registry
from .physics.borrow import borrow_arguments
from .physics.options import PassOptions

BEGIN = "# >>> binding"
END = "# <<< binding"

# The serial passes (PassOptions.parallel False) are compiled with numba's parallel passes on
# but its transform of prange loops off (physics/passes.py, PARALLEL_OPTION), and numba warns
# of each that "no transformation for parallel execution was possible".  That is the point, so
# the warning is silenced for the generated serial modules' files only.
warnings.filterwarnings(
    "ignore", message=r"(?s)\s*The keyword argument 'parallel=True' was specified but no "
    r"transformation.*passes_\w*_serial_[0-9a-f]{16}\.py")
# and the chunked passes (physics/chunked.py), which take the same option in every module
warnings.filterwarnings(
    "ignore", message=r"(?s)\s*The keyword argument 'parallel=True' was specified but no "
    r"transformation.*passes_\w*[0-9a-f]{16}\.py\", line \d+:.*"
    r"def ((moment|gradient|pair|hourglass|switch)_pass|stage)\(")
#: the package modules whose code the template inlines (their source is part of the hash)
TEMPLATE_IMPORTS = ("kernels.py", "materials.py", "physics/borrow.py", "physics/chunked.py",
                    "physics/contact.py",
                    "physics/continuity.py", "physics/energy.py", "physics/momentum.py",
                    "physics/reconstruction.py", "physics/records.py", "physics/stress_rate.py")
PACKAGE = Path(__file__).parent


#: the temporary directory that stands in for each cache directory that cannot be written,
#: made once a process
_FALLBACK: dict[str, Path] = {}


def cache_directory() -> Path:
    """Where the generated modules are written (see the module docstring)."""
    root = os.environ.get("IMPACTSPH_CACHE_DIR")
    if root is None:
        xdg = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"),
                                                                ".cache")
        root = os.path.join(xdg, "impactsph")
    path = Path(root) / "kernels"
    try:
        path.mkdir(parents=True, exist_ok=True)
        probe = tempfile.NamedTemporaryFile(dir=path, prefix=".probe", delete=True)
        probe.close()
    except OSError:
        known = _FALLBACK.get(str(path))
        if known is None or not known.is_dir():
            known = _FALLBACK[str(path)] = Path(tempfile.mkdtemp(prefix="impactsph-kernels-"))
            atexit.register(_remove_fallback, known, os.getpid())
        path = known
    return path


def _remove_fallback(folder: Path, owner: int) -> None:
    """Remove a fallback folder of :func:`cache_directory` when the process that made it ends
    (nothing in it serves another process); not in a child forked from it, which would
    otherwise take it from under its parent."""
    if os.getpid() == owner:
        shutil.rmtree(folder, ignore_errors=True)


def _no_jit(*args: Any, **kwargs: Any) -> Any:
    """``JIT`` under the CUDA simulator: leaves the function as it is."""
    if len(args) == 1 and callable(args[0]) and not kwargs:
        return args[0]
    return lambda f: f


def _python(f: Any) -> Any:
    """The Python source function of a numba dispatcher (itself otherwise)."""
    return getattr(f, "py_func", f)


def _python_all_the_way(f: Any, done: dict | None = None) -> Any:
    """For the simulator: the Python source of ``f`` with every compiled function its globals
    name (a model's own helpers, called with the simulator's arrays) replaced likewise, in a
    copy of those globals (the CPU's functions are left alone)."""
    f = _python(f)
    done = {} if done is None else done
    if not isinstance(f, types.FunctionType):
        return f
    if f in done:
        return done[f]
    names = {k: v for k, v in f.__globals__.items() if k in f.__code__.co_names
             and hasattr(v, "py_func")}
    if not names:
        done[f] = f
        return f
    namespace = dict(f.__globals__)
    copy = types.FunctionType(f.__code__, namespace, f.__name__, f.__defaults__, f.__closure__)
    done[f] = copy
    for k, v in names.items():
        namespace[k] = _python_all_the_way(v, done)
    return copy


def _source_of(f: Any) -> str:
    """The text that decides what ``f`` computes: its module's source file, or its code."""
    f = _python(f)
    try:
        return Path(inspect.getsourcefile(f)).read_text()
    except (TypeError, OSError):
        code = f.__code__
        return repr((code.co_code, code.co_consts, code.co_names))


def _dispatch(name: str, args: str, prefix: str, models: list[tuple[int, Any]],
              fallback: str, inject: dict[str, Any], fallback_kind: int | None = None) -> str:
    """An inlined if-chain ``name(kind, args)`` calling ``{prefix}{k}(args)`` for the kind
    codes ``k`` of ``models``, ``fallback`` for any other (``fallback_kind``: the kind whose
    function the fallback calls).

    Kinds bound to one compiled function (the same object in ``inject``, by name) share one
    branch, and those of the fallback's function take the fallback: numba inlines a branch's
    callee where it is called, so each distinct function is compiled into the pass once.  The
    eight registered viscosity schemes all use Monaghan's ``Pi_ij``: with a branch each, the
    Taylor bar's 2D pair pass compiled in 25.9 and 28.0 s, with one call in 20.1 and 20.7 s
    (cold, alternating, docs/architecture.md "Compile time")."""
    shared = inject[f"{prefix}{fallback_kind}"] if fallback_kind is not None else None
    branches: dict[int, tuple[int, list[int]]] = {}  # id(function) -> (first kind, kinds)
    for k, _ in models:
        function = inject[f"{prefix}{k}"]
        if function is not shared:
            branches.setdefault(id(function), (k, []))[1].append(k)
    lines = ['@JIT(inline="always", cache=True)', f"def {name}(kind, {args}):"]
    for first, kinds in branches.values():
        test = " or ".join(f"kind == {k}" for k in kinds)
        lines += [f"    if {test}:", f"        return {prefix}{first}({args})"]
    lines.append(f"    {fallback}")
    return "\n".join(lines) + "\n"


def binding(dim: int, options: PassOptions | str | None = None) -> tuple[str, dict[str, Any]]:
    """The binding block for ``dim``, the registered models and the compile-time
    :class:`~impactsph.physics.options.PassOptions` (or a gradient-correction mode by name;
    docs/stabilisation.md): its source, and the compiled functions to inject under their
    names."""
    options = PassOptions.coerce(options)
    layout = TableLayout.registered()
    inject: dict[str, Any] = {}
    described = []
    eos = list(enumerate(EOS))
    for k, m in eos:
        inject[f"_eos_{k}"] = m.pressure
        described.append(f"#   eos {k}: {m.name} ({_qualified(m.pressure)})")
    if options.eos_kinds is not None:  # (the last one named is the dispatch's fallback)
        eos = [(k, m) for k, m in eos if k in options.eos_kinds]
    strength = [(k, m) for k, m in enumerate(STRENGTH) if m.return_map is not None
                and (options.strength_kinds is None or k in options.strength_kinds)]
    for k, m in enumerate(STRENGTH):
        if m.return_map is not None:
            inject[f"_strength_{k}"] = m.return_map
        described.append(f"#   strength {k}: {m.name} ({_qualified(m.return_map)})")
    damage = [(k, m) for k, m in enumerate(DAMAGE) if m.update is not None
              and (options.damage_kinds is None or k in options.damage_kinds)]
    for k, m in enumerate(DAMAGE):
        if m.update is not None:
            inject[f"_damage_{k}"] = m.update
        described.append(f"#   damage {k}: {m.name} ({_qualified(m.update)})")
    viscosity = list(enumerate(VISCOSITY))
    corrections = [(k, m) for k, m in viscosity if m.correction is not None]
    switches = [(k, m) for k, m in viscosity if m.switch is not None
                and options.switch_kind in (-1, k)]
    for k, m in viscosity:
        inject[f"_viscosity_{k}"] = m.pair_viscosity
        if m.correction is not None:
            inject[f"_correction_{k}"] = m.correction
        if m.switch is not None and options.switch_kind in (-1, k):
            inject[f"_switch_{k}"] = m.switch
        described.append(f"#   viscosity {k}: {m.name} ({_qualified(m.pair_viscosity)}, "
                         f"{_qualified(m.correction)}, {_qualified(m.switch)})")
    last_eos = eos[-1][0]
    source = "\n".join([
        f"{BEGIN}: generated by impactsph.codegen for these models (the functions named",
        "# _eos_K, _strength_K, _damage_K, _viscosity_K, _correction_K, _switch_K are injected",
        "# into this module):",
        *described,
        f"DIM = {dim}",
        *options.constants(dim),
        "JIT = nb.njit",
        f"EOS_PARAMS = {layout.eos_params}",
        f"STRENGTH_PARAMS = {layout.strength_params}",
        f"DAMAGE_PARAMS = {layout.damage_params}",
        f"STRENGTH_STATE = {layout.strength_state}",
        f"DAMAGE_STATE = {layout.damage_state}",
        "",
        "",
        _dispatch("eos_pressure", "rho, e, rho0, bulk, params", "_eos_", eos[:-1],
                  f"return _eos_{last_eos}(rho, e, rho0, bulk, params)", inject, last_eos),
        "",
        _dispatch("strength_return", "S, rho, pressure, shear, params, state, own, dt",
                  "_strength_", strength, "return 0.0", inject),
        "",
        _dispatch("damage_update", "S, pressure, rho, size, dt, plastic_strain_increment, row, "
                  "params, state, own", "_damage_", damage, "return None", inject),
        "",
        _dispatch("pair_viscosity", "vr, r2, h_ij, c_ij, rho_ij, params", "_viscosity_",
                  viscosity[:-1], f"return _viscosity_{viscosity[-1][0]}(vr, r2, h_ij, c_ij, "
                  f"rho_ij, params)", inject, viscosity[-1][0]),
        "",
        _dispatch("viscosity_correction", "p, i, P, start, end, indices, columns, dim, params, "
                  "books, dv, de", "_correction_", corrections, "return None", inject),
        "",
        _dispatch("viscosity_switch", "p, i, P, start, end, indices, columns, dim, params, "
                  "elapsed, memory", "_switch_", switches, "return 1.0", inject),
        END,
    ])
    return source, inject


def _qualified(f: Any) -> str:
    if f is None:
        return "none"
    f = _python(f)
    return f"{f.__module__}.{f.__qualname__}"


def _template_text(template: ModuleType) -> str:
    return Path(inspect.getsourcefile(template)).read_text()


def generate(template: ModuleType, dim: int, options: PassOptions | str | None = None
             ) -> tuple[str, dict[str, Any]]:
    """The text of the generated module and the functions to inject (see :func:`binding`)."""
    text = _template_text(template)
    start, end = text.index(BEGIN), text.index(END)
    end = text.index("\n", end) + 1
    block, inject = binding(dim, options)
    text = text[:start] + block + "\n" + text[end:]
    # the serial passes' arrays, and the chunked passes' in any module, without reference
    # counts, as numba's threaded loop bodies get them (impactsph.physics.borrow)
    text = _borrowed(text, serial=not PassOptions.coerce(options).parallel)
    return text, inject


def _borrowed(text: str, serial: bool) -> str:
    """:func:`~impactsph.physics.borrow.borrow_arguments` of ``text``, kept in the cache
    directory under a hash of ``text``, ``serial`` and borrow.py's own source: its walk over
    the module's syntax tree took 35-40 ms a variant in every new process, a fifth of the
    Taylor bar's ``Simulation(case)`` (its three variants).  A file that cannot be read or
    written is made again."""
    digest = hashlib.sha256(text.encode())
    digest.update(b"serial" if serial else b"any")
    digest.update((PACKAGE / "physics" / "borrow.py").read_bytes())
    path = cache_directory() / f"borrowed_{digest.hexdigest()[:24]}.txt"
    try:
        return path.read_text()
    except (OSError, UnicodeDecodeError):
        pass
    borrowed = borrow_arguments(text, serial=serial)
    try:
        atomic.write_text(path, borrowed)
    except OSError:
        pass
    return borrowed


def _fingerprint(text: str, inject: dict[str, Any]) -> str:
    digest = hashlib.sha256(text.encode())
    for name in sorted(inject):
        digest.update(name.encode())
        digest.update(_source_of(inject[name]).encode())
    for rel in TEMPLATE_IMPORTS:
        digest.update((PACKAGE / rel).read_bytes())
    return digest.hexdigest()[:16]


def load(template: ModuleType, dim: int, simulated: bool = False,
         options: PassOptions | str | None = None) -> ModuleType:
    """The template bound to the registered models, ``dim`` and the compile-time ``options``,
    imported (cached in this process per registry version)."""
    return _load(template.__name__, dim, simulated, PassOptions.coerce(options).compiled(),
                 _registry.version())


@cache
def _load(template_name: str, dim: int, simulated: bool, options: PassOptions,
          version: int) -> ModuleType:
    template = sys.modules[template_name]
    text, inject = generate(template, dim, options)
    key = _fingerprint(text, inject)
    stem = template_name.rsplit(".", 1)[-1]
    path = cache_directory() / f"{stem}_{dim}d{options.tag}_{key}.py"
    if not path.exists() or path.read_text() != text:
        atomic.write_text(path, text)
    name = f"impactsph_generated.{path.stem}{'_simulated' if simulated else ''}"
    spec = importlib.util.spec_from_file_location(name, path)
    module = importlib.util.module_from_spec(spec)
    if simulated:
        inject = {k: _python_all_the_way(f) for k, f in inject.items()}
    module.__dict__.update(inject)
    sys.modules[name] = module
    code = compile(text, str(path), "exec")
    if simulated:
        # run the text with JIT doing nothing, then swap every compiled function it imported
        # for its Python source
        code = compile(text.replace("JIT = nb.njit", "JIT = _no_jit"), str(path), "exec")
        module.__dict__["_no_jit"] = _no_jit
    exec(code, module.__dict__)
    if simulated:
        for key_name, value in list(module.__dict__.items()):
            if hasattr(value, "py_func") and not key_name.startswith("__"):
                module.__dict__[key_name] = value.py_func
    return module
