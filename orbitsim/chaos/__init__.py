"""Chaos indicators: MEGNO and the mean exponential growth of nearby orbits (mLCE, the Lyapunov exponent).

:mod:`.megno` holds the indicators' running sums, computed as REBOUND computes them; the variational
(tangent) state they read is integrated by each integrator family beside its own step, with the tangent
gravity of :mod:`orbitsim.physics.tangent`.
"""
