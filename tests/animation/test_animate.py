"""``orbitsim animate``: the fixed-timestep render loop, its guarantees, the movies, the errors."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.animation.loop import Timing, frame_times, interpolate, plan_frames, resolve_timing
from orbitsim.cli.main import cli


def _invoke(*args: str) -> object:
    return CliRunner().invoke(cli, ["animate", *args], catch_exceptions=False)


def _literal_loop(timing: Timing, dt: float) -> tuple[list[int], list[float]]:
    """The loop as the lesson states it, one step at a time: the reference for :func:`plan_frames`."""
    _, clock = frame_times(timing)
    acc, done, steps, alphas = 0.0, 0, [], []
    for k in range(timing.n_frames):
        acc += clock[k] - (clock[k - 1] if k else 0.0)
        while acc >= dt:
            acc -= dt
            done += 1
        steps.append(done)
        alphas.append(acc / dt)
    return steps, alphas


# -- the loop ------------------------------------------------------------------------------------


@pytest.mark.parametrize("dt", [1e-4, 0.0418879, 0.3, 7.0])
@pytest.mark.parametrize(("fps", "duration"), [(24, 5.0), (30, 10.0), (12.5, 4.0)])
def test_frame_count_is_fps_times_duration_whatever_dt(dt: float, fps: float, duration: float) -> None:
    timing = resolve_timing(fps, span=40.0, duration=duration)
    plan = plan_frames(timing, dt)
    assert plan.n_frames == timing.n_frames == round(fps * duration)
    assert plan.wall_time[-1] == pytest.approx((plan.n_frames - 1) / fps, rel=1e-15)  # one division's rounding


def test_speed_sets_the_duration() -> None:
    timing = resolve_timing(24, span=60.0, speed=2.5)
    assert timing.n_frames == 24 * 24 and timing.duration == 24.0


def test_two_scenarios_differing_only_in_dt_share_frame_times() -> None:
    from orbitsim.animation.states import scenario_source
    from orbitsim.scenario import load_scenario

    base = load_scenario("lesson")
    fine = base.with_overrides(dt=base.dt / 4, steps=base.steps * 4)  # the same end time
    sources = [scenario_source(base), scenario_source(fine)]
    assert sources[0].span == sources[1].span  # dividing dt by 4 and multiplying steps by 4 is exact
    plans = [plan_frames(resolve_timing(24, s.span, duration=5.0), s.loop_dt) for s in sources]
    np.testing.assert_array_equal(plans[0].wall_time, plans[1].wall_time)
    np.testing.assert_array_equal(plans[0].clock, plans[1].clock)
    # The same frames ask for four times the physics steps at a quarter of the step.
    assert plans[1].steps[-1] == pytest.approx(4 * plans[0].steps[-1], abs=4)


def test_the_accumulator_takes_whole_steps_and_keeps_the_remainder() -> None:
    timing = resolve_timing(30, span=10.0, duration=3.0)
    for dt in (0.01, 0.07, 0.5):
        plan = plan_frames(timing, dt)
        steps, alphas = _literal_loop(timing, dt)
        # Where a frame's clock lands on a step boundary, rounding decides between (n, alpha ~ 1) and
        # (n + 1, alpha ~ 0): the same drawn state. steps + alpha agree to rounding everywhere.
        assert np.max(np.abs(plan.steps - np.array(steps))) <= 1
        np.testing.assert_allclose(plan.steps + plan.alpha, np.add(steps, alphas), atol=1e-6)
        assert np.all((plan.alpha >= 0) & (plan.alpha < 1))
        assert np.all(np.diff(plan.steps) >= 0) and plan.steps_this_frame.sum() == plan.steps[-1]
        # steps + alpha, in units of dt, is the clock the frames fed in.
        np.testing.assert_allclose((plan.steps + plan.alpha) * dt, plan.clock, rtol=1e-12, atol=1e-12)


def test_a_frame_longer_than_a_step_takes_several_and_a_shorter_one_may_take_none() -> None:
    coarse = plan_frames(Timing(fps=10, n_frames=11, speed=1.0), dt=0.025)  # 0.1 per frame: 4 steps
    assert list(coarse.steps_this_frame[1:]) == [4] * 10
    fine = plan_frames(Timing(fps=10, n_frames=11, speed=1.0), dt=0.25)  # 2.5 frames per step
    assert 0 in fine.steps_this_frame[1:] and fine.steps_this_frame.max() == 1


def test_alpha_interpolates_between_the_last_two_states() -> None:
    prev = np.array([[0.0, 0.0, 0.0], [1.0, 2.0, 3.0]])
    cur = np.array([[1.0, 0.0, 0.0], [3.0, 2.0, -1.0]])
    np.testing.assert_array_equal(interpolate(prev, cur, 0.0), prev)
    np.testing.assert_allclose(interpolate(prev, cur, 0.25), [[0.25, 0, 0], [1.5, 2, 2]])
    stacked = interpolate(np.stack([prev, prev]), np.stack([cur, cur]), np.array([0.0, 0.5]))
    np.testing.assert_allclose(stacked[1], 0.5 * (prev + cur))


def test_frames_show_the_engines_states_interpolated() -> None:
    from orbitsim.animation.states import frame_states, scenario_source
    from orbitsim.scenario import load_scenario
    from orbitsim.simulation import simulate

    sc = load_scenario("lesson")
    source = scenario_source(sc)
    states = frame_states(source, resolve_timing(10, source.span, duration=3.0))
    every = simulate(sc.masses, sc.positions, sc.velocities, integrator=sc.integrator, dt=sc.dt, steps=sc.steps,
                     every=1, G=sc.G, softening=sc.softening).positions
    plan = states.plan
    expected = every[plan.previous] + plan.alpha[:, None, None] * (every[plan.steps] - every[plan.previous])
    # The same engine stopped at other steps gives the same bits; only the blend's rounding differs.
    np.testing.assert_allclose(states.positions, expected, rtol=0, atol=1e-14)
    np.testing.assert_allclose(states.time, plan.state_time)
    assert states.energy_error.max() < 1e-2  # Verlet on the lesson orbit: |dE/E| ~ 1e-3
    trail = states.trail(plan.n_frames - 1, 5)
    assert trail.shape[1:] == (2, 3) and np.array_equal(trail[-1], states.positions[-1])


@pytest.mark.parametrize(("kwargs", "word"), [
    ({"duration": 2.0, "speed": 1.0}, "not both"), ({"duration": 0.001}, "no frame"),
    ({"duration": 1e6}, "more than"), ({"duration": math.nan}, "finite"),
])
def test_timing_errors_name_the_fix(kwargs: dict[str, float], word: str) -> None:
    with pytest.raises(ValueError, match=word):
        resolve_timing(30, 10.0, **kwargs)


# -- the movies ----------------------------------------------------------------------------------


def test_mp4_of_two_body_eccentric_has_exactly_fps_times_duration_frames(tmp_path: Path) -> None:
    import imageio_ffmpeg

    out = tmp_path / "e.mp4"
    result = _invoke("two_body_eccentric", "-o", str(out), "--fps", "24", "--duration", "5", "-q")
    assert result.exit_code == 0, result.output
    frames, seconds = imageio_ffmpeg.count_frames_and_secs(str(out))
    assert frames == 120 and seconds == pytest.approx(5.0, abs=1 / 24)  # the container rounds to a frame
    assert [p.name for p in tmp_path.iterdir()] == ["e.mp4"]  # no temporary file left


def test_gif_of_the_lesson_has_every_frame(tmp_path: Path) -> None:
    from PIL import Image

    out = tmp_path / "lesson.gif"
    result = _invoke("lesson", "-o", str(out), "--fps", "10", "--duration", "2.5", "--view", "3d", "-q")
    assert result.exit_code == 0, result.output
    with Image.open(out) as gif:
        assert gif.n_frames == 25 and gif.info["duration"] == 100
        gif.seek(gif.n_frames - 1)
        last = np.asarray(gif.convert("RGB"))
    assert last.std() > 5  # drawn, not blank


def test_a_trace_plays_its_samples(tmp_path: Path) -> None:
    from PIL import Image

    trace = tmp_path / "lesson.h5"
    run = CliRunner().invoke(cli, ["run", "lesson", "-o", str(trace), "--every", "3", "-q"], catch_exceptions=False)
    assert run.exit_code == 0, run.output
    out = tmp_path / "t.gif"
    result = _invoke(str(trace), "-o", str(out), "--fps", "8", "--speed", "20", "--follow", "star", "--trail", "0")
    assert result.exit_code == 0, result.output
    # 945 steps of 0.0418879 in 20 time units per second: 1.98 s, 16 frames at 8 fps.
    with Image.open(out) as gif:
        assert gif.n_frames == round(8 * 945 * 0.0418879 / 20)
    assert "physics steps" in result.output


# -- bad input: one line, exit 2, nothing written --------------------------------------------------


@pytest.mark.parametrize(("args", "word"), [
    (["-o", "{d}/m.avi"], ".mp4 or .gif"),
    (["-o", "{d}/m"], ".mp4 or .gif"),
    (["-o", "{d}/missing/m.mp4"], "does not exist"),
    (["-o", "{d}/m.mp4", "--duration", "2", "--speed", "1"], "not both"),
    (["-o", "{d}/m.mp4", "--fps", "0"], "--fps"),
    (["-o", "{d}/m.mp4", "--view", "side"], "--view"),
    (["-o", "{d}/m.mp4", "--follow", "moon"], "--follow moon"),
    (["-o", "{d}/m.mp4", "--duration", "0.001"], "no frame"),
])
def test_bad_input_is_one_line_and_writes_nothing(tmp_path: Path, args: list[str], word: str) -> None:
    result = CliRunner().invoke(cli, ["animate", "lesson", *[a.format(d=tmp_path) for a in args]])
    assert result.exit_code == 2, result.output
    lines = result.output.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("orbitsim: error:") and word in lines[0], result.output
    assert list(tmp_path.iterdir()) == []


def test_existing_output_needs_force_and_a_trace_needs_positions(tmp_path: Path) -> None:
    movie = tmp_path / "m.gif"
    movie.write_bytes(b"old")
    result = CliRunner().invoke(cli, ["animate", "lesson", "-o", str(movie)])
    assert result.exit_code == 2 and "--force" in result.output and movie.read_bytes() == b"old"
    trace = tmp_path / "bare.h5"
    run = CliRunner().invoke(cli, ["run", "lesson", "-o", str(trace), "--no-positions", "-q"])
    assert run.exit_code == 0, run.output
    result = CliRunner().invoke(cli, ["animate", str(trace), "-o", str(tmp_path / "b.mp4")])
    assert result.exit_code == 2 and "positions were not recorded" in result.output
    assert not (tmp_path / "b.mp4").exists()


@pytest.mark.parametrize("name", ["m.mp4", "m.gif"])
def test_a_render_that_fails_leaves_nothing(tmp_path: Path, name: str) -> None:
    from orbitsim.animation.encode import write_movie

    def frames() -> object:
        yield np.zeros((480, 640, 3), dtype=np.uint8)
        raise KeyboardInterrupt  # Ctrl-C halfway through

    with pytest.raises(KeyboardInterrupt):
        write_movie(frames(), tmp_path / name, 10, (640, 480))
    assert list(tmp_path.iterdir()) == []
