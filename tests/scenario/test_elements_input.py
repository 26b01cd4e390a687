"""Orbital elements as a user writes them: P, q, pomega, longitudes, parabolas, angle units and frames."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.initial_conditions.elements import cartesian_to_elements
from orbitsim.initial_conditions.parabolic import parabolic_to_cartesian, parabolic_true_anomaly
from orbitsim.io.trace_reader import read_trace
from orbitsim.runner import run_scenario
from orbitsim.scenario import ScenarioError, scenario_from_dict
from orbitsim.scenario.frames import OBLIQUITY_ARCSEC, rotate

G = 4.0 * math.pi**2
HALLEY = {"name": "halley", "m": 0.0, "primary": "sun", "frame": "ecliptic", "a": 17.834, "e": 0.96714,
          "inc": 162.26, "Omega": 58.42, "omega": 111.33, "M": 10.0}


def _doc(*bodies: dict, **top: object) -> dict:
    return {"units": "au-yr-msun", "integrator": "verlet", "dt": 0.001, "steps": 1, **top,
            "bodies": [{"name": "sun", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0]}, *bodies]}


def _state(body: dict, **top: object) -> tuple[np.ndarray, np.ndarray]:
    s = scenario_from_dict(_doc({"name": "b", "m": 1e-3, "primary": "sun", **body}, **top))
    return s.positions[1], s.velocities[1]


def _same(a: tuple[np.ndarray, np.ndarray], b: tuple[np.ndarray, np.ndarray], rel: float) -> None:
    for u, w in zip(a, b, strict=True):
        assert np.max(np.abs(u - w)) <= rel * np.max(np.abs(w))


def test_period_pericentre_and_longitudes_give_the_same_orbit() -> None:
    ref = _state({"a": 2.0, "e": 0.3, "inc": 10, "Omega": 40, "omega": 70, "M": 30})
    gm = G * 1.001
    period = 2 * math.pi * math.sqrt(8.0 / gm)
    # Each alternative goes through one or two extra roundings (a cube root, a sum of angles): 1e-14
    # relative is a few ulp of the state and far below any difference between distinct orbits.
    _same(_state({"P": period, "e": 0.3, "inc": 10, "Omega": 40, "omega": 70, "M": 30}), ref, 1e-14)
    _same(_state({"q": 1.4, "e": 0.3, "inc": 10, "Omega": 40, "omega": 70, "M": 30}), ref, 1e-14)
    _same(_state({"a": 2.0, "e": 0.3, "inc": 10, "Omega": 40, "pomega": 110, "M": 30}), ref, 1e-14)
    _same(_state({"a": 2.0, "e": 0.3, "inc": 10, "Omega": 40, "omega": 70, "l": 140}), ref, 1e-14)
    f = cartesian_to_elements(gm, *ref)["f"]
    _same(_state({"a": 2.0, "e": 0.3, "inc": 10, "Omega": 40, "pomega": 110, "theta": 110 + f}), ref, 1e-13)


def test_q_for_a_hyperbola() -> None:
    _same(_state({"q": 0.5, "e": 1.5, "f": 20}), _state({"a": -1.0, "e": 1.5, "f": 20}), 1e-15)


@pytest.mark.parametrize("f", [0.0, 30.0, -120.0, 179.0])
def test_parabola_has_zero_energy_and_the_right_pericentre(f: float) -> None:
    gm, q = 2.5, 0.7
    r, v = parabolic_to_cartesian(gm, q, 20.0, 30.0, 40.0, f=f)
    rn = float(np.linalg.norm(r))
    # Energy 0 means v^2 r = 2 gm exactly; 1e-14 relative is a few roundings of r and v.
    assert float(v @ v) * rn / (2 * gm) == pytest.approx(1.0, abs=1e-14)
    # The conic r = p / (1 + cos f) = q / cos^2(f / 2), in the form without cancellation near f = 180 deg.
    assert rn == pytest.approx(q / math.cos(math.radians(f) / 2) ** 2, rel=1e-14)
    h = np.cross(r, v)
    assert float(h @ h) / gm == pytest.approx(2 * q, rel=1e-13)  # p = h^2 / gm = 2 q
    if f == 0.0:
        assert rn == pytest.approx(q, rel=1e-15) and abs(float(r @ v)) < 1e-15  # at pericentre, moving sideways


def test_barker_equation_is_inverted() -> None:
    for M in (-50.0, -1.0, 0.0, 0.3, 2.0, 100.0):
        D = math.tan(parabolic_true_anomaly(M) / 2)
        assert D + D**3 / 3 == pytest.approx(M, rel=1e-14, abs=1e-15)  # a few roundings of the cubic


def test_parabolic_body_in_a_scenario() -> None:
    s = scenario_from_dict(_doc({"name": "c", "m": 0.0, "primary": "sun", "q": 0.5, "e": 1, "M": 0}))
    r, v = s.positions[1], s.velocities[1]
    assert float(np.linalg.norm(r)) == pytest.approx(0.5, rel=1e-15)
    assert float(v @ v) / 2 - G / float(np.linalg.norm(r)) == pytest.approx(0.0, abs=1e-12 * G)  # E = 0


def test_radians() -> None:
    deg = _state({"a": 1.0, "e": 0.1, "inc": 30, "Omega": 60, "omega": 90, "M": 45})
    rad = _state({"a": 1.0, "e": 0.1, "inc": math.pi / 6, "Omega": math.pi / 3, "omega": math.pi / 2,
                  "M": math.pi / 4}, angles="rad")
    _same(rad, deg, 1e-14)  # radians -> degrees -> radians: a rounding or two


def test_halley_alone_in_the_ecliptic() -> None:
    s = scenario_from_dict(_doc(HALLEY))
    el = cartesian_to_elements(G, s.positions[1], s.velocities[1])
    assert el["inc"] == pytest.approx(162.26, abs=1e-9)  # atan2 of the built state: ~1e-12 deg round-off


def test_halley_with_de421_read_back_from_the_trace(tmp_path: Path) -> None:
    """Placed with frame: ecliptic among DE421's equatorial bodies, Halley's inclination to the ecliptic
    read back from the trace is 162.26 deg.

    At the first sample the tolerance, 1e-9 deg, allows only the round-off of the rotation into the
    equatorial axes and back and of the elements (~1e-12 deg). Two steps later the osculating
    inclination has also been moved by Jupiter (its pull on the Sun, ~1.4e-3 au/yr^2, changes Halley's
    heliocentric velocity by ~3e-6 au/yr in 0.002 yr: ~3e-6 deg measured), so there 1e-4 deg. A wrong
    frame would be off by up to the obliquity, 23.44 deg.
    """
    doc = {"units": "au-yr-msun", "integrator": "leapfrog", "dt": 0.001, "steps": 2, "output": {"every": 1},
           "ephemeris": {"epoch": "2000-01-01T12:00:00", "bodies": ["sun", "jupiter"]}, "bodies": [HALLEY]}
    out = tmp_path / "halley.h5"
    run_scenario(scenario_from_dict(doc), out)
    trace = read_trace(out)
    sun, halley = trace.names.index("sun"), trace.names.index("halley")
    gm = G * trace.masses[sun]
    for sample, tolerance in ((0, 1e-9), (-1, 1e-4)):
        r_equ = trace.positions[sample, halley] - trace.positions[sample, sun]
        v_equ = trace.velocities[sample, halley] - trace.velocities[sample, sun]
        r, v = rotate(r_equ, "equatorial", "ecliptic"), rotate(v_equ, "equatorial", "ecliptic")
        assert cartesian_to_elements(gm, r, v)["inc"] == pytest.approx(162.26, abs=tolerance)
        # ... and in the equatorial axes it is not: the frame was applied.
        assert abs(cartesian_to_elements(gm, r_equ, v_equ)["inc"] - 162.26) > 1.0


def test_ecliptic_ephemeris_rotates_every_body() -> None:
    base = {"units": "au-day-msun", "integrator": "verlet", "dt": 1.0, "steps": 1}
    equ = scenario_from_dict({**base, "ephemeris": {"epoch": "2000-01-01", "bodies": ["sun", "earth"]}})
    ecl = scenario_from_dict({**base, "ephemeris": {"epoch": "2000-01-01", "bodies": ["sun", "earth"],
                                                     "frame": "ecliptic"}})
    assert np.allclose(rotate(equ.positions, "equatorial", "ecliptic"), ecl.positions, rtol=0, atol=1e-15)
    # The Earth lies in the ecliptic: its z there is tiny (the EMB offset and the 20 mas frame bias).
    earth = ecl.positions[1] - ecl.positions[0]
    assert abs(earth[2]) < 1e-4 * np.linalg.norm(earth) < abs((equ.positions[1] - equ.positions[0])[2])
    assert OBLIQUITY_ARCSEC == 84381.406


@pytest.mark.parametrize(("body", "key", "words"), [
    ({"a": 1.0, "P": 1.0, "M": 0}, "bodies[1].P", "give only one of a or P or q"),
    ({"e": 0.1, "M": 0}, "bodies[1]", "give one of a or P or q"),
    ({"a": 1.0, "omega": 1, "pomega": 2, "M": 0}, "bodies[1].pomega", "give only one of omega or pomega"),
    ({"a": 1.0, "M": 0, "l": 3}, "bodies[1].l", "give only one of M or f or l or theta"),
    ({"a": 1.0, "e": 1.0, "M": 0}, "bodies[1].a", "give q (the pericentre distance)"),
    ({"P": 1.0, "e": 1.5, "M": 0}, "bodies[1].P", "only a bound orbit"),
    ({"q": 1.0, "e": 1.0, "f": "180 deg"}, "bodies[1].f", "at infinity on a parabola"),
    ({"a": 1.0, "inc": "90 degs", "M": 0}, "bodies[1].inc", "unknown angle unit"),
    ({"a": 1.0, "M": 0, "frame": "galactic"}, "bodies[1].frame", "unknown value 'galactic'"),
    ({"a": -1.0, "e": 0.5, "M": 0}, "bodies[1].a", "a must be positive"),
])
def test_bad_elements_are_one_line_naming_the_key_and_the_angle_unit(body: dict, key: str, words: str,
                                                                    tmp_path: Path) -> None:
    import yaml

    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(_doc({"name": "b", "m": 0.0, "primary": "sun", **body}, angles="rad")))
    result = CliRunner().invoke(cli, ["validate", str(path)])
    assert result.exit_code == 2
    lines = [line for line in result.output.splitlines() if line.strip()]
    assert len(lines) == 1
    assert f"{path}: {key}: " in lines[0] and words in lines[0] and "angles in radians (angles: rad)" in lines[0]


def test_validate_names_the_angle_unit(tmp_path: Path) -> None:
    import yaml

    path = tmp_path / "ok.yaml"
    path.write_text(yaml.safe_dump(_doc(HALLEY)))
    result = CliRunner().invoke(cli, ["validate", str(path)])
    assert result.exit_code == 0, result.output
    assert "input: angles in degrees (angles: deg)" in result.output


def test_unknown_angles_value() -> None:
    with pytest.raises(ScenarioError, match="angles: unknown value 'grad'"):
        scenario_from_dict(_doc(HALLEY, angles="grad"))


# -- no anomaly: f = 0, REBOUND's rule (issue 27, item 15) ------------------------------------------------------

@pytest.mark.parametrize("body", [
    {"a": 1.3, "e": 0.2, "inc": 10, "Omega": 40, "omega": 70},
    {"P": 2.0, "e": 0.0},
    {"q": 0.5, "e": 1.0, "inc": 30},   # a parabola
    {"a": -2.0, "e": 1.5, "pomega": 50},  # a hyperbola
])
def test_no_anomaly_means_f_zero(body: dict) -> None:
    """Without M, f, l or theta the body starts at f = 0 (at pericentre), the same bits as writing f: 0."""
    defaulted, explicit = _state(body), _state({**body, "f": 0})
    for u, w in zip(defaulted, explicit, strict=True):
        np.testing.assert_array_equal(u, w)


def test_no_anomaly_matches_rebound() -> None:
    """REBOUND's ``sim.add(primary=..., a=..., e=...)`` without an anomaly puts the body where orbitsim does."""
    rebound = pytest.importorskip("rebound")
    sim = rebound.Simulation()
    sim.G = G
    sim.add(m=1.0)
    sim.add(m=1e-3, primary=sim.particles[0], a=1.3, e=0.2, inc=math.radians(10), Omega=math.radians(40),
            omega=math.radians(70))
    x, v = _state({"a": 1.3, "e": 0.2, "inc": 10, "Omega": 40, "omega": 70})
    p = sim.particles[1]
    # Two implementations of the same conversion (and degrees -> radians here): a few ulps of |x|, |v|.
    np.testing.assert_allclose(x, [p.x, p.y, p.z], rtol=0, atol=1e-14)
    np.testing.assert_allclose(v, [p.vx, p.vy, p.vz], rtol=0, atol=1e-13)


