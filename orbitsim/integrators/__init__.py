"""orbitsim's integrators, one record each (:class:`~orbitsim.integrators.base.Integrator`).

* :mod:`.base`: the record every scheme declares (every hook the engine calls, with defaults; one
  settings shape) and the jitted pieces the schemes share;
* :mod:`.registry`: the one ordered list of schemes and the name/alias lookup, importing only the
  scheme asked for;
* one module per scheme: :mod:`.euler`, :mod:`.semi_implicit_euler`, :mod:`.verlet`, :mod:`.rk4`;
  :mod:`.leapfrog` holds REBOUND's one leapfrog, orders 2/4/6/8 from one table (registered as
  ``leapfrog``, ``leapfrog4``, ``leapfrog6``, ``leapfrog8``);
* one package per family, its ``__init__`` the scheme: :mod:`.wisdom_holman`, :mod:`.ias15`,
  :mod:`.trace`;
* :mod:`.rebound_names`: REBOUND's names for the same schemes.
"""
