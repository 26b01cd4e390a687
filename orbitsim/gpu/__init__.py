"""orbitsim on one CUDA GPU, through numba-cuda (the optional extra ``pip install -e '.[gpu]'``).

Nothing here is imported by the CPU paths: the CLI loads this package only for ``--device gpu``, and the
test suite runs its kernels on Numba's CUDA simulator (``NUMBA_ENABLE_CUDASIM=1``) where no GPU exists.
Modules in this package import only numpy, numba and numba-cuda (and orbitsim modules that import only
those), so that the device checks in benchmarks/ run on a GPU machine's own python with the project on
``PYTHONPATH``.
"""
