"""Figure of ``orbitsim plot --resonance P:Q``: the resonant angles of a pair of bodies.

For bodies on either side of a P:Q mean-motion resonance (P > Q, the outer period P/Q times the
inner one; order k = P - Q) the two resonant angles are (Murray & Dermott 1999, ch. 8)

.. math::

    \\varphi_{\\rm in} = P \\lambda_{\\rm out} - Q \\lambda_{\\rm in} - k \\varpi_{\\rm in}, \\qquad
    \\varphi_{\\rm out} = P \\lambda_{\\rm out} - Q \\lambda_{\\rm in} - k \\varpi_{\\rm out},

with the mean longitude :math:`\\lambda = \\Omega + \\omega + M` and the longitude of pericentre
:math:`\\varpi = \\Omega + \\omega` of each body, read from the trace's ``elements`` group (a
run with ``output.elements: true``). An angle that *librates* (stays within less than a full turn
about a centre) marks a pair in resonance; one that circulates through every value does not. The
figure draws both angles in [-180, 180) degrees and the period ratio
:math:`(a_{\\rm out} / a_{\\rm in})^{3/2}` with P/Q marked, against time: a capture shows as the
ratio settling on P/Q while the angles stop circulating.

References
----------
.. [1] Murray, C. D. & Dermott, S. F. (1999), *Solar System Dynamics*, CUP, ch. 8.
"""

from __future__ import annotations

import math
import re
from pathlib import Path
from typing import Any

import numpy as np

from orbitsim.plots.style import figure_style, save

__all__ = ["draw_resonance", "libration_amplitude", "parse_resonance", "pick_pair", "resonant_angles"]

_SPEC = re.compile(r"^\s*(\d+)\s*:\s*(\d+)\s*$")


def parse_resonance(text: str) -> tuple[int, int]:
    """``"2:1"`` -> ``(2, 1)``; P > Q >= 1 (the outer body's period over the inner one's)."""
    match = _SPEC.match(text)
    if not match or not int(match.group(1)) > int(match.group(2)) >= 1:
        raise ValueError(f"resonance must be P:Q with whole numbers P > Q >= 1, e.g. 2:1 or 3:2; got {text!r}")
    return int(match.group(1)), int(match.group(2))


def wrap_deg(angle: np.ndarray) -> np.ndarray:
    """Degrees in [-180, 180)."""
    return np.mod(np.asarray(angle, dtype=np.float64) + 180.0, 360.0) - 180.0


def resonant_angles(elements: dict[str, np.ndarray], inner: int, outer: int, p: int, q: int
                    ) -> tuple[np.ndarray, np.ndarray]:
    """(phi_in, phi_out) in degrees, [-180, 180), from element arrays of shape (S, N) in degrees.

    ``elements`` holds at least ``Omega``, ``omega`` and ``M``; ``inner`` and ``outer`` are
    body columns.
    """
    pomega = {k: elements["Omega"][:, k] + elements["omega"][:, k] for k in (inner, outer)}
    lam = {k: pomega[k] + elements["M"][:, k] for k in (inner, outer)}
    base = p * lam[outer] - q * lam[inner]
    return wrap_deg(base - (p - q) * pomega[inner]), wrap_deg(base - (p - q) * pomega[outer])


def libration_amplitude(phi: np.ndarray) -> float:
    """Largest distance (degrees) of the angle from its circular mean: < 180 when it librates.

    A circulating angle comes within a sample's spacing of 180; a librating one stays at its
    libration amplitude. NaN samples are ignored.
    """
    rad = np.radians(np.asarray(phi, dtype=np.float64))
    rad = rad[np.isfinite(rad)]
    if rad.size == 0:
        return math.nan
    centre = math.atan2(float(np.mean(np.sin(rad))), float(np.mean(np.cos(rad))))
    return float(np.max(np.abs(wrap_deg(np.degrees(rad - centre)))))


def pick_pair(names: list[str], a: np.ndarray, pair: str | None) -> tuple[int, int]:
    """Columns (inner, outer) of the pair: named ``"b,c"``, else the only two bodies with elements.

    ``a`` is the (S, N) semi-major axis array of the bodies ``names``; inner is the one with the
    smaller median a.
    """
    if pair:
        wanted = [w.strip() for w in pair.split(",")]
        missing = [w for w in wanted if w not in names]
        if len(wanted) != 2 or wanted[0] == wanted[1] or missing:
            raise ValueError(f"--pair must name two different bodies with elements ({', '.join(names)}); got {pair!r}")
        cols = [names.index(w) for w in wanted]
    else:
        cols = [k for k in range(len(names)) if np.isfinite(a[:, k]).any()]
        if len(cols) != 2:
            raise ValueError(f"{len(cols)} bodies have elements; name the pair with --pair inner,outer")
    median = [float(np.nanmedian(a[:, k])) for k in cols]
    inner, outer = (cols[0], cols[1]) if median[0] <= median[1] else (cols[1], cols[0])
    return inner, outer


def draw_resonance(data: dict[str, Any], resonance: tuple[int, int], pair: tuple[int, int], target: Path,
                   title: str, time_unit: str) -> Path:
    """Two panels against time: both resonant angles (dots), and the period ratio with P/Q marked.

    ``data`` is :func:`orbitsim.plots.elements.read_elements`' dictionary.
    """
    p, q = resonance
    inner, outer = pair
    el, time = data["elements"], data["time"]
    names = data["bodies"]
    phi_in, phi_out = resonant_angles(el, inner, outer, p, q)
    with np.errstate(invalid="ignore", divide="ignore"):
        ratio = (el["a"][:, outer] / el["a"][:, inner]) ** 1.5
    def coef(c: int) -> str:  # mathtext: no "1" in front of a term
        return "" if c == 1 else str(c)

    lam = f"{coef(p)}\\lambda_{{\\rm {names[outer]}}} - {coef(q)}\\lambda_{{\\rm {names[inner]}}}"
    k = coef(p - q)
    with figure_style() as plt:
        fig, (ax_phi, ax_ratio) = plt.subplots(2, 1, sharex=True, figsize=(9, 6.5), layout="constrained")
        # Dots, not lines: a circulating angle would otherwise be drawn as vertical strokes at each wrap.
        for phi, body, colour in ((phi_in, names[inner], "C0"), (phi_out, names[outer], "C1")):
            ax_phi.plot(time, phi, ".", ms=2, color=colour, label=rf"$\varphi = {lam} - {k}\varpi_{{\rm {body}}}$")
        ax_phi.set_ylim(-180, 180)
        ax_phi.set_yticks([-180, -90, 0, 90, 180])
        ax_phi.set_ylabel("resonant angle [deg]")
        ax_phi.set_title(f"{p}:{q} resonant angles of {names[inner]} and {names[outer]}")
        ax_phi.legend(loc="upper right", markerscale=4)
        ax_ratio.plot(time, ratio, lw=0.9, color="C2")
        ax_ratio.axhline(p / q, color="0.35", lw=0.8, ls="--", label=f"{p}/{q}")
        ax_ratio.set_ylabel(r"$(a_{\rm out}/a_{\rm in})^{3/2}$")
        ax_ratio.set_xlabel(f"time [{time_unit}]")
        ax_ratio.legend(loc="upper right")
        fig.suptitle(title)
        return save(fig, target)
