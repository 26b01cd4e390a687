"""The REBOUND bridge: orbitsim scenarios run in REBOUND with matched settings.

* :mod:`~orbitsim.reference.bridge`: ``rebound_simulation`` (scenario inputs -> a configured
  ``rebound.Simulation``) and the REBOUND scheme names (``leapfrog:4``, ``whfast``, ``ias15`` ...);
* :mod:`~orbitsim.reference.sampling`: REBOUND runs sampled at orbitsim's step indices, and the
  IAS15 reference landing exactly on the same times;
* :mod:`~orbitsim.reference.pairs`: the matched-pairs table and its tolerances, with the reasons.

REBOUND itself is imported only inside functions, so importing this package is cheap.
"""
