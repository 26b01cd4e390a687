"""Stability maps (``orbitsim map``): a grid over one or two parameters, each pixel a short run.

:mod:`.axes` parses the ``--x``/``--y`` specs, :mod:`.plan` checks the scenario and builds every
pixel's start state, :mod:`.driver` runs the chunks (here or on Dask) through
:mod:`orbitsim.ensemble`, :mod:`.store` keeps finished chunks and writes ``map.h5``, and
:mod:`.figure` draws ``map.png``.
"""
