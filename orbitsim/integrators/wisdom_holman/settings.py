"""Settings of the ``wisdom_holman`` integrator: the schema and its validation.

A scenario passes them as ``integrator: {name: wisdom_holman, coordinates: jacobi, corrector: 11}``;
the scenario loader checks them against the record's :data:`SETTINGS` / :func:`validate_settings`,
and :func:`orbitsim.integrators.wisdom_holman.make_work` validates them again (a direct API call
has no loader in front of it).
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from orbitsim.integrators.base import Setting

#: Corrector orders offered (Wisdom, Holman & Touma 1996; Rein & Tamayo 2015); 0 means none.
CORRECTOR_ORDERS = (0, 3, 5, 7, 11, 17)

#: Settings schema: key -> :class:`~orbitsim.integrators.base.Setting` (REBOUND's defaults).
SETTINGS: dict[str, Setting] = {
    "coordinates": Setting("jacobi", "the coordinates of the map, Jacobi or democratic heliocentric (also written "
                           "as REBOUND does, democraticheliocentric, or dh)", ("jacobi", "democratic_heliocentric")),
    "corrector": Setting(0, "order of the symplectic corrector applied at the start and at every output "
                         "(0: none; the correctors need jacobi coordinates)", CORRECTOR_ORDERS),
}

#: Coordinate name -> the id the jitted kernels dispatch on (see :mod:`.operators`).
COORDINATE_IDS = {"jacobi": 0, "democratic_heliocentric": 1}
#: Other spellings accepted for ``coordinates`` (REBOUND's enum name among them).
COORDINATE_ALIASES = {"democraticheliocentric": "democratic_heliocentric", "dh": "democratic_heliocentric"}


def validate_settings(settings: Mapping[str, Any] | None) -> dict[str, Any]:
    """Check the integrator settings of a scenario and fill in defaults.

    Parameters
    ----------
    settings : mapping or None
        ``coordinates`` (``"jacobi"`` or ``"democratic_heliocentric"``; case, ``-`` and REBOUND's
        ``democraticheliocentric`` spelling are accepted) and ``corrector`` (0, 3, 5, 7, 11 or
        17). A ``name`` key (the integrator name in the scenario mapping) is ignored.

    Returns
    -------
    dict
        ``{"coordinates": str, "corrector": int}``, defaults ``jacobi`` and 0.

    Raises
    ------
    ValueError
        Naming the offending key: an unknown key, a value outside a setting's choices, or a
        corrector with democratic heliocentric coordinates (the correctors need Jacobi
        coordinates, as in REBOUND).
    """
    given = dict(settings or {})
    given.pop("name", None)
    unknown = sorted(set(given) - set(SETTINGS))
    if unknown:
        raise ValueError(f"wisdom_holman setting {unknown[0]!r} is unknown; valid keys: {', '.join(SETTINGS)}")
    coordinates = given.get("coordinates", SETTINGS["coordinates"].default)
    if isinstance(coordinates, str):
        coordinates = coordinates.strip().lower().replace("-", "_").replace(" ", "_")
        coordinates = COORDINATE_ALIASES.get(coordinates, coordinates)
    if coordinates not in SETTINGS["coordinates"].choices:
        raise ValueError(
            f"wisdom_holman setting 'coordinates': {given.get('coordinates')!r} is not one of "
            + ", ".join(SETTINGS["coordinates"].choices)
        )
    corrector = given.get("corrector", SETTINGS["corrector"].default)
    is_integer = isinstance(corrector, int | np.integer) and not isinstance(corrector, bool)
    if not is_integer or corrector not in CORRECTOR_ORDERS:
        raise ValueError(
            f"wisdom_holman setting 'corrector': {corrector!r} is not one of "
            + ", ".join(str(p) for p in CORRECTOR_ORDERS)
        )
    if corrector != 0 and coordinates != "jacobi":
        raise ValueError(
            "wisdom_holman setting 'corrector': symplectic correctors need coordinates 'jacobi', "
            f"got corrector {corrector} with {coordinates!r}"
        )
    return {"coordinates": coordinates, "corrector": int(corrector)}
