"""``orbitsim animate``: a movie of a scenario or a trace, drawn by the fixed-timestep render loop."""

from __future__ import annotations

import sys
from pathlib import Path
from typing import TYPE_CHECKING

import click

from orbitsim.cli.errors import fail, reports_errors
from orbitsim.cli.options import FINITE_POSITIVE, OneLineUsageError, force_option, is_hdf5_name, quiet_option

if TYPE_CHECKING:  # the CLI imports only click at start-up
    from orbitsim.animation.states import Source

#: Frames of trail behind each body by default: about three seconds of a 30 fps movie.
DEFAULT_TRAIL = 90


@click.command("animate")
@click.argument("source", metavar="SCENARIO|TRACE.h5")
@click.option("-o", "--output", required=True, type=click.Path(),
              help="The movie: .mp4 (H.264, through the ffmpeg that imageio-ffmpeg ships) or .gif (Pillow). "
                   "Example: -o orbit.mp4")
@click.option("--fps", type=FINITE_POSITIVE, default=30.0, show_default=True,
              help="Frames per second of movie. The movie has fps x duration frames, whatever dt is. "
                   "Example: --fps 24")
@click.option("--duration", type=FINITE_POSITIVE, default=None,
              help="Seconds of movie for the whole run (default 10). Example: --duration 5")
@click.option("--speed", type=FINITE_POSITIVE, default=None, metavar="T_PER_S",
              help="Simulated time per second of movie, instead of --duration (the movie then lasts the run's "
                   "span / T_PER_S). Example: --speed 2.5")
@click.option("--view", type=click.Choice(["xy", "xz", "yz", "3d"]), default="xy", show_default=True,
              help="The projection: a coordinate plane, or a 3-D view. Example: --view 3d")
@click.option("--trail", type=click.IntRange(min=0), default=DEFAULT_TRAIL, show_default=True,
              help="Frames of path drawn behind each body (0: none). Example: --trail 300")
@click.option("--follow", default=None, metavar="BODY",
              help="Keep this body (a name or 0-based index) at the centre. Example: --follow planet")
@force_option()
@quiet_option()
@reports_errors
def command(source: str, output: str, fps: float, duration: float | None, speed: float | None, view: str,
            trail: int, follow: str | None, force: bool, quiet: bool) -> None:
    """Animate SCENARIO (stepped as the frames need it) or TRACE.h5 (its recorded samples).

    Frames fall at --fps on the movie's clock; the physics advances in whole steps of the run's
    fixed dt. Each frame adds its elapsed simulated time to an accumulator, takes whole steps while
    the accumulator holds at least dt, and draws the state interpolated by alpha = accumulator / dt
    between the last two physics states. Each frame shows the time, dt, the physics steps taken
    so far and |dE/E|.

    \b
    Examples:
      orbitsim animate two_body_eccentric -o e.mp4 --fps 24 --duration 5
      orbitsim animate lesson -o lesson.gif --fps 15 --duration 8
      orbitsim animate run.h5 -o run.mp4 --view 3d --follow sun
    """
    target = _check_output(output, force)
    if duration is not None and speed is not None:
        raise OneLineUsageError("give --duration or --speed, not both (--speed sets the duration: span / speed)")
    from orbitsim.animation.draw import FrameDrawer
    from orbitsim.animation.encode import FRAME_SIZE, movie_format, write_movie
    from orbitsim.animation.loop import resolve_timing
    from orbitsim.animation.states import body_index, frame_states

    src = _load(source)
    try:
        timing = resolve_timing(fps, src.span, duration, speed)
        followed = body_index(src, follow) if follow is not None else None
    except ValueError as err:
        raise OneLineUsageError(str(err)) from None
    say = (lambda _m: None) if quiet else (lambda m: click.echo(m, err=True))
    say(f"{src.label}: {timing.n_frames} frames at {fps:g} fps ({timing.duration:.4g} s), "
        f"{timing.speed:.4g} time units per second of movie")
    states = frame_states(src, timing)
    if states.note:
        say(f"orbitsim: note: {states.note}")
    drawer = FrameDrawer(src, states, view, trail, followed, FRAME_SIZE[movie_format(target)])
    if quiet:
        write_movie(drawer.frames(), target, fps, drawer.size)
    else:
        with click.progressbar(drawer.frames(), length=timing.n_frames, label="rendering", show_pos=True,
                               file=sys.stderr) as frames:
            write_movie(frames, target, fps, drawer.size)
    click.echo(f"wrote {target} ({timing.n_frames} frames, {int(states.engine_steps[-1]):,} physics steps)")


def _check_output(output: str, force: bool) -> Path:
    """The output path, refused in one line before anything runs: a suffix that is not .mp4 or
    .gif, a directory, a missing parent, or an existing file without --force."""
    from orbitsim.animation.encode import movie_format

    target = Path(output)
    if target.is_dir():
        raise OneLineUsageError(f"{output}: is a directory; give a file name such as {target / 'movie.mp4'}")
    try:
        movie_format(target)
    except ValueError as err:
        raise OneLineUsageError(str(err)) from None
    if not target.parent.is_dir():
        fail(f"{output}: directory {target.parent} does not exist")
    if target.exists() and not force:
        fail(f"{output}: already exists; use --force to overwrite it")
    return target


def _load(source: str) -> Source:
    """A trace when SOURCE is an HDF5 file name, else a scenario (a file or a bundled name)."""
    from orbitsim.animation.states import scenario_source, trace_source

    if is_hdf5_name(source):
        return trace_source(source)
    from orbitsim.scenario import load_scenario

    return scenario_source(load_scenario(source))
