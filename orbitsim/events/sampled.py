"""A step far too long for an orbit, seen in a run without ``events:`` (issue 27, item 6).

Without an ``events:`` section a run is the plain fixed-dt loop, and nothing said that an e = 0.99
comet stepped at dt = P / 200 was thrown out at its first perihelion: the run ended ``complete``.
:class:`StepCheck` looks, between the run's jitted calls, at the state the run has reached (at
the start, and then each time a chunk of samples is handed over), finds each body's shortest
timescale ahead (:func:`orbitsim.events.timescales.timescales_of`: now, or at the pericentre of
its osculating orbit about its dominant attractor) and remembers the first state in which dt
exceeds it. The run then prints one warning, naming the body and the ``events:`` line that
watches every step, and the trace keeps it as the attribute ``unresolved_warning``.

It costs nothing per step: the steps are the same compiled loop, untouched (same bits), and the
check reads a state between calls. It stops looking at the first warning, and its O(N^2) pass
(the dominant attractors) is skipped whenever the pairs it has examined would exceed
:data:`FREE_PAIRS` plus 1/:data:`PAIR_SHARE` of the pairs the integrator's own force evaluations
visited. A look costs about 5 force evaluations of the same N (measured at N = 2000: 3.5e8 pairs/s
against 1.8e9), so it adds about 1% to a large-N run at most (a single step of N = 200000 visits
2e10 pairs), and a few milliseconds to a short one; a chunk of a small run (0.2 s of steps) pays
for several looks, so every chunk is checked. The rule counts pairs, not seconds,
so the bound holds on any machine (where the chunks fall, and so which states are seen, follows
the run's timing, as the chunks do; the bits of the run never do).

Under ``trace`` the warning leaves out what TRACE hands to Bulirsch-Stoer by its own criteria
(:func:`orbitsim.events.bodies.handed_over` for the per-step watch): a pair whose pericentre lies
within ``r_crit_hill`` Hill radii, a massive body whose pericentre timescale is below
dt / ``peri_crit_eta``, and a massless body's orbit about the star (the Kepler drift is exact).
Adaptive schemes (an adaptive ``ias15``) choose their own steps and are not checked.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from orbitsim.scenario import Scenario
    from orbitsim.simulation import Simulation

__all__ = ["EVENTS_LINE", "FREE_PAIRS", "PAIR_SHARE", "StepCheck", "step_check"]

#: Pairs the check may examine whatever the run's length: ~3 ms of the compiled pass, so the state
#: a run starts from is looked at for N up to 1448 (larger ones after their first ~256 steps).
FREE_PAIRS = 2**20
#: Beyond that, at most 1 pair examined for this many pairs the integrator's force evaluations visit:
#: a look costs ~5 force evaluations of the same N, so ~1% of the run.
PAIR_SHARE = 512
#: The ``events:`` line that watches every step for what this check sees only at samples.
EVENTS_LINE = "events: {unresolved: true}"


def step_check(scenario: Scenario, sim: Simulation) -> StepCheck | None:
    """The check for a run of ``scenario`` (which ``sim`` steps), or None where it does not apply:
    a run with an ``events:`` section (its watch checks every step, or was told not to) or a
    scheme that chooses its own steps."""
    if scenario.events is not None or scenario.adaptive:
        return None
    return StepCheck(scenario.names, sim)


class StepCheck:
    """Looks at a run's states between its jitted calls; :attr:`warning` is "" or the one warning."""

    def __init__(self, names: tuple[str, ...] | list[str], sim: Simulation) -> None:
        self.names = list(names)
        self.dt = abs(float(sim.dt))
        self.scheme = sim.spec.name
        self.settings = {**sim.scheme.default_settings(), **sim.settings}
        self.first_step = sim.steps_done
        self.pairs_examined = 0
        self.warning = ""
        self.look(sim)  # the state the run starts from

    def look(self, sim: Simulation) -> None:
        """Check ``sim``'s current state, if the pair budget allows and nothing was found yet."""
        if self.warning or sim.n < 2:
            return
        pairs = sim.n * (sim.n - 1) // 2
        stepped = (sim.steps_done - self.first_step) * pairs * sim.spec.force_evals
        if self.pairs_examined + pairs > FREE_PAIRS + stepped // PAIR_SHARE:
            return
        self.pairs_examined += pairs
        from orbitsim.events.timescales import timescales_of  # noqa: PLC0415 -- lazy: loads numba

        n = sim.n
        tau, attractor, closest = np.empty(n), np.empty(n, dtype=np.int64), np.empty(n)
        timescales_of(sim.pos, sim.vel, sim.m, float(sim.G), float(sim.softening) ** 2, tau, attractor, closest)
        with np.errstate(invalid="ignore"):  # a non-finite state (a diverging run) flags nothing
            too_long = np.flatnonzero(self.dt > tau)
        fixes = [fix for i in too_long if (fix := self._fix(sim, int(i), int(attractor[i]), tau[i], closest[i]))]
        if fixes:
            self.warning = self._text(sim, fixes)

    def _fix(self, sim: Simulation, i: int, k: int, tau: float, closest: float) -> tuple[int, int, float, str] | None:
        """(body, attractor, tau, what to change) for a flagged body, or None where the scheme
        resolves it by its own criteria (trace)."""
        if self.scheme != "trace":
            return i, k, tau, ""
        m, pos = sim.m, sim.pos
        if i == 0 or k == 0:
            other = k if i == 0 else i
            eta = float(self.settings.get("peri_crit_eta", 1.0))
            if m[other] == 0.0 or self.dt > eta * tau:
                return None  # the Kepler drift (exact), or TRACE's pericentre switch hands it to BS
            return i, k, tau, f"lower peri_crit_eta below {self.dt / tau:.3g} (now {eta:g}), or use dt <= {tau:.3g}"
        hill = max(_hill_radius(pos, m, i), _hill_radius(pos, m, k))
        crit = float(self.settings.get("r_crit_hill", 3.0))
        if closest < crit * hill:
            return None  # TRACE will flag the pair as an encounter before it gets there
        return i, k, tau, f"raise r_crit_hill above {closest / hill:.3g} (now {crit:g}), or use dt <= {tau:.3g}"

    def _text(self, sim: Simulation, fixes: list[tuple[int, int, float, str]]) -> str:
        i, k, tau, fix = min(fixes, key=lambda f: f[2])  # the tightest orbit
        who, about = self.names[i], self.names[k]  # without events no body leaves: the scenario's indices
        more = f" (and {len(fixes) - 1} more bod{'ies' if len(fixes) > 2 else 'y'})" if len(fixes) > 1 else ""
        change = fix or f"use dt <= {tau:.3g}"
        how = ("trace steps it with the fixed dt" if self.scheme == "trace"
               else "a fixed step this long cannot follow it")
        return (f"dt = {self.dt:.3g} is longer than the timescale of {who}'s orbit about {about} ({tau:.3g} at its "
                f"tightest; seen at t = {sim.time:.6g}){more}: {how}, and without an events: section no step is "
                f"checked. Add `{EVENTS_LINE}` to the scenario to check every step, or {change}")


def _hill_radius(pos: np.ndarray, m: np.ndarray, i: int) -> float:
    """TRACE's modified Hill radius of body ``i``, |x_i - x_0| (m_i / 3 m_0)^(1/3)."""
    return float(np.linalg.norm(pos[:, i] - pos[:, 0]) * np.cbrt(m[i] / (3.0 * m[0])))
