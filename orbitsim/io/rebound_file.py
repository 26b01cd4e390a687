"""REBOUND simulation files (``sim.save_to_file``) in and out.

Reading: :func:`read_rebound_file` takes one snapshot of a REBOUND Simulation or Simulationarchive
file (both are the same binary format; a plain ``save_to_file`` is an archive of one snapshot) and
returns the particles' masses, positions, velocities and radii, ``G``, ``t``, ``dt``, the softening
and the integrator mapped to orbitsim's (:func:`orbitsim_integrator`). A snapshot saved
unsynchronised (WHFast, SABA, MERCURIUS, EOS with ``safe_mode = 0``) is read as REBOUND's
``sim.synchronize()`` reports it (:func:`_synchronized`), the physical state at its ``t``.

Writing: :func:`write_rebound_file` builds a :class:`rebound.Simulation` from a state and saves it
atomically (a temporary file beside the target, then a rename): ``save_to_file`` *appends* a
snapshot to an existing file, so writing to a fresh temporary file is also what keeps an old file
at the target from becoming the first snapshot of an archive.

Checked against REBOUND 5.2.2 by experiment: ``rebound.Simulationarchive(path)`` raises
RuntimeError for a file that is not REBOUND's, ``archive[k]`` IndexError out of range; particle
fields and ``sim.t``/``sim.dt``/``sim.G`` are C doubles, so values round-trip bit for bit. REBOUND is
imported inside the functions: importing this module costs nothing.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from orbitsim.io import durable

__all__ = ["REBOUND_MAGIC", "ReboundFileError", "ReboundSnapshot", "is_rebound_file", "orbitsim_integrator",
           "read_rebound_file", "rebound_scheme_for", "write_rebound_file"]

#: Every REBOUND binary (and Simulationarchive) file starts with these bytes.
REBOUND_MAGIC = b"REBOUND Binary File"

#: REBOUND leapfrog order -> orbitsim's scheme of the same coefficients.
_LEAPFROG = {2: "leapfrog", 4: "leapfrog4", 6: "leapfrog6", 8: "leapfrog8"}
#: REBOUND WHFast coordinates -> orbitsim ``wisdom_holman`` coordinates (WHDS and barycentric have none).
_WH_COORDINATES = {"JACOBI": "jacobi", "DEMOCRATICHELIOCENTRIC": "democratic_heliocentric"}


class ReboundFileError(ValueError):
    """A REBOUND file that cannot be read or used; the message names the file and what is wrong.

    ``field`` is ``"snapshot"`` when the snapshot index was at fault, else ``"file"``.
    """

    def __init__(self, message: str, field: str = "file") -> None:
        super().__init__(message)
        self.field = field


@dataclass(frozen=True, eq=False)
class ReboundSnapshot:
    """One snapshot of a REBOUND file, as orbitsim needs it.

    ``radii`` is None when every particle's radius is 0; ``integrator`` is the orbitsim
    ``(name, settings)`` or None, with ``unmapped`` saying why (REBOUND's scheme has no counterpart).
    """

    path: str
    index: int
    count: int
    masses: np.ndarray
    positions: np.ndarray
    velocities: np.ndarray
    radii: np.ndarray | None
    G: float
    t: float
    dt: float
    softening: float
    rebound_integrator: str
    integrator: tuple[str, dict[str, Any]] | None
    unmapped: str = ""


def is_rebound_file(path: str | os.PathLike[str]) -> bool:
    """Whether ``path`` is a file that starts as REBOUND binaries do (reads 19 bytes, never raises)."""
    try:
        with open(path, "rb") as f:
            return f.read(len(REBOUND_MAGIC)) == REBOUND_MAGIC
    except OSError:
        return False


def read_rebound_file(path: str | os.PathLike[str], snapshot: int = -1) -> ReboundSnapshot:
    """Snapshot ``snapshot`` (Python indexing: -1 is the last) of a REBOUND file.

    Raises
    ------
    ReboundFileError
        Naming the file: missing, not a REBOUND file, a snapshot index out of range, or test
        particles with mass that orbitsim cannot represent.
    """
    import rebound  # noqa: PLC0415 -- lazy: loads rebound

    name = os.fspath(path)
    if not os.path.isfile(name):
        raise ReboundFileError(f"{name}: no such file" if not os.path.isdir(name) else f"{name}: is a directory")
    if not is_rebound_file(name):
        raise ReboundFileError(f"{name}: not a REBOUND simulation file (it does not start with {REBOUND_MAGIC!r})")
    try:
        with warnings.catch_warnings():  # a damaged tail: REBOUND warns and keeps the readable snapshots
            warnings.simplefilter("ignore", RuntimeWarning)
            archive = rebound.Simulationarchive(name)
    except (RuntimeError, ValueError, OSError) as err:
        raise ReboundFileError(f"{name}: cannot read the REBOUND file ({' '.join(str(err).split())})") from None
    count = len(archive)
    if isinstance(snapshot, bool) or not isinstance(snapshot, int | np.integer) or not -count <= snapshot < count:
        plural = "s" if count != 1 else ""
        raise ReboundFileError(f"{name}: snapshot {snapshot!r} is out of range: the file holds {count} "
                               f"snapshot{plural} (0 to {count - 1}, or -1 for the last)", "snapshot")
    index = int(snapshot) % count
    with warnings.catch_warnings():  # _synchronized handles this one; REBOUND's other warnings still show
        warnings.filterwarnings("ignore", message="The simulation might not be synchronized", category=RuntimeWarning)
        sim = archive[index]
    return _snapshot(_synchronized(sim, name, index), name, index, count)


def _synchronized(sim: Any, name: str, index: int) -> Any:
    """``sim`` with its particles synchronised as ``sim.synchronize()`` reports them.

    REBOUND's WHFast, SABA, MERCURIUS and EOS with ``safe_mode = 0`` combine the closing drift of a
    step with the opening drift of the next, so between steps (where a Simulationarchive saves its
    snapshots) the particles hold a drifted, uncorrected state and ``sim.is_synchronized`` is 0; the
    integrator's own coordinates in the file are what REBOUND continues from. REBOUND's
    ``synchronize`` applies the owed drift (and the inverse corrector) with REBOUND's own
    arithmetic; ``keep_unsynchronized = 1`` would keep ``is_synchronized`` 0 after it, so it is
    cleared first (the copy is this reader's own, never written back). Leapfrog, IAS15, TRACE, BS
    and JANUS are synchronised at every step and pass through untouched (same bits as saved).

    Raises
    ------
    ReboundFileError
        When REBOUND reports an error while synchronising or the snapshot is still not synchronised
        afterwards, naming the setting.
    """
    if sim.is_synchronized:
        return sim
    config = sim.integrator
    scheme = str(config)
    fields = {fd.name.decode() for fd in config.callbacks.field_descriptor_list}
    setting = f"REBOUND {scheme} with safe_mode = 0" if "safe_mode" in fields else f"REBOUND {scheme}"
    try:
        if "keep_unsynchronized" in fields:
            config.keep_unsynchronized = 0
        with warnings.catch_warnings():
            warnings.simplefilter("error", RuntimeWarning)  # REBOUND reports its problems as warnings too
            sim.synchronize()
    except (RuntimeError, RuntimeWarning, ValueError) as err:
        raise ReboundFileError(f"{name}: snapshot {index} was saved unsynchronised ({setting}) and REBOUND "
                               f"could not synchronise it ({' '.join(str(err).split())}); save it after "
                               "sim.synchronize() or with safe_mode = 1", "snapshot") from None
    if not sim.is_synchronized:
        raise ReboundFileError(f"{name}: snapshot {index} was saved unsynchronised ({setting}) and REBOUND's "
                               "synchronize() left it so; save it after sim.synchronize() or with safe_mode = 1",
                               "snapshot")
    return sim


def _snapshot(sim: Any, name: str, index: int, count: int) -> ReboundSnapshot:
    n = sim.N
    if n < 1:
        raise ReboundFileError(f"{name}: snapshot {index} holds no particles")
    m, x, v = np.zeros(n), np.zeros((n, 3)), np.zeros((n, 3))
    r = np.zeros(n)
    sim.serialize_particle_data(m=m, xyz=x, vxvyvz=v, r=r)
    active = sim.N_active
    if 0 <= active < n and (np.any(m[active:] != 0.0) and sim.testparticle_type == 0):
        # REBOUND ignores the forces of these particles; orbitsim has no such class of body.
        raise ReboundFileError(f"{name}: particles {active} to {n - 1} are test particles (N_active = {active}) "
                               "but have mass; orbitsim would let them pull: set their masses to 0")
    scheme = str(sim.integrator)  # the configuration object prints as the scheme's name
    try:
        mapped: tuple[str, dict[str, Any]] | None = orbitsim_integrator(sim)
        why = ""
    except ReboundFileError as err:
        mapped, why = None, str(err)
    return ReboundSnapshot(path=name, index=index, count=count, masses=m, positions=x, velocities=v,
                           radii=r if np.any(r != 0.0) else None, G=float(sim.G), t=float(sim.t), dt=float(sim.dt),
                           softening=float(sim.softening), rebound_integrator=scheme, integrator=mapped,
                           unmapped=why)


def orbitsim_integrator(sim: Any) -> tuple[str, dict[str, Any]]:
    """orbitsim's ``(integrator, settings)`` for the scheme ``sim`` is set to.

    leapfrog (order 2/4/6/8) -> leapfrog, leapfrog4/6/8; whfast -> wisdom_holman (Jacobi or
    democratic heliocentric coordinates, its corrector); ias15 -> ias15 (epsilon, min_dt; epsilon 0
    is a fixed step); trace -> trace (r_crit_hill, peri_crit_eta, peri_mode).

    Raises
    ------
    ReboundFileError
        Naming REBOUND's scheme, or the option of it, that orbitsim has no counterpart for.
    """
    config = sim.integrator
    name = str(config)  # `config.name` is bytes in REBOUND 5.2; str() is the name as text
    if name == "leapfrog":
        order = int(config.order)
        if order not in _LEAPFROG:
            raise ReboundFileError(f"REBOUND leapfrog of order {order} has no orbitsim counterpart (orders 2, 4, 6, 8)")
        return _LEAPFROG[order], {}
    if name == "whfast":
        return "wisdom_holman", _whfast_settings(config)
    if name == "ias15":
        epsilon, min_dt = float(config.epsilon), float(config.min_dt)
        settings: dict[str, Any] = {"epsilon": epsilon, "min_dt": min_dt}
        if epsilon == 0.0:  # REBOUND's fixed-step IAS15
            settings = {"adaptive": False}
        return "ias15", settings
    if name == "trace":
        return "trace", {"r_crit_hill": float(config.r_crit_hill), "peri_crit_eta": float(config.peri_crit_eta),
                         "peri_mode": str(config.peri_mode).lower()}
    raise ReboundFileError(f"REBOUND integrator {name!r} has no orbitsim counterpart (leapfrog, whfast, ias15 and "
                           "trace have one); choose one with `integrator:` (see `orbitsim list integrators`)")


def _whfast_settings(config: Any) -> dict[str, Any]:
    coordinates = str(config.coordinates).upper()
    if coordinates not in _WH_COORDINATES:
        raise ReboundFileError(f"REBOUND whfast coordinates {coordinates} have no orbitsim counterpart "
                               f"({', '.join(_WH_COORDINATES)} have one)")
    if int(config.corrector2) != 0 or str(config.kernel).upper() != "DEFAULT":
        raise ReboundFileError(f"REBOUND whfast with kernel {config.kernel} and corrector2 = {config.corrector2} has "
                               "no orbitsim counterpart (only the default kernel, without corrector2)")
    return {"coordinates": _WH_COORDINATES[coordinates], "corrector": int(config.corrector)}


def rebound_scheme_for(integrator: str, settings: dict[str, Any]) -> tuple[str | None, str]:
    """The bridge's REBOUND scheme text for an orbitsim integrator, and a note when there is none."""
    inverse = {v: k for k, v in _LEAPFROG.items()}
    if integrator in inverse:
        return f"leapfrog:{inverse[integrator]}", ""
    if integrator == "wisdom_holman":
        return "whfast", ""
    if integrator in ("ias15", "trace"):
        return integrator, ""
    return None, f"{integrator} has no REBOUND counterpart: the file keeps REBOUND's default integrator (ias15)"


def write_rebound_file(path: str | os.PathLike[str], masses: np.ndarray, positions: np.ndarray,
                       velocities: np.ndarray, *, G: float, t: float, dt: float, softening: float = 0.0,
                       radii: np.ndarray | None = None, integrator: str | None = None,
                       settings: dict[str, Any] | None = None) -> str:
    """Write one REBOUND snapshot of the state, atomically; returns a note ('' when none).

    The particles carry the exact bits of ``masses``, ``positions``, ``velocities`` (and ``radii``).
    The integrator is matched as :mod:`orbitsim.reference.bridge` matches a comparison run.

    Raises
    ------
    OutputWriteError
        When the file cannot be written; nothing is left at ``path`` but what was there before.
    """
    import rebound  # noqa: PLC0415 -- lazy: loads rebound

    from orbitsim.io.h5safe import io_failure  # noqa: PLC0415 -- lazy: loads h5py
    from orbitsim.reference.bridge import configure_scheme, parse_rebound_scheme  # noqa: PLC0415 -- lazy: off `orbitsim run`

    sim = rebound.Simulation()
    sim.G, sim.t, sim.softening = float(G), float(t), float(softening)
    r = np.zeros(len(masses)) if radii is None else radii
    for i in range(len(masses)):
        sim.add(m=float(masses[i]), x=float(positions[i, 0]), y=float(positions[i, 1]), z=float(positions[i, 2]),
                vx=float(velocities[i, 0]), vy=float(velocities[i, 1]), vz=float(velocities[i, 2]), r=float(r[i]))
    sim.dt = float(dt)
    scheme, note = rebound_scheme_for(integrator or "", settings or {})
    if scheme is not None:
        configure_scheme(sim, parse_rebound_scheme(scheme), settings)
        if integrator == "ias15":
            _ias15_settings(sim, settings or {})
    target = Path(path)
    tmp = target.with_name(f".{target.name}.tmp{os.getpid()}")
    try:
        tmp.unlink(missing_ok=True)  # save_to_file appends to an existing file
        sim.save_to_file(os.fspath(tmp))
        durable.replace_durably(tmp, target)  # looked up at the call: a test swaps it for a full disk
    except (OSError, RuntimeError) as err:
        tmp.unlink(missing_ok=True)
        raise io_failure(err, f"{target}: {{reason}} (nothing was written)", target) from None
    return note


def _ias15_settings(sim: Any, settings: dict[str, Any]) -> None:
    """orbitsim's IAS15 settings on REBOUND's: ``adaptive: false`` is REBOUND's ``epsilon = 0``."""
    sim.integrator.epsilon = 0.0 if settings.get("adaptive") is False else float(settings.get("epsilon", 1e-9))
    sim.integrator.min_dt = float(settings.get("min_dt", 0.0))
