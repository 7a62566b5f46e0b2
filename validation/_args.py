"""What the validation scripts' command lines share: argument types that refuse a value as
argparse refuses any other (its usage line, one error line naming the argument and the value,
exit code 2), before any run; a count of 0 had ended in a ``ZeroDivisionError``'s traceback
(an audit, 2026-12-08)."""

from __future__ import annotations

import argparse
import math


def positive_int(text: str) -> int:
    """An integer >= 1 (a particle count, a resolution factor)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not an integer") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"{value} is not an integer >= 1")
    return value


def positive_float(text: str) -> float:
    """A finite number > 0 (a length in spacings)."""
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not a number") from None
    if not (math.isfinite(value) and value > 0.0):
        raise argparse.ArgumentTypeError(f"{text} is not a finite number > 0")
    return value
