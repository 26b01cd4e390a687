"""Options and arguments shared by several commands, and the parameter types they need.

Every option's help text ends with an example, so ``--help`` is the reference.
"""

from __future__ import annotations

import math
import os
import re
from collections.abc import Callable
from pathlib import Path
from typing import IO, Any

import click

from orbitsim.cli.errors import EXIT_USAGE, one_line

__all__ = ["FINITE_POSITIVE", "HDF5_SUFFIXES", "POSITIVE_TIME", "OneLineUsageError", "check_trace_output",
           "force_option", "is_hdf5_name", "max_threads", "output_option", "quiet_option", "scenario_argument",
           "threads_option", "trace_argument"]

#: Suffixes an HDF5 file goes by (the HDF Group's list); a trace output must end in one of them.
HDF5_SUFFIXES = (".h5", ".hdf5", ".hdf", ".he5")


class OneLineUsageError(click.ClickException):
    """Bad input shown as the one line every orbitsim error is, exit code 2.

    Click's own :class:`click.BadParameter` prints the usage text and ``Error: ...`` over
    several lines; raising this instead (from a parameter type or a command body) keeps
    ``orbitsim: error: <message>`` on one line, and it is raised before any file is touched.
    """

    exit_code = EXIT_USAGE

    def show(self, file: IO[Any] | None = None) -> None:
        click.echo(f"orbitsim: error: {one_line(self.format_message())}", err=True, file=file)


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


class PositiveTime(click.ParamType):
    """A time > 0: a number in the scenario's time unit (a float, as :data:`FINITE_POSITIVE` gives it) or a
    number with a unit, ``"1 day"``, ``"10 yr"`` (kept as text: the scenario's units, known only once it
    is loaded, convert it, as they convert the same text in the file)."""

    name = "time"
    _TEXT = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([A-Za-z][A-Za-z ]*?)\s*$")

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> float | str:
        if isinstance(value, float):
            return FINITE_POSITIVE.convert(value, param, ctx)
        text = str(value)
        match = self._TEXT.match(text)
        if match is None:
            return FINITE_POSITIVE.convert(value, param, ctx)  # a plain number, or its refusal
        number = float(match.group(1))
        option = param.opts[0] if param is not None and param.opts else "the value"
        if not (math.isfinite(number) and number > 0.0):
            raise OneLineUsageError(f"{option} {text.strip()}: must be a finite time > 0")
        return f"{match.group(1)} {match.group(2)}"


POSITIVE_TIME = PositiveTime()


def max_threads() -> tuple[int, str]:
    """The most threads Numba can run here, and where that limit comes from.

    Computed as ``numba.config.NUMBA_NUM_THREADS`` is (the ``NUMBA_NUM_THREADS`` variable, else the
    cores this process may run on), without importing numba: the CLI imports only click at
    start-up. :func:`orbitsim._jit.set_num_threads` still checks against numba itself.
    """
    env = os.environ.get("NUMBA_NUM_THREADS")
    if env:
        try:
            return max(1, int(env)), f"NUMBA_NUM_THREADS={env}"
        except ValueError:
            pass  # numba warns and falls back to the core count
    try:
        cores = len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        cores = os.cpu_count() or 1
    return max(1, cores), "the CPU cores this process may use; NUMBA_NUM_THREADS sets another limit"


class ThreadCount(click.ParamType):
    """``--threads N``: 1 to :func:`max_threads`, refused in one line (numba would raise mid-run)."""

    name = "integer"

    def convert(self, value: Any, param: click.Parameter | None, ctx: click.Context | None) -> int:
        if isinstance(value, int):
            count = value
        else:
            try:
                count = int(str(value).strip())
            except ValueError:
                raise OneLineUsageError(f"--threads {value}: not a whole number; give 1 or more") from None
        limit, source = max_threads()
        if count < 1:
            raise OneLineUsageError(f"--threads {value}: give a count from 1 to {limit}")
        if count > limit:
            plural = "s" if limit != 1 else ""
            raise OneLineUsageError(f"--threads {value}: at most {limit} thread{plural} can run here ({source}); "
                                    f"give --threads 1 to {limit}")
        return count


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
    # A directory passes here: click's own refusal is usage text; check_trace_output says it in one line.
    return click.option("-o", "--output", type=click.Path(), default=None, help=help_text)


def check_trace_output(path: str | os.PathLike, example_name: str, fix: str = "") -> None:
    """Refuse, before anything is done, a trace output that is a directory or not named as HDF5.

    ``example_name`` (a scenario or trace name) makes the suggested file name concrete; ``fix``
    replaces the advice for a wrong suffix where the output was not given with ``-o``. The
    suffix check is why ``-o out.csv`` is refused instead of silently holding HDF5.
    """
    given = os.fspath(path)
    target = Path(given)
    if target.is_dir():
        raise OneLineUsageError(f"{given}: is a directory; give a file name such as {target / example_name}.h5")
    if not is_hdf5_name(target):
        fix = fix or f"give a .h5 path such as {target.with_suffix('.h5')}"
        raise OneLineUsageError(f"{given}: orbitsim writes HDF5 traces, and this is not an HDF5 file name "
                                f"({', '.join(HDF5_SUFFIXES)}); {fix}")


def is_hdf5_name(path: str | os.PathLike) -> bool:
    """Whether ``path`` ends in one of :data:`HDF5_SUFFIXES` (any case)."""
    return Path(path).suffix.lower() in HDF5_SUFFIXES


def force_option() -> Decorator:
    """--force: replace an existing output file."""
    return click.option("--force", is_flag=True,
                        help="Overwrite an existing output file (it is replaced only once the new one is "
                             "written). Example: --force")


def quiet_option() -> Decorator:
    """-q/--quiet: no progress bar, no summary; errors only."""
    return click.option("-q", "--quiet", is_flag=True,
                        help="Print nothing but errors (no progress bar, no summary). Example: -q")


def device_option() -> Decorator:
    """--device cpu|gpu: where the runs step (overrides the scenario's ``device:``); numba-cuda is loaded
    only for gpu (docs/gpu.md)."""
    return click.option("--device", type=click.Choice(["cpu", "gpu"]), default=None,
                        help="Run on the CPU or on one CUDA GPU (overrides the scenario's device:, default cpu). "
                             "The GPU runs the fixed-step schemes with direct-sum gravity; anything else is refused "
                             "in one line (docs/gpu.md). Example: --device gpu")


def threads_option(*, free_cores_default: bool = True) -> Decorator:
    """--threads N: Numba threads; by default one per core other processes leave free
    (:mod:`orbitsim.cores`), or with ``free_cores_default=False`` (``bench``) all of them."""
    default = ("default: one per core that other processes leave free now, at most NUMBA_NUM_THREADS or all "
               "cores" if free_cores_default else "default and maximum: NUMBA_NUM_THREADS or all cores")
    return click.option("--threads", type=ThreadCount(), default=None,
                        help=f"Threads for the force kernel ({default}); results are bit-identical for any count. "
                             "Example: --threads 2")
