"""Forces beyond Newtonian point masses, from the scenario's ``forces:`` list.

General relativity (``gr_potential``, ``gr``, ``gr_full``), a body's zonal harmonics
(``harmonics``: J2, J4) and orbit migration and damping (``migration``), each matched against
REBOUNDx. :mod:`.table` holds a run's forces as arrays (what the scenario resolved to);
:mod:`.terms` turns them into one record per force, the form the kernels read; :mod:`.kernels`
walks the records; :mod:`.hooks` is where every integrator's own loop meets them. A run without
forces imports only :mod:`.hooks` (Numba overloads that compile to nothing for it) and compiles
nothing here.
"""
