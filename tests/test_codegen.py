"""The generated binding's model dispatches (:mod:`impactsph.codegen`): every kind code reaches
its own model's function, and a function that several kinds share is named once, so that numba
inlines it into a pass once."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from types import SimpleNamespace
from typing import Any

import pytest

from impactsph import codegen
from impactsph.codegen import _dispatch, binding
from impactsph.models import DAMAGE, EOS, STRENGTH, VISCOSITY
from impactsph.physics import passes
from impactsph.physics.borrow import borrow_arguments
from impactsph.physics.options import PassOptions

#: dispatch name -> (registry, the model's attribute, what the dispatch returns without one)
DISPATCHES = {
    "eos_pressure": (EOS, "pressure", None),
    "strength_return": (STRENGTH, "return_map", 0.0),
    "damage_update": (DAMAGE, "update", None),
    "pair_viscosity": (VISCOSITY, "pair_viscosity", None),
    "viscosity_correction": (VISCOSITY, "correction", None),
    "viscosity_switch": (VISCOSITY, "switch", 1.0),
}


def _executed(source: str, inject: dict[str, Any]) -> dict[str, Any]:
    """The binding's source run as Python, with ``JIT`` doing nothing and every injected
    function replaced by one that returns the injected object (so a call says which it
    reached)."""
    namespace: dict[str, Any] = {"nb": SimpleNamespace(njit=lambda *a, **k: lambda f: f)}
    for name, function in inject.items():
        namespace[name] = (lambda reached: lambda *args: reached)(function)
    exec(source, namespace)  # the package's own generated text
    return namespace


@pytest.mark.parametrize("options", [PassOptions(), PassOptions(viscosity_factor=True)],
                         ids=["plain", "switches"])
def test_every_kind_reaches_its_own_models_function(options):
    source, inject = binding(2, options)
    namespace = _executed(source, inject)
    for name, (registry, attribute, without) in DISPATCHES.items():
        dispatch = namespace[name]
        n_args = dispatch.__code__.co_argcount - 1
        for kind, model in enumerate(registry):
            function = getattr(model, attribute)
            reached = dispatch(kind, *([0] * n_args))
            if function is None:
                assert reached == without, (name, model.name)
            else:
                assert reached is function, (name, model.name)


def test_a_function_several_kinds_share_is_named_once():
    """The registered viscosity schemes all use Monaghan's pair function: the pair pass's
    dispatch calls it once, with no branch on the kind."""
    source, inject = binding(2)
    start = source.index("def pair_viscosity(")
    dispatch = source[start:source.index("\n\n", start)]
    distinct = {id(m.pair_viscosity) for m in VISCOSITY}
    assert dispatch.count("return _viscosity_") == len(distinct)
    assert len(distinct) < len(VISCOSITY)  # else this test checks nothing


def test_kinds_are_grouped_by_their_function():
    """Kinds of one function share a branch, kinds of the fallback's function take the
    fallback, and every kind still reaches its own function."""
    first, second, third = object(), object(), object()
    bound = {0: first, 1: second, 2: first, 3: third, 4: second, 5: first}
    inject = {f"_m_{k}": f for k, f in bound.items()}
    source = _dispatch("model", "x", "_m_", [(k, None) for k in range(5)],
                       "return _m_5(x)", inject, fallback_kind=5)
    assert source.count("return _m_") == 3  # second, third, and the fallback (first)
    assert "kind == 1 or kind == 4" in source
    namespace = _executed("JIT = nb.njit\n" + source, inject)
    for kind, function in bound.items():
        assert namespace["model"](kind, 0.0) is function
    assert namespace["model"](17, 0.0) is first  # an unknown kind: the fallback


def test_a_cache_that_cannot_be_written_falls_back_to_one_folder_a_process(tmp_path,
                                                                          monkeypatch):
    """Where the cache directory cannot be made (here, under a file), the generated modules
    and the kept rewrites go to a temporary folder, the same one for every call of the
    process (not a new folder for each module)."""
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    monkeypatch.setenv("IMPACTSPH_CACHE_DIR", str(blocker / "cache"))
    first, second = codegen.cache_directory(), codegen.cache_directory()
    assert first == second and first.is_dir() and not str(first).startswith(str(blocker))
    text = codegen._template_text(passes)
    assert codegen._borrowed(text, True) == borrow_arguments(text, serial=True)
    assert [p.name.startswith("borrowed_") for p in first.iterdir()] == [True]


#: a child that falls back to a temporary folder, writes a kept rewrite into it, forks a
#: grandchild that ends by ``sys.exit`` (running the handlers it inherited), and prints the
#: folder, whether it held the file and whether it outlived the grandchild
_FALLBACK_CHILD = """
import json, os, sys
from impactsph import codegen
from impactsph.physics import passes
folder = codegen.cache_directory()
codegen._borrowed(codegen._template_text(passes), True)
kept = any(p.name.startswith("borrowed_") for p in folder.iterdir())
pid = os.fork()
if pid == 0:
    sys.exit(0)
os.waitpid(pid, 0)
print(json.dumps({"folder": str(folder), "kept": kept, "after_fork": folder.is_dir()}))
"""


@pytest.mark.skipif(not hasattr(os, "fork"), reason="needs os.fork")
def test_the_fallback_folder_is_removed_when_its_process_ends(tmp_path):
    """The temporary folder that stands in for a cache directory that cannot be written
    goes when the process that made it ends (each suite run left two in the temporary
    directory, 2026-12-07), and not when a child forked from that process ends."""
    blocker = tmp_path / "a-file"
    blocker.write_text("not a folder")
    env = dict(os.environ, IMPACTSPH_CACHE_DIR=str(blocker / "cache"))
    result = subprocess.run([sys.executable, "-c", _FALLBACK_CHILD], env=env,
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr[-3000:]
    report = json.loads(result.stdout.strip().splitlines()[-1])
    folder = report["folder"]
    assert not folder.startswith(str(blocker)) and report["kept"], report
    assert report["after_fork"], report  # the grandchild's exit left it to its parent
    assert not os.path.exists(folder), os.listdir(folder)
