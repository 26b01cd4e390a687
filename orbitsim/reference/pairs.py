"""Matched pairs: the same scheme in orbitsim and in REBOUND, and how closely they must agree.

Two codes that take the same substeps with the same coefficients produce the same trajectory up
to round-off. orbitsim's leapfrog family uses REBOUND's coefficient tables (see
:mod:`orbitsim.integrators.leapfrog`), so the pairs below should agree to ~1e-13 relative on
well-behaved systems. What separates them is only round-off: orbitsim's force sum is reassociated
for vectorisation, its multiply-adds fused (a relative change of ~4e-15 per evaluation) and each
code rounds differently.

Tolerance on the maximum relative position difference over the run (the metric of
:func:`orbitsim.compare.metrics.relative_position_difference`), per sample k:

    allowed_k = max(BASE_TOLERANCE * max(1, n_k / BASE_STEPS) ** 1.5,  TWIN_MARGIN * twin_k)

* The first term is the nominal tolerance, 1e-9 at 10^4 steps. Round-off errors random-walk
  the energy, and an energy error shifts the orbital frequency, so the phase error of a
  fixed-step integration grows like n^{3/2} (Brouwer's law; Brouwer 1937, AJ 46, 149). The
  measured agreement on non-chaotic systems is ~1e-13 at 10^4 steps, so the nominal value leaves
  a margin of four decades while a different scheme (a truncation-error difference, ~dt^p) still
  fails it by many decades.
* The second term covers chaotic and close-encounter systems, where round-off differences grow
  exponentially and no fixed number can hold. Beside each pair we run REBOUND a second time from
  initial positions scaled by ``1 + TWIN_PERTURBATION`` (4 ulp): the "twin" divergence twin_k
  measures how much this very scenario amplifies round-off-sized differences by sample k. On the
  Pythagorean three-body problem (dt = 1e-4, 2e5 steps) the orbitsim-REBOUND leapfrog4 difference
  followed the twin within a factor 3 from 1e-13 up to 3e-4 after the close encounter at t = 15.9,
  hence the margin of 100.

A pair whose difference exceeds ``allowed_k`` at any sample disagrees: ``orbitsim compare`` exits 1
and names it. A pair within ``allowed_k`` is a pass only while ``allowed_k`` stays below
``orbitsim.compare.metrics.TESTABLE_LIMIT`` (1e-3 of the system's size) and the IAS15 reference
is reliable; otherwise its verdict says why it is not testable and ``compare`` exits 5.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from orbitsim.reference.bridge import ReboundScheme, parse_rebound_scheme

#: Nominal tolerance on the max relative position difference of a matched pair at BASE_STEPS.
BASE_TOLERANCE = 1e-9
BASE_STEPS = 10_000
#: Exponent of the nominal tolerance's growth with the step count (Brouwer's law, see above).
GROWTH_EXPONENT = 1.5
#: Relative scaling of the twin run's initial positions: 4 ulp, the size of a few round-offs.
TWIN_PERTURBATION = 2.0**-50
#: How far above the twin divergence a pair may be (measured ratio: below 3).
TWIN_MARGIN = 100.0

#: What the compare report says of a pair whose codes hand close encounters to another integrator
#: (TRACE), before the tolerance it shows: which encounter happens is decided by round-off-sized
#: differences near a switching threshold, so there is no middle ground between the same bits and
#: chaotic divergence, and the twin run measures how fast that divergence grows in this scenario.
ENCOUNTER_CHAOS = ("close encounters are chaotic, so orbitsim and REBOUND agree bit for bit only while both take "
                   "the same sequence of encounters, and otherwise diverge at the rate round-off grows in the "
                   "chaos")


@dataclass(frozen=True)
class MatchedPair:
    """An orbitsim integrator and the REBOUND scheme that takes the same steps.

    Parameters
    ----------
    orbitsim : str
        orbitsim integrator name.
    rebound : ReboundScheme
        The REBOUND scheme.
    reason : str
        Why the two should agree (or, for a user-specified pair, that the user asked for it).
    builtin : bool
        False for pairs added with ``--pair``.
    encounters : bool
        True for hybrids that switch integrators at close encounters (TRACE): the report then
        states :data:`ENCOUNTER_CHAOS` with the twin-divergence tolerance the pair was judged by.
    """

    orbitsim: str
    rebound: ReboundScheme
    reason: str
    builtin: bool = True
    encounters: bool = False

    @property
    def name(self) -> str:
        """``orbitsim <name> <-> REBOUND <scheme>``, how verdicts name the pair."""
        return f"orbitsim {self.orbitsim} <-> {self.rebound.display}"


#: The built-in pairs. wisdom_holman is listed even before it is registered: pairs whose orbitsim
#: side is missing are skipped (see :func:`available_pairs`).
MATCHED_PAIRS: tuple[MatchedPair, ...] = (
    MatchedPair("leapfrog", ReboundScheme("leapfrog", "2"),
                "drift-kick-drift leapfrog in both codes"),
    MatchedPair("leapfrog4", ReboundScheme("leapfrog", "4"),
                "Yoshida (1990) triple jump, REBOUND's order-4 coefficients"),
    MatchedPair("leapfrog6", ReboundScheme("leapfrog", "6"),
                "Blanes & Casas (2016) 9-stage composition, REBOUND's order-6 coefficients"),
    MatchedPair("leapfrog8", ReboundScheme("leapfrog", "8"),
                "Blanes & Casas (2016) 17-stage composition, REBOUND's order-8 coefficients"),
    MatchedPair("wisdom_holman", ReboundScheme("whfast"),
                "Wisdom-Holman map, same coordinates and corrector as REBOUND WHFast"),
    MatchedPair("trace", ReboundScheme("trace"),
                "TRACE in both codes: the same switching, Bulirsch-Stoer and order of operations (bit for bit "
                "until chaotic encounters amplify round-off; the twin run measures that)", encounters=True),
)

#: orbitsim's ias15 and REBOUND's IAS15: an adaptive pair, judged by ``orbitsim compare`` when ias15
#: is among its integrators (the two are its references). Its ``n`` is IAS15's accepted steps.
IAS15_PAIR = MatchedPair("ias15", ReboundScheme("ias15"),
                         "IAS15 in both codes: the same Gauss-Radau predictor-corrector, step control "
                         "(PRS23), epsilon, first trial step and exact finish on every output time")


def _registered(name: str) -> str | None:
    """Canonical orbitsim name, or None when the integrator is not registered."""
    from orbitsim.integrators.registry import UnknownIntegratorError, canonical_name  # noqa: PLC0415 -- lazy: loads numba

    try:
        return canonical_name(name)
    except UnknownIntegratorError:
        return None


def available_pairs() -> tuple[MatchedPair, ...]:
    """The built-in pairs whose orbitsim integrator is registered in this build."""
    return tuple(p for p in MATCHED_PAIRS if _registered(p.orbitsim) is not None)


def partner_of(orbitsim_name: str) -> ReboundScheme | None:
    """The REBOUND scheme matched with an orbitsim integrator, or None."""
    canonical = _registered(orbitsim_name)
    for pair in available_pairs():
        if pair.orbitsim == canonical:
            return pair.rebound
    return None


def parse_pair(text: str) -> MatchedPair:
    """Parse ``--pair orbitsim_name=rebound_name[:option]`` into a user-specified pair.

    Raises
    ------
    ValueError
        For a missing ``=``, an unknown orbitsim integrator or REBOUND scheme, or an adaptive
        REBOUND scheme (a pair compares fixed steps).
    """
    left, sep, right = text.partition("=")
    if not sep or not left.strip() or not right.strip():
        raise ValueError(f"--pair expects ORBITSIM=REBOUND[:OPTION], e.g. verlet=leapfrog:4; got {text!r}")
    from orbitsim.integrators.registry import canonical_name  # noqa: PLC0415 -- lazy: loads numba

    scheme = parse_rebound_scheme(right)
    if not scheme.fixed_step:
        raise ValueError(f"--pair {text!r}: {scheme.name} is adaptive and cannot be a matched pair")
    return MatchedPair(canonical_name(left), scheme, "requested with --pair", builtin=False)


def nominal_tolerance(steps: np.ndarray | int) -> np.ndarray:
    """Nominal tolerance after ``steps`` steps: BASE_TOLERANCE * max(1, n / BASE_STEPS)^1.5."""
    n = np.asarray(steps, dtype=np.float64)
    return BASE_TOLERANCE * np.maximum(1.0, n / BASE_STEPS) ** GROWTH_EXPONENT


def allowed_difference(steps: np.ndarray, twin: np.ndarray | None) -> np.ndarray:
    """Tolerance at each sample: the nominal one, raised where the twin run shows amplification."""
    allowed = nominal_tolerance(steps)
    if twin is not None and twin.size:
        k = min(allowed.size, twin.size)
        allowed = allowed.copy()
        allowed[:k] = np.fmax(allowed[:k], TWIN_MARGIN * twin[:k])  # fmax: a NaN twin sample adds nothing
    return allowed
