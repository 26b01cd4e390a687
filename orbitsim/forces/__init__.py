"""Forces beyond Newtonian point masses, from the scenario's ``forces:`` list.

General relativity (``gr_potential``, ``gr``, ``gr_full``), a body's zonal harmonics
(``harmonics``: J2, J4) and orbit migration and damping (``migration``), each matched against
REBOUNDx. :mod:`.table` holds the arrays the kernels read; :mod:`.stepping` the forced loops.
A run without forces imports only :mod:`.hooks` (Numba overloads that compile to nothing for it)
and compiles nothing here.
"""
