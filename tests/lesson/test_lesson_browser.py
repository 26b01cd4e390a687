"""``lesson.html`` in a real browser: headless Chromium (Debian's ``chromium`` package) loads the
page ``orbitsim demo`` writes, the test moves the dt slider and checks that the orbit and the
energy text change, that the page's loop is frame-rate independent, and that a screenshot is not
blank. Skipped, with the reason, where Chromium is not installed."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.browser import Browser, chromium_path, has_websocket_client

pytestmark = [
    pytest.mark.slow,
    pytest.mark.skipif(chromium_path() is None, reason="chromium is not installed (apt-get install chromium)"),
    pytest.mark.skipif(not has_websocket_client(),
                       reason="websocket-client is not installed (pip install -e '.[test]')"),
]


@pytest.fixture(scope="module")
def page(tmp_path_factory: pytest.TempPathFactory) -> Path:
    from click.testing import CliRunner

    from orbitsim.cli.main import cli

    out = tmp_path_factory.mktemp("demo") / "report"
    result = CliRunner().invoke(cli, ["demo", "-o", str(out), "-q"], catch_exceptions=False)
    assert result.exit_code == 0, result.output
    return out / "lesson.html"


@pytest.fixture(scope="module")
def browser(page: Path) -> Browser:
    with Browser() as b:
        b.open(page, "window.lesson")
        yield b


def _orbit_and_energy(b: Browser) -> tuple[str, str]:
    """The Euler orbit canvas's pixels and its energy text."""
    return (b.evaluate("document.getElementById('orbit-euler').toDataURL()"),
            b.evaluate("document.getElementById('energy-euler').textContent"))


def test_the_page_is_self_contained(page: Path) -> None:
    html = page.read_text()
    # No network: nothing is fetched from elsewhere (no CDN scripts, styles, fonts or images).
    for marker in ("http://", "https://", "src=", "@import"):
        assert marker not in html, marker
    assert 'id="dt"' in html
    assert "change the update order, not dt" in html.lower()


def test_moving_the_slider_changes_the_orbit_and_the_energy(browser: Browser) -> None:
    browser.evaluate("document.getElementById('play').click()")  # pause, so only the slider changes things
    assert browser.evaluate("window.lesson.view.playing") is False
    before = _orbit_and_energy(browser)
    browser.evaluate("(() => { const s = document.getElementById('dt'); s.value = s.max; "
                     "s.dispatchEvent(new Event('input')); })()")
    after = _orbit_and_energy(browser)
    assert browser.evaluate("window.lesson.view.idx") == browser.evaluate("Number(document.getElementById('dt').max)")
    assert after[0] != before[0], "the Euler orbit did not change with dt"
    assert after[1] != before[1], "the energy text did not change with dt"
    assert "max |dE/E|" in after[1]
    # At the largest dt explicit Euler's energy error is larger than at the lesson's dt.
    peak = lambda text: float(text.rsplit(" ", 1)[-1])  # noqa: E731
    assert peak(after[1]) > peak(before[1])


def test_the_orbit_does_not_depend_on_the_frame_rate(browser: Browser) -> None:
    # The page's accumulator loop, fed 5 s of frames at 5, 24 and 60 fps (25, 120 and 300 frames):
    # same steps, same planet.
    states = browser.evaluate("[5, 24, 60].map(f => window.lesson.stateAt(f, 5, 'euler', 2))")
    steps = {s["steps"] for s in states}
    assert len(steps) == 1 and steps.pop() > 100
    for s in states[1:]:
        # Only the rounding of summing frame times differs (~1e-15 relative per frame).
        assert s["x"] == pytest.approx(states[0]["x"], rel=1e-9)
        assert s["y"] == pytest.approx(states[0]["y"], rel=1e-9)
    # And a frame rate that does not divide the time still lands between the same two states.
    odd = browser.evaluate("window.lesson.stateAt(7, 5, 'euler', 2)")
    assert abs(odd["steps"] - states[0]["steps"]) <= 1


def test_the_page_plays_and_its_screenshot_is_not_blank(browser: Browser, tmp_path: Path) -> None:
    from PIL import Image, ImageStat

    browser.evaluate("window.lesson.view.playing || document.getElementById('play').click()")
    browser.evaluate("new Promise(r => setTimeout(r, 1500))")
    assert browser.evaluate("window.lesson.clock.frames") > 3, "the animation loop did not run"
    assert browser.evaluate("window.lesson.clock.steps") > 0
    shot = browser.screenshot(tmp_path / "lesson.png")
    image = Image.open(shot).convert("RGB")
    assert image.size[0] >= 800
    stats = ImageStat.Stat(image)
    # A blank page is one colour: every channel's spread is zero. Orbits, text and panels spread it.
    assert min(stats.stddev) > 10
    assert len(image.getcolors(maxcolors=1 << 20) or []) > 50
