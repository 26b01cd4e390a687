"""orbitsim's DKD leapfrog and its compositions against REBOUND's ``leapfrog`` of the same order.

Same scheme, same coefficients, same frame, same initial floats: the two codes take the same
substeps and differ only by the rounding of the force sums (orbitsim reassociates its j-sum and
uses Newton's third law; REBOUND's ``basic`` gravity loops over all pairs). After 1000 steps every
body's position must agree to 1e-11 relative (measured: at most 2.6e-13 at dt = 10 days).

REBOUND 5.2 API, checked by experiment: ``sim.integrator = "leapfrog"`` then
``sim.integrator.order = 4`` (there is no ``sim.ri_leapfrog`` any more), ``sim.steps(n)`` takes n
whole steps of ``sim.dt``. An unsupported order is accepted silently, so the test reads it back.

The system is the outer Solar System at J2000 (Sun, Jupiter, Saturn, Uranus, Neptune, Pluto):
barycentric positions (au) and velocities (au/day) from JPL DE421 (evaluated once with
``orbitsim.initial_conditions.ephemeris.de421_states`` and written out here, so the test needs
neither the ephemeris files nor that module), masses = GM / k^2 with the Gaussian constant
k = 0.01720209895 (the Sun's rounded to exactly 1).
"""

from __future__ import annotations

import numpy as np
import pytest

from orbitsim.simulation import simulate

rebound = pytest.importorskip("rebound")

G_GAUSS = 0.01720209895**2  # au^3 / (M_sun day^2)

#: name, mass (M_sun), position (au), velocity (au/day): DE421, JD 2451545.0 TDB, ICRF axes.
OUTER_SOLAR_SYSTEM = (
    ("sun", 1.0,
     (-0.007136456395244341, -0.002647021852902184, -0.0009229478710186404),
     (5.378458816469042e-06, -6.758186170687157e-06, -3.032849308682816e-06)),
    ("jupiter", 0.0009547919152183977,
     (3.994040712133264, 2.7339318400364547, 1.0745889511249778),
     (-0.004562935035030462, 0.0058747040836484455, 0.002629269913481281)),
    ("saturn", 0.00028588567272438574,
     (6.3992724071771425, 6.172010782205168, 2.273847798802086),
     (-0.004286973413521458, 0.0035215863860678276, 0.0016388986618824642)),
    ("uranus", 4.3662437358640145e-05,
     (14.424720796003834, -12.508913423542024, -5.6826103651263),
     (0.0026834835172542646, 0.002455246591881046, 0.0010373759878326337)),
    ("neptune", 5.151389724950276e-05,
     (16.804912254286567, -22.982749682524855, -9.825348544215696),
     (0.002584653188600846, 0.0016616666981557387, 0.0006157823854510027)),
    ("pluto", 7.361781606144686e-09,
     (-9.882489740060837, -27.98152003673075, -5.754616359462622),
     (0.0030341290310025577, -0.0011343511745488656, -0.0012681637607377212)),
)

STEPS = 1000

#: orbitsim name -> REBOUND leapfrog order.
ORDERS = {"leapfrog": 2, "leapfrog4": 4, "leapfrog6": 6, "leapfrog8": 8}

#: Per-body relative position agreement after 1000 steps: the force sums round differently by
#: ~1e-16 per evaluation and that grows roughly linearly with the step count (measured <= 2.6e-13
#: at dt = 10 days, <= 1e-12 at dt = 50 days).
AGREEMENT = 1e-11


def state() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    m = np.array([body[1] for body in OUTER_SOLAR_SYSTEM])
    x = np.array([body[2] for body in OUTER_SOLAR_SYSTEM])
    v = np.array([body[3] for body in OUTER_SOLAR_SYSTEM])
    return m, x, v


def rebound_positions(order: int, dt: float) -> np.ndarray:
    m, x, v = state()
    sim = rebound.Simulation()
    sim.G = G_GAUSS
    for mi, xi, vi in zip(m, x, v, strict=True):
        sim.add(m=mi, x=xi[0], y=xi[1], z=xi[2], vx=vi[0], vy=vi[1], vz=vi[2])
    sim.integrator = "leapfrog"
    sim.integrator.order = order
    assert sim.integrator.order == order
    sim.softening = 0.0
    sim.dt = dt
    sim.steps(STEPS)
    # Substeps add up to dt with rounding; the time is a bookkeeping check that all steps ran.
    assert sim.t == pytest.approx(STEPS * dt, rel=1e-12)
    return np.array([[p.x, p.y, p.z] for p in sim.particles])


def orbitsim_positions(name: str, dt: float) -> np.ndarray:
    m, x, v = state()
    result = simulate(m, x, v, integrator=name, dt=dt, steps=STEPS, every=STEPS, G=G_GAUSS, softening=0.0)
    assert result.steps_done == STEPS
    return result.final_positions


def relative_difference(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Per-body |a - b| / |b|."""
    return np.linalg.norm(a - b, axis=1) / np.linalg.norm(b, axis=1)


@pytest.mark.parametrize("dt", [10.0, 50.0], ids=["dt=10d", "dt=50d"])
@pytest.mark.parametrize("name", list(ORDERS))
def test_positions_agree_with_rebound(name: str, dt: float) -> None:
    ours = orbitsim_positions(name, dt)
    theirs = rebound_positions(ORDERS[name], dt)
    diff = relative_difference(ours, theirs)
    _, x0, _ = state()
    assert np.min(np.linalg.norm(theirs - x0, axis=1)[1:]) > 0.1  # every planet moved (>= 0.1 au)
    worst = OUTER_SOLAR_SYSTEM[int(np.argmax(diff))][0]
    assert np.all(diff < AGREEMENT), f"{name}: max relative difference {diff.max():.2e} ({worst})"


def test_comparison_tells_the_orders_apart() -> None:
    """Negative control: at dt = 50 days (Jupiter's period / 87) every orbitsim scheme is far from
    REBOUND's other orders, so the agreement above really pins the order and the coefficients.
    (At dt = 10 days orders 6 and 8 differ by only 1.9e-12, below the tolerance.)"""
    dt = 50.0
    theirs = {order: rebound_positions(order, dt) for order in ORDERS.values()}
    for name, order in ORDERS.items():
        ours = orbitsim_positions(name, dt)
        for other, positions in theirs.items():
            if other != order:
                # Measured >= 9e-8 (orders 6 vs 8); 100x the agreement tolerance is a clear gap.
                assert relative_difference(ours, positions).max() > 100 * AGREEMENT, (name, other)
