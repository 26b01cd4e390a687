"""``orbitsim map``: a stability map, every pixel a short run, all pixels through the ensemble kernel."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING

import click

from orbitsim.cli.errors import fail, reports_errors, warn
from orbitsim.cli.options import threads_option

if TYPE_CHECKING:
    from orbitsim.stability.plan import MapPlan

#: ``orbitsim.stability.plan.INDICATORS``, written out so that the CLI imports only click at start-up
#: (tests/stability checks that the two agree).
INDICATOR_CHOICES = ("megno", "lyapunov_time", "survival_time", "max_e", "delta_a", "energy_error")
#: Default pixels per chunk: on the CPU, 64 groups of 16 lanes (a map over a massless body steps its massive
#: bodies once per chunk, ~1 us a step: 1,024 pixels make that 2-3% of the chunk, 256 made it 10%; a killed
#: map loses under a second per core); on a GPU, 65,536 threads
#: (512 blocks of 128: several waves over an H100's 132 multiprocessors, one launch per 256 x 256 pixels).
CPU_CHUNK = 1024
GPU_CHUNK = 65536


@click.command("map")
@click.argument("scenario")
@click.option("--x", "x_spec", required=True, metavar="BODY.KEY=LO:HI:N",
              help="The x axis: a body's orbital element (a, P, q, e, inc, Omega, omega, pomega, M, f, l, theta) or "
                   "mass m, N values from LO to HI in the scenario's units and angle setting. The body must be "
                   "given by elements. Example: --x planet.a=5.8:9.0:20")
@click.option("--y", "y_spec", default=None, metavar="BODY.KEY=LO:HI:N",
              help="The y axis, as --x; without it the map is a line over x. Example: --y planet.e=0:0.38:20")
@click.option("--x-log", is_flag=True, help="Space the x values logarithmically (LO > 0).")
@click.option("--y-log", is_flag=True, help="Space the y values logarithmically (LO > 0).")
@click.option("--t-end", required=True, metavar="T",
              help="End time of every pixel's run, in the scenario's time unit or with a unit. Example: --t-end 1e4")
@click.option("-o", "--output", "outdir", required=True, type=click.Path(),
              help="Directory for map.h5 and map.png (created). Example: -o js_map")
@click.option("--indicator", type=click.Choice(INDICATOR_CHOICES), default="megno", show_default=True,
              help="The indicator map.png shows; map.h5 holds them all (orbitsim plot map.h5 --indicator NAME).")
@click.option("--max-energy-error", type=float, default=1e-6, show_default=True,
              help="Pixels whose |dE/E| at the end exceeds this are marked unreliable (hatched in map.png). One "
                   "default for every scheme a map runs: all are symplectic.")
@click.option("--escape-distance", type=float, default=None,
              help="A body farther than this from body 0 has escaped (default: 10 times the largest start "
                   "distance from body 0 over the map).")
@click.option("--chunk", type=click.IntRange(min=1), default=None,
              help=f"Pixels per kernel call (and per Dask task); finished chunks survive a kill. Default: "
                   f"{CPU_CHUNK} on the CPU, {GPU_CHUNK} with --device gpu (enough threads to fill a GPU).")
@click.option("--seed", type=click.IntRange(min=0), default=0, show_default=True,
              help="Seed of every pixel's initial tangent vector (MEGNO, Lyapunov time): unit norm per body, drawn "
                   "from N(0, 1) with numpy's PCG64.")
@click.option("--scheduler", metavar="ADDRESS", default=None,
              help="Send the chunks to this Dask scheduler (tcp://HOST:PORT) instead of running them here.")
@click.option("--device", type=click.Choice(["cpu", "gpu"]), default="cpu", show_default=True,
              help="gpu: every pixel is one thread of a CUDA kernel (orbitsim.gpu.ensemble; needs numba-cuda and a "
                   "GPU), its results equal to the CPU's to ~1e-13 relative, not bit for bit; chunks run in this "
                   "process (not with --scheduler).")
@click.option("--resume", is_flag=True,
              help="Finish a killed map in the directory (the same command does the same); refuse if none is there.")
@click.option("--force", is_flag=True, help="Start over: replace a finished map or another map's parts.")
@click.option("--quiet", is_flag=True, help="No progress line.")
@threads_option()
@reports_errors
def command(scenario: str, x_spec: str, y_spec: str | None, x_log: bool, y_log: bool, t_end: str, outdir: str,
            indicator: str, max_energy_error: float, escape_distance: float | None, chunk: int | None, seed: int,
            scheduler: str | None, device: str, resume: bool, force: bool, quiet: bool, threads: int | None) -> None:
    """Map SCENARIO's stability over one or two parameters: map.h5 (every indicator) and map.png.

    Each pixel runs SCENARIO with the axes' values from its start to --t-end with the scenario's
    integrator and its variational equations, as one system of an ensemble (orbitsim.ensemble):
    wisdom_holman (Jacobi coordinates, no corrector; the tangent map as REBOUND's WHFast), verlet,
    or leapfrog of any order (for close encounters or no dominant body). A pixel stops alone when a
    body escapes, two bodies with radii collide, or its state diverges. Indicators, all from one
    pass: megno, lyapunov_time, survival_time, max_e and delta_a (of the --x body's Jacobi orbit),
    energy_error.

    Finished chunks are kept in DIR/map.parts as they finish: a killed map loses none, and the
    same command (or --resume) runs only the rest, with bit-identical pixels.

    With --device gpu every pixel is one thread of a CUDA kernel (the same scheme, stops and
    indicators; FP64, equal to the CPU's pixels to round-off); map.h5 records the device, and a
    map is resumed on the device it was started on.

    \b
    Examples:
      orbitsim map jupiter_saturn --x planet.a=5.8:9.0:20 --y planet.e=0:0.38:20 --t-end 62830.67 -o js
      orbitsim plot js/map.h5 --indicator max_e
    """
    import numpy as np

    from orbitsim.cli.errors import EXIT_USAGE
    from orbitsim.io.lock import hold_output
    from orbitsim.provenance import provenance
    from orbitsim.scenario import load_scenario
    from orbitsim.scenario.loader import _locate
    from orbitsim.scenario.quantities import scenario_time
    from orbitsim.scenario.yamlio import parse_yaml
    from orbitsim.stability.axes import MapSpecError, parse_axis
    from orbitsim.stability.plan import make_plan
    from orbitsim.stability.store import MapParts

    if device == "gpu":
        if scheduler is not None:
            fail("--device gpu with --scheduler: a GPU map runs its chunks in this process; drop --scheduler",
                 EXIT_USAGE)
        from orbitsim.gpu.device import GPUUnavailableError, device_name, require_cuda

        try:
            require_cuda()
        except GPUUnavailableError as err:
            fail(str(err), EXIT_USAGE)
    if chunk is None:
        chunk = GPU_CHUNK if device == "gpu" else CPU_CHUNK
    base = load_scenario(scenario)
    path, label = _locate(scenario)
    doc, _ = parse_yaml(path.read_text(encoding="utf-8"), label)
    try:
        end = scenario_time(_number_or_text(t_end), base.units, base.G, "--t-end")
        axes = [parse_axis("--x", x_spec, doc, x_log)]
        if y_spec is not None:
            axes.append(parse_axis("--y", y_spec, doc, y_log))
        elif y_log:
            raise MapSpecError("--y-log needs --y")
        if not max_energy_error > 0.0:
            raise MapSpecError(f"--max-energy-error must be > 0, got {max_energy_error:g}")
        if escape_distance is not None and not escape_distance > 0.0:
            raise MapSpecError(f"--escape-distance must be > 0, got {escape_distance:g}")
        plan = make_plan(base, doc, axes, end, escape_distance, chunk, seed, device)
    except MapSpecError as err:
        fail(str(err), EXIT_USAGE)
    directory = Path(outdir)
    if directory.exists() and not directory.is_dir():
        fail(f"-o {outdir}: exists and is not a directory", EXIT_USAGE)
    if not directory.parent.is_dir():
        fail(f"-o {outdir}: directory {directory.parent} does not exist", EXIT_USAGE)
    directory.mkdir(exist_ok=True)
    target = directory / "map.h5"
    from orbitsim.stability.plan import fingerprint

    with hold_output(target):
        parts = MapParts(directory, fingerprint(plan), plan.n_chunks, plan.chunk)
        matches = parts.plan_matches()
        if force:
            parts.remove()
            matches = None
        elif matches is False:
            fail(f"{directory}: holds the parts of another map (other scenario, axes, t-end, chunk or device); use "
                 "another -o, or --force to start over", EXIT_USAGE)
        elif target.exists() and matches is None:
            from orbitsim.stability.driver import read_map

            if read_map(target).get("fingerprint") == parts.fingerprint:
                click.echo(f"{target}: this map is already complete")
                return
            fail(f"{target}: already holds another map; use another -o, or --force to replace it", EXIT_USAGE)
        if resume and matches is None:
            fail(f"--resume: {directory} holds no unfinished map to resume", EXIT_USAGE)
        from orbitsim._jit import set_num_threads

        set_num_threads(threads)
        attrs = {"scenario_yaml": base.to_yaml(), "scenario_sha256": base.sha256,
                 "scenario_name": base.name, "scenario_source": str(base.source),
                 "command": " ".join(["orbitsim", *sys.argv[1:]]), "time_unit": _time_unit(base.units, base.G)}
        attrs.update({f"provenance_{k}": v for k, v in provenance().items()})
        if device == "gpu":  # a CPU map's attributes stay as they were
            attrs.update({"device": "gpu", "device_name": device_name()})
        if not quiet and device == "cpu":
            _hint_shared_massive(plan)
        progress = None if quiet else (lambda line: click.echo(f"\r{line}   ", err=True, nl=False))
        data = run_map(plan, directory, max_energy_error=max_energy_error, indicator=indicator, attrs=attrs,
                       scheduler=scheduler, progress=progress,
                       on_compile=None if quiet else (lambda line: click.echo(f"orbitsim: {line}", err=True)))
    if not quiet:
        click.echo("", err=True)
    counts = ", ".join(f"{int(np.sum(data['status'] == i))} {name}" for i, name in enumerate(data["status_names"]))
    click.echo(f"wrote {target} and {directory / 'map.png'} ({plan.n_pixels} pixels: {counts})")
    unreliable = int(np.sum(data["unreliable"]))
    if unreliable:
        errors = data["indicators"]["energy_error"][data["unreliable"]]
        why = ""
        if unreliable > 1 and float(np.max(errors)) == float(np.min(errors)):
            # a massless varied body carries no energy: the error is the massive bodies', one number for all
            why = (f"; every one has |dE/E| = {float(errors[0]):.3g}, the massive bodies' error, which the varied "
                   f"massless body does not change: a smaller dt or a larger --max-energy-error sets the bar")
        warn(f"{unreliable} pixels have |dE/E| > {max_energy_error:g} (hatched){why}")


def _hint_shared_massive(plan: MapPlan) -> None:
    """A massless varied body that is not the last one: say that listed last it would let the map step
    the massive bodies once for all pixels (orbitsim/ensemble/restricted.py)."""
    from orbitsim.stability.plan import chunk_states

    if plan.integrator != "wisdom_holman":
        return  # the shared massive bodies are the Wisdom-Holman ensemble's shortcut only
    masses = chunk_states(plan, 0).masses[0]
    body = plan.axes[0].index
    if len(masses) >= 3 and masses[body] == 0.0 and body != len(masses) - 1 and \
            all(axis.index == body for axis in plan.axes):
        warn(f"{plan.axes[0].body} is massless but not the last body: listed last, it would let the map step the "
             "massive bodies once for all pixels (about 3x faster; the body order sets the Jacobi coordinates, so "
             "the map would differ slightly)")


def _number_or_text(text: str) -> float | str:
    try:
        return float(text)
    except ValueError:
        return text


def _time_unit(units: str, G: float) -> str:
    from orbitsim.units import UNIT_SYSTEMS

    system = UNIT_SYSTEMS.get(units)
    if system is None or G != system.G:
        return "time units"
    return str(system.time)


def run_map(*args, **kwargs):  # type: ignore[no-untyped-def]
    """:func:`orbitsim.stability.driver.run_map`, imported when first called (it loads numba)."""
    from orbitsim.stability.driver import run_map as _run_map

    return _run_map(*args, **kwargs)
