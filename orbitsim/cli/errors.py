"""One error path for every command: a one-line message on stderr and a documented exit code.

Exit codes

===  =====================================================================================
0    success
1    an unexpected error (a bug: set ``ORBITSIM_DEBUG=1`` for the traceback), or a sweep
     in which a run failed
2    bad input or usage: a malformed scenario, a bad option, an unreadable trace, an
     existing output file without ``--force``, an output another process is writing, an
     output directory that cannot be written; nothing is written
3    the run diverged (its state became non-finite); the trace is kept
4    an I/O error while writing (disk full, quota, a device error): the output path keeps
     what it had before, and only a resumable checkpoint is left beside it
5    ``compare``: no pair disagrees, but agreement is not testable (a chaotic pair, or an
     unreliable reference)
6    the run halted at an event the scenario asked to halt on (``events:``); the trace is kept
130  interrupted by SIGINT (Ctrl-C); 143 by SIGTERM; the trace is kept
===  =====================================================================================

The error classes are matched lazily, by module and name: importing them here would import
numba and h5py at start-up, and an exception can only be an instance of a class whose module
has already been imported.
"""

from __future__ import annotations

import functools
import os
import sys
from collections.abc import Callable
from typing import Any, NoReturn, TypeVar

import click

__all__ = ["EXIT_DIVERGED", "EXIT_FAILURE", "EXIT_HALTED", "EXIT_IO", "EXIT_NOT_TESTABLE", "EXIT_OK", "EXIT_USAGE",
           "fail", "reports_errors", "warn"]

EXIT_OK = 0
EXIT_FAILURE = 1
EXIT_USAGE = 2
EXIT_DIVERGED = 3
EXIT_IO = 4
#: ``compare`` when no matched pair disagrees but the comparison cannot pass: a pair's agreement is
#: not testable (chaos) or the IAS15 reference is unreliable. Distinct from 1 (a pair disagrees:
#: orbitsim or the pairing is wrong) so that a script can tell "wrong" from "this scenario cannot be
#: checked this way", and non-zero so that it never reads as a pass.
EXIT_NOT_TESTABLE = 5
EXIT_HALTED = 6

#: Errors that mean "fix your input": (module, class name).
USER_ERRORS: tuple[tuple[str, str], ...] = (
    ("orbitsim.scenario.errors", "ScenarioError"),
    ("orbitsim.io.schema", "TraceError"),  # re-exported by orbitsim.io.trace; CheckpointError is one
    ("orbitsim.sampling", "SimulationError"),  # re-exported by orbitsim.simulation
    ("orbitsim.integrators.registry", "UnknownIntegratorError"),
    ("orbitsim.io.schema", "OutputError"),  # re-exported by orbitsim.runner; OutputBusyError is one
    ("orbitsim.gpu.device", "GPUUnavailableError"),  # --device gpu without a usable GPU
)

F = TypeVar("F", bound=Callable[..., Any])


def is_user_error(exc: BaseException) -> bool:
    """Whether ``exc`` is one of :data:`USER_ERRORS`."""
    for module_name, class_name in USER_ERRORS:
        module = sys.modules.get(module_name)
        cls = getattr(module, class_name, None) if module is not None else None
        if cls is not None and isinstance(exc, cls):
            return True
    return False


def one_line(text: object) -> str:
    """Collapse a message to one line."""
    return " ".join(str(text).split())


def fail(message: str, code: int = EXIT_USAGE) -> NoReturn:
    """Print ``orbitsim: error: <message>`` on stderr and exit with ``code``."""
    click.echo(f"orbitsim: error: {one_line(message)}", err=True)
    raise click.exceptions.Exit(code)


def warn(message: str) -> None:
    """Print ``orbitsim: note: <message>`` on stderr."""
    click.echo(f"orbitsim: note: {one_line(message)}", err=True)


def _is_complete(exc: OSError) -> bool:
    """Whether ``exc`` is a :class:`orbitsim.io.schema.OutputWriteError`, whose text is already the whole line."""
    module = sys.modules.get("orbitsim.io.schema")
    cls = getattr(module, "OutputWriteError", None) if module is not None else None
    return cls is not None and isinstance(exc, cls)


def reports_errors(func: F) -> F:
    """Decorate a command so that errors end it with one line and the right exit code, no traceback."""

    @functools.wraps(func)
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        try:
            return func(*args, **kwargs)
        except (click.exceptions.Exit, click.ClickException, click.Abort):
            raise
        except KeyboardInterrupt:
            fail("interrupted", 130)
        except BrokenPipeError:
            # The reader went away (`orbitsim info x.h5 | head`): stop quietly, as the Python docs
            # advise, and keep the interpreter from complaining again while flushing stdout at exit.
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, sys.stdout.fileno())
            raise click.exceptions.Exit(EXIT_FAILURE) from None
        except Exception as exc:
            if is_user_error(exc):
                fail(str(exc), EXIT_USAGE)
            if os.environ.get("ORBITSIM_DEBUG"):
                raise
            if isinstance(exc, OSError):
                where = f"{exc.filename}: " if exc.filename else ""
                fail(str(exc) if _is_complete(exc) else f"{where}{exc.strerror or exc}", EXIT_IO)
            fail(f"unexpected {type(exc).__name__}: {exc} (set ORBITSIM_DEBUG=1 for a traceback)", EXIT_FAILURE)

    return wrapper  # type: ignore[return-value]