def test_validate_says_which_bodies_start_at_f_zero(tmp_path: Path) -> None:
    import yaml

    planets = [{"name": f"p{k}", "m": 0.0, "primary": "sun", "a": 1.0 + k} for k in range(7)]
    path = tmp_path / "ok.yaml"
    path.write_text(yaml.safe_dump(_doc(*planets, {**HALLEY, "primary": "sun"})))
    result = CliRunner().invoke(cli, ["validate", str(path)])
    assert result.exit_code == 0, result.output
    notes = [line for line in result.output.splitlines() if "no anomaly" in line]
    assert notes == ["  input: no anomaly (M, f, l or theta) for bodies[1] (p0), bodies[2] (p1), bodies[3] (p2), "
                     "bodies[4] (p3), bodies[5] (p4) and 2 more: f = 0, at pericentre (REBOUND's default)"]
    path.write_text(yaml.safe_dump(_doc(HALLEY)))  # every body gives its anomaly: no such line
    result = CliRunner().invoke(cli, ["validate", str(path)])
    assert result.exit_code == 0 and "no anomaly" not in result.output, result.output


@pytest.mark.parametrize("inc", [30.0, 120.0, 162.26, 180.0])
@pytest.mark.parametrize("longitudes", [{"pomega": 100.0, "l": 250.0}, {"pomega": 100.0, "theta": 250.0},
                                        {"omega": 60.0, "l": 250.0}, {"pomega": -20.0, "M": 30.0}])
def test_longitudes_follow_rebound_on_retrograde_orbits(inc: float, longitudes: dict) -> None:
    """pomega, l and theta are measured along the motion: on a retrograde orbit (cos i < 0) REBOUND's
    ``sim.add`` takes pomega = Omega - omega, l = Omega - omega - M, theta = Omega - omega - f."""
    rebound = pytest.importorskip("rebound")
    sim = rebound.Simulation()
    sim.G = G
    sim.add(m=1.0)
    sim.add(m=1e-3, primary=sim.particles[0], a=1.3, e=0.4, inc=math.radians(inc), Omega=math.radians(40),
            **{k: math.radians(v) for k, v in longitudes.items()})
    x, v = _state({"a": 1.3, "e": 0.4, "inc": inc, "Omega": 40, **longitudes})
    p = sim.particles[1]
    # Two implementations of the same conversion (and degrees -> radians here): a few ulps of |x|, |v|,
    # where a wrong sense of the longitudes moves the body by order 1.
    np.testing.assert_allclose(x, [p.x, p.y, p.z], rtol=0, atol=1e-13)
    np.testing.assert_allclose(v, [p.vx, p.vy, p.vz], rtol=0, atol=1e-12)
