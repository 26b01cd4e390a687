"""REBOUND's WHFast512 in the ``ensemble`` bench group: a figure where it runs, one line saying why where not."""

from __future__ import annotations

import sys
import types

import pytest
import rebound

from orbitsim.bench.ensemble import WHFAST512_TOLERANCE, side_by_side_step_ns, whfast512_step_ns, whfast512_unavailable
from orbitsim.bench.report import markdown


class _Wheel:
    """The wheel's Simulation behind a proxy (``rebound.Simulation`` cannot be subclassed: its ``__new__``
    returns the base class), for stand-ins that refuse WHFast512 as other REBOUNDs do."""

    def __init__(self) -> None:
        object.__setattr__(self, "sim", rebound.Simulation())

    def __getattr__(self, name: str) -> object:
        return getattr(self.sim, name)

    def __setattr__(self, name: str, value: object) -> None:
        setattr(self.sim, name, value)


class _NoWHFast512(_Wheel):
    """As a REBOUND from before WHFast512 answers its name (``reb_simulation_set_integrator``)."""

    def __setattr__(self, name: str, value: object) -> None:
        if name == "integrator" and value == "whfast512":
            raise RuntimeError("Integrator not found.")
        super().__setattr__(name, value)


class _NoAVX512(_Wheel):
    """As REBOUND's step answers on a CPU without AVX-512 (``integrator_whfast512.c``)."""

    def steps(self, n: int) -> None:
        if str(self.sim.integrator) == "whfast512":
            raise RuntimeError("AVX512 is not supported by your CPU.")
        self.sim.steps(n)


def _rebound_with(simulation: type | None = None, **attributes: object) -> types.ModuleType:
    """A stand-in for the ``rebound`` module: the wheel's, with its Simulation or attributes replaced."""
    fake = types.ModuleType("rebound")
    fake.__dict__.update({k: v for k, v in vars(rebound).items() if not k.startswith("__")})
    fake.__version__ = rebound.__version__
    if simulation is not None:
        fake.Simulation = simulation
    fake.__dict__.update(attributes)
    return fake


@pytest.mark.parametrize(("fake", "expected"), [
    (None, "REBOUND is not installed"),
    (_rebound_with(avx512_available=False), "this CPU lacks AVX-512F/DQ"),
    (_rebound_with(_NoAVX512), "cannot run WHFast512 here: AVX512 is not supported by your CPU."),
    (_rebound_with(_NoWHFast512), "cannot run WHFast512 here: Integrator not found."),
], ids=["missing", "no-avx512-flag", "step-refused", "too-old"])
def test_whfast512_gives_a_reason_not_a_figure_where_rebound_lacks_it(monkeypatch, fake, expected):
    monkeypatch.setitem(sys.modules, "rebound", fake)  # None: `import rebound` raises ImportError
    assert expected in whfast512_unavailable()
    result = whfast512_step_ns(100)
    assert isinstance(result, str) and expected in result


def test_the_side_by_side_table_shows_the_reason_in_place_of_whfast512s_figure(monkeypatch):
    monkeypatch.setitem(sys.modules, "rebound", _rebound_with(_NoAVX512))
    measured = side_by_side_step_ns(k=4, steps=3, rounds=1, single_steps=50)
    assert measured["whfast512"] == (f"REBOUND {rebound.__version__} cannot run WHFast512 here: "
                                     "AVX512 is not supported by your CPU.")
    for key in ("ensemble_threads_ns", "ensemble_1_thread_ns", "single_ns", "whfast_ns"):
        assert len(measured[key]) == 1 and measured[key][0] > 0.0, key
    probe = {"group": "ensemble", "kind": "ensemble", "map_n": 2, "years": 1.0, "indicator": "megno",
             "rebound_map_s": 1.0, "orbitsim_map_s": 1.0, "orbitsim_compute_s": 0.5, "orbitsim_kernel_s": 0.4,
             "k": 4, "steps": 3, "ensemble_ns": 700.0, "single_ns": 700.0, "rebound_ns": 1200.0,
             "step_ns_side_by_side": measured}
    text = markdown({"machine": {}, "matrix": {"name": "t", "quick": True}, "threads": 2, "probes": [probe]})
    line = next(row for row in text.splitlines() if row.startswith("- ns per system-step side by side"))
    assert line.endswith(f"WHFast512 not run: {measured['whfast512']}")
    assert "N_systems" not in line  # no figure beside the reason


@pytest.mark.skipif(whfast512_unavailable() is not None, reason="this REBOUND cannot run WHFast512 here")
def test_whfast512_is_timed_where_it_runs_and_agrees_with_whfast():
    result = whfast512_step_ns(2000)
    assert result["n_systems_1_ns"] > 0.0 and result["n_systems_2_ns"] > 0.0
    # measured 2e-13 after 2000 steps (WHFAST512_TOLERANCE says why); 0 would mean the same arithmetic
    assert 0.0 < result["max_rel_dx"] < WHFAST512_TOLERANCE
    refused = whfast512_step_ns(2000, tolerance=result["max_rel_dx"] / 2)
    assert isinstance(refused, str) and "disagrees with WHFast" in refused and "not timed" in refused
    text = markdown({"machine": {}, "matrix": {"name": "t", "quick": True}, "threads": 2, "probes": [
        {"group": "ensemble", "kind": "ensemble", "map_n": 2, "years": 1.0, "indicator": "megno",
         "rebound_map_s": 1.0, "orbitsim_map_s": 1.0, "orbitsim_compute_s": 0.5, "orbitsim_kernel_s": 0.4,
         "k": 4, "steps": 3, "ensemble_ns": 700.0, "single_ns": 700.0, "rebound_ns": 1200.0,
         "step_ns_side_by_side": {"k": 4, "steps": 3, "single_steps": 2000, "threads": 2,
                                  "ensemble_threads_ns": [600.0], "ensemble_1_thread_ns": [1100.0],
                                  "single_ns": [650.0], "whfast_ns": [1200.0],
                                  "whfast512": {key: [value] if key.endswith("_ns") else value
                                                for key, value in result.items()}}}]})
    assert f"N_systems = 1 {result['n_systems_1_ns']:.0f}, N_systems = 2 {result['n_systems_2_ns']:.0f}" in text
