"""Options and arguments shared by several commands, and the parameter types they need.

Every option's help text ends with an example, so ``--help`` is the reference.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import click

__all__ = ["FINITE_POSITIVE", "force_option", "output_option", "quiet_option", "scenario_argument",
           "threads_option", "trace_argument"]


class FinitePositiveFloat(click.ParamType):
    """A finite number > 0 (``click.FloatRange`` lets ``nan`` and ``inf`` through)."""

    name = "float"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> float:
        try:
            number = float(value)
        except (TypeError, ValueError):
            self.fail(f"{value!r} is not a number", param, ctx)
        if not (math.isfinite(number) and number > 0.0):
            self.fail(f"must be a finite number > 0, got {value}", param, ctx)
        return number


FINITE_POSITIVE = FinitePositiveFloat()

Decorator = Callable[[Callable[..., Any]], Callable[..., Any]]


def scenario_argument(nargs: int = 1) -> Decorator:
    """SCENARIO: a YAML file or the name of a bundled scenario."""
    return click.argument("scenario", metavar="SCENARIO" if nargs == 1 else "SCENARIO...", nargs=nargs,
                          required=True)


def trace_argument() -> Decorator:
    """TRACE: an orbitsim HDF5 trace file."""
    return click.argument("trace", metavar="TRACE.h5")


def output_option(help_text: str) -> Decorator:
    """-o/--output PATH."""
    return click.option("-o", "--output", type=click.Path(dir_okay=False), default=None, help=help_text)


def force_option() -> Decorator:
    """--force: replace an existing output file."""
    return click.option("--force", is_flag=True,
                        help="Overwrite an existing output file (it is replaced only once the new one is "
                             "written). Example: --force")


def quiet_option() -> Decorator:
    """-q/--quiet: no progress bar, no summary; errors only."""
    return click.option("-q", "--quiet", is_flag=True,
                        help="Print nothing but errors (no progress bar, no summary). Example: -q")


def threads_option() -> Decorator:
    """--threads N: Numba threads."""
    return click.option("--threads", type=click.IntRange(min=1), default=None,
                        help="Threads for the force kernel (default: NUMBA_NUM_THREADS or all cores); "
                             "results are bit-identical for any count. Example: --threads 2")
