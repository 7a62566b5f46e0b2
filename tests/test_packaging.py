"""The package declares what it imports: every third-party module that a file of
``src/impactsph`` imports is one of ``pyproject.toml``'s core dependencies, so that
``pip install impactsph`` alone runs every command (the plates' analysis once needed SciPy,
which only the ``test`` extra brought, and said "not measured" without it)."""

from __future__ import annotations

import ast
import re
import sys
import tomllib
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
PACKAGE = ROOT / "src" / "impactsph"

#: import names whose distribution is named otherwise (none today; e.g. "yaml": "pyyaml")
DISTRIBUTION_OF: dict[str, str] = {}


def declared() -> set[str]:
    """The core dependencies' distribution names, lower case, without their versions."""
    project = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]
    return {re.split(r"[<>=!~\[; ]", spec, maxsplit=1)[0].strip().lower()
            for spec in project["dependencies"]}


def imported() -> dict[str, set[str]]:
    """Each third-party top-level module the package's files import (absolute imports,
    at any depth of a file, guarded or not), with the files that import it."""
    found: dict[str, set[str]] = {}
    for path in sorted(PACKAGE.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                names = [node.module]
            else:
                continue
            for name in names:
                top = name.split(".")[0]
                if top != "impactsph" and top not in sys.stdlib_module_names:
                    found.setdefault(top, set()).add(str(path.relative_to(ROOT)))
    return found


def test_every_module_the_package_imports_is_a_core_dependency():
    deps = declared()
    missing = {name: sorted(files) for name, files in imported().items()
               if DISTRIBUTION_OF.get(name, name).lower() not in deps}
    assert not missing, f"imported but not in pyproject.toml's dependencies: {missing}"


def test_the_check_finds_an_undeclared_import(tmp_path, monkeypatch):
    """The scan sees imports inside functions (as the plates' SciPy was) and ignores the
    standard library and the package's own modules."""
    package = tmp_path / "src" / "impactsph"
    package.mkdir(parents=True)
    (package / "m.py").write_text("import os\nfrom . import x\nfrom impactsph import y\n"
                                  "def f():\n    from somewhere.deep import thing\n")
    monkeypatch.setattr(sys.modules[__name__], "PACKAGE", package)
    monkeypatch.setattr(sys.modules[__name__], "ROOT", tmp_path)
    assert imported() == {"somewhere": {"src/impactsph/m.py"}}
