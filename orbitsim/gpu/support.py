"""What a run on the GPU (``device: gpu``) carries, and the one-line refusal of what it does not.

Imports nothing but the standard library: the scenario's validation asks it (:mod:`orbitsim.scenario.model`)
without loading numba-cuda, and :mod:`orbitsim.gpu.stepping` takes its list of schemes from here.
"""

from __future__ import annotations

from typing import Any

__all__ = ["DEVICES", "GPU_SCHEMES", "GPU_SUPPORTS", "gpu_refusal"]

#: The values of ``device:`` in a scenario (and of ``--device``).
DEVICES = ("cpu", "gpu")

#: The schemes the GPU runs, in the registry's order (the rest are refused, in one line, by name).
GPU_SCHEMES = ("euler", "semi_implicit_euler", "verlet", "leapfrog", "rk4", "leapfrog4", "leapfrog6", "leapfrog8")

#: What every refusal says the GPU does run.
GPU_SUPPORTS = (f"the GPU runs {', '.join(GPU_SCHEMES)} with direct-sum Newtonian gravity (softening allowed), "
                "without events, forces, output.chaos, output.elements or integrator settings")


def gpu_refusal(scenario: Any) -> tuple[str, str] | None:
    """``(key, reason)`` for the first part of ``scenario`` (a ScenarioData) the GPU does not carry, or None."""
    what: tuple[str, str] | None = None
    if scenario.integrator not in GPU_SCHEMES:
        what = ("integrator", f"{scenario.integrator} does not run on the GPU")
    elif scenario.integrator_settings:
        what = ("integrator", f"integrator settings ({', '.join(scenario.integrator_settings)}) are not taken on "
                              "the GPU")
    elif scenario.events is not None:
        what = ("events", "events are not watched on the GPU")
    elif scenario.forces:
        what = ("forces", "forces are not applied on the GPU")
    elif scenario.chaos is not None:
        what = ("output.chaos", "the variational equations (output.chaos) are not integrated on the GPU")
    elif scenario.record_elements:
        what = ("output.elements", "orbital elements (output.elements) are not recorded on the GPU")
    if what is None:
        return None
    key, reason = what
    return key, f"{reason} (device: gpu): {GPU_SUPPORTS}; or run it with device: cpu"
