"""The compiled loops' vectors (impactsph.vectors): 256-bit vectors asked for on an x86-64
host with AVX-512 and loads for gathers on a Zen 4, numba's own setting and
``IMPACTSPH_VECTORS=host`` respected, a bad value refused by name; and in this process, the
compiled code itself."""

from __future__ import annotations

import json
import os
import platform
import re
import subprocess
import sys

import numba as nb
import numpy as np
import pytest

import impactsph  # noqa: F401  (the choice is made when impactsph is imported)
from impactsph.output import provenance
from impactsph.vectors import (
    FEATURES_VARIABLE,
    NO_GATHER,
    NO_GATHER_CPUS,
    PREFER_256,
    VECTORS_VARIABLE,
    _host_features,
    choose_vector_width,
    cpu_name,
    tuning,
    vector_width,
)

AVX512 = "+sse2,+avx2,+fma,+avx512f,+avx512vl,-amx-tile"
NO_AVX512 = "+sse2,+avx2,+fma,-avx512f,-avx512vl"


def _choose(environ: dict[str, str], features: str = AVX512, machine: str = "x86_64",
            cpu: str = "emeraldrapids"):
    return choose_vector_width(environ, lambda: features, machine, lambda: cpu)


@pytest.mark.parametrize("cpu, features, added", [
    ("emeraldrapids", AVX512, [PREFER_256]),
    ("znver5", AVX512, [PREFER_256]),
    ("znver4", AVX512, [PREFER_256, NO_GATHER]),
    ("znver4", NO_AVX512, [NO_GATHER]),
])
def test_a_host_gets_its_own_features_and_the_measured_choices(cpu, features, added):
    assert tuning(cpu, features) == added
    environ: dict[str, str] = {}
    assert _choose(environ, features, cpu=cpu) == ",".join(added)
    assert environ == {FEATURES_VARIABLE: ",".join([features, *added])}
    environ = {VECTORS_VARIABLE: " Tuned "}
    assert _choose(environ, features, machine="AMD64", cpu=cpu) == ",".join(added)
    assert environ[FEATURES_VARIABLE].endswith(added[-1])


@pytest.mark.parametrize("environ, features, machine, cpu, said", [
    ({FEATURES_VARIABLE: "+avx2"}, AVX512, "x86_64", "znver4", "as set"),
    ({VECTORS_VARIABLE: "host"}, AVX512, "x86_64", "znver4", "IMPACTSPH_VECTORS=host"),
    ({VECTORS_VARIABLE: "HOST"}, AVX512, "x86_64", "znver4", "IMPACTSPH_VECTORS=host"),
    ({}, NO_AVX512, "x86_64", "znver3", "nothing to change"),
    ({}, AVX512, "aarch64", "znver4", "not x86-64"),
])
def test_nothing_is_set_where_numba_or_the_user_decides_or_nothing_is_to_change(
        environ, features, machine, cpu, said):
    before = dict(environ)
    assert said in _choose(environ, features, machine, cpu)
    assert environ == before


def test_a_bad_choice_is_refused_by_name():
    with pytest.raises(ValueError, match=r"^\$IMPACTSPH_VECTORS = '256': allowed are tuned .* "
                                         r"and host"):
        _choose({VECTORS_VARIABLE: "256"})


def _dot(a, b):
    total = 0.0
    for i in range(a.shape[0]):
        total += a[i] * b[i]
    return total


def _gathered_sum(a, index):
    total = 0.0
    for i in range(index.shape[0]):
        total += a[index[i]]
    return total


def _host_has_avx512() -> bool:
    return (platform.machine().lower() in ("x86_64", "amd64")
            and "+avx512f" in _host_features().split(","))


@pytest.mark.skipif(not _host_has_avx512(), reason="not an x86-64 host with AVX-512")
def test_this_process_compiles_256_bit_vectors_and_says_so():
    """After ``import impactsph``, a vectorised sum compiled in this process uses 256-bit
    registers and no 512-bit ones, a sum over an index gathers except on the CPU models
    that load the lanes instead, and every output's provenance says so (unless the
    environment set numba's features: then they are as set)."""
    if os.environ.get(FEATURES_VARIABLE, "") and PREFER_256 not in os.environ[FEATURES_VARIABLE]:
        pytest.skip(f"${FEATURES_VARIABLE} was set without {PREFER_256}")
    dot = nb.njit(fastmath=True)(_dot)
    a = np.arange(64.0)
    assert dot(a, a) == float(a @ a)
    code = dot.inspect_asm(dot.signatures[0])
    assert "ymm" in code and "zmm" not in code
    gathered = nb.njit(fastmath=True)(_gathered_sum)
    assert gathered(a, np.arange(64)[::-1].copy()) == float(a.sum())
    gathers = re.search(r"\sv(p)?gather", gathered.inspect_asm(gathered.signatures[0])) is not None
    assert gathers == (cpu_name() not in NO_GATHER_CPUS)
    width = "256-bit" + ("" if gathers else ", no gathers")
    assert vector_width() == width
    assert provenance()["vectors"] == width


@pytest.mark.skipif(not _host_has_avx512(), reason="not an x86-64 host with AVX-512")
@pytest.mark.parametrize("first, choice", [
    ("", "host"),
    ("import numba\n@numba.njit\ndef f(x):\n    return x\n", ""),
], ids=["IMPACTSPH_VECTORS=host", "numba-set-up-first"])
def test_llvm_chooses_where_asked_or_where_numba_was_set_up_first(first, choice):
    """In a fresh process, with ``IMPACTSPH_VECTORS=host``, or where a numba function was
    defined before ``import impactsph`` (numba's compiler made with the host's features):
    nothing is set, and the provenance says the CPU model's tuning decided."""
    env = {k: v for k, v in os.environ.items() if k not in (FEATURES_VARIABLE, VECTORS_VARIABLE)}
    env[VECTORS_VARIABLE] = choice
    script = (first + "import json, os, impactsph\n"
              "from impactsph.vectors import vector_width, cpu_name\n"
              "print(json.dumps([os.environ.get('NUMBA_CPU_FEATURES'), vector_width(), "
              "cpu_name()]))\n")
    out = subprocess.run([sys.executable, "-c", script], env=env, capture_output=True,
                         text=True, check=True).stdout
    features, width, cpu = json.loads(out.strip().splitlines()[-1])
    assert features is None
    assert width == f"LLVM's choice for {cpu}"
