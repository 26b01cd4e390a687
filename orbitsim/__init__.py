"""orbitsim: a Numba-accelerated fixed-timestep N-body orbit simulator, cross-checked against REBOUND.

The public API is small and imports numba only when a simulation is built::

    from orbitsim import simulate
    result = simulate(masses, positions, velocities, integrator="verlet", dt=1e-3, steps=10_000, every=100)
    result.energy_error   # (E - E0) / |E0| at every sample

See :func:`orbitsim.simulation.simulate`, :class:`orbitsim.simulation.Simulation` and the README.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from orbitsim._version import __version__

if TYPE_CHECKING:
    from orbitsim.simulation import Simulation, SimulationResult, simulate

__all__ = ["Simulation", "SimulationResult", "__version__", "integrators", "simulate"]


def __getattr__(name: str) -> Any:
    # Lazy: `import orbitsim` (and the CLI) must not pay for importing numba.
    if name in ("simulate", "Simulation", "SimulationResult"):
        import importlib  # noqa: PLC0415 -- lazy: off `import orbitsim` (the CLI start-up)

        return getattr(importlib.import_module("orbitsim.simulation"), name)
    if name == "integrators":
        from orbitsim.integrators.registry import INTEGRATORS  # noqa: PLC0415 -- lazy: off `import orbitsim` (the CLI start-up)

        return INTEGRATORS
    raise AttributeError(f"module 'orbitsim' has no attribute {name!r}")
