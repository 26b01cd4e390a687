"""The ``orbitsim`` command: a click group whose subcommands load lazily.

Start-up imports click and nothing else: each subcommand lives in its own module
(``orbitsim/cli/<name>.py``, exposing ``command``) and imports numpy, numba, h5py or REBOUND in its
body. ``orbitsim --help`` reads the one-line summaries below, so listing the commands imports no
subcommand module at all.
"""

from __future__ import annotations

import importlib
import importlib.util  # a submodule: `import importlib` does not load it (an editable install's finder did)
import sys

import click

from orbitsim._version import __version__

#: name -> (module under orbitsim.cli, one-line summary shown by `orbitsim --help`).
COMMANDS: dict[str, tuple[str, str]] = {
    "run": ("run", "Run a scenario and write its HDF5 energy trace."),
    "validate": ("validate", "Check scenario files without running them."),
    "list": ("listing", "List integrators or bundled scenarios."),
    "info": ("info", "Show what is in an HDF5 trace."),
    "export": ("export", "Export a trace as a REBOUND file, a scenario or CSV."),
    "plot": ("plot", "Plot orbits and |dE/E| from a trace."),
    "animate": ("animate", "Render a movie (MP4 or GIF) of a scenario or a trace."),
    "compare": ("compare", "Cross-check orbitsim against REBOUND on a scenario."),
    "convergence": ("convergence", "Measure convergence order against a reference."),
    "demo": ("demo", "Run the lesson: one orbit, three ways to step time."),
    "bench": ("bench", "Benchmark orbitsim against REBOUND."),
    "batch": ("batch", "Run a parameter sweep on Dask."),
    "map": ("map", "Make a stability map (MEGNO, survival, max e) over one or two parameters."),
    "resume": ("resume", "Continue an interrupted run from its checkpoint."),
    "cache": ("cache", "Inspect or clear the compiled-kernel cache."),
}


class LazyGroup(click.Group):
    """A group that imports a subcommand's module only when that subcommand is used."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return [name for name, (module, _) in COMMANDS.items() if _module_exists(module)]

    def invoke(self, ctx: click.Context) -> object:
        """Run the subcommand; a usage error (``--steps 0``, an unknown option) is one line, exit 2.

        Click shows such errors as its usage text followed by ``Error: ...``; every orbitsim
        error is ``orbitsim: error: ...`` on one line instead, with where to read more.
        """
        from orbitsim.cli.options import OneLineUsageError

        try:
            return super().invoke(ctx)
        except click.UsageError as err:
            if isinstance(err, OneLineUsageError):
                raise
            where = err.ctx.command_path if err.ctx is not None else "orbitsim"
            raise OneLineUsageError(f"{err.format_message().rstrip('.')}; see `{where} --help`") from None

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        entry = COMMANDS.get(cmd_name)
        if entry is None or not _module_exists(entry[0]):
            return None
        if ctx.resilient_parsing or _listing_only():
            return click.Command(cmd_name, help=entry[1], short_help=entry[1])
        module = importlib.import_module(f"orbitsim.cli.{entry[0]}")
        return module.command


def _module_exists(module: str) -> bool:
    return importlib.util.find_spec(f"orbitsim.cli.{module}") is not None


def _listing_only() -> bool:
    """True for a bare `orbitsim --help`: the summaries suffice, no module is imported."""
    args = sys.argv[1:]
    return bool(args) and all(a in ("--help", "-h") for a in args)


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="orbitsim")
def cli() -> None:
    """orbitsim: fixed-timestep N-body orbits, Numba-fast, cross-checked against REBOUND.

    \b
    Quick start:
      orbitsim list scenarios
      orbitsim run two_body_circular -o circ.h5
      orbitsim plot circ.h5 -o circ.png
      orbitsim compare outer_solar_system -o cmp/
    """


def main() -> None:
    """Console-script entry point."""
    cli(prog_name="orbitsim")
