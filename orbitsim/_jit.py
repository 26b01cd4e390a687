"""The one place that sets orbitsim's Numba policy.

Every jitted function in orbitsim is decorated with :func:`jit` (exact IEEE arithmetic) or
:func:`jit_force` (the force sum only, where reassociation is allowed). The choices, and why:

* ``cache=True``: a CLI lives or dies by the on-disk cache. A cold compile costs 0.3-1.5 s per
  function; a warm cache loads one in ~0.01 s.
* The cache directory is keyed by the package version and a hash of the package's own source
  (:data:`CACHE_DIR`). Numba's cache index only watches the file that holds the cached function, so
  a caller in one module keeps running a stale copy of a callee edited in another module. Keying
  the directory by the hash of every source file means an edited tree never loads stale machine
  code. ``orbitsim cache clear`` removes old directories. A ``NUMBA_CACHE_DIR`` the user set is
  where the generations go (:func:`cache_root`), never a flat cache of its own.
* ``fastmath``: off everywhere except :func:`jit_force`, which allows only ``reassoc`` and
  ``contract`` (no ``nsz``/``arcp``/``afn``) so LLVM can vectorise the inner j-sum of the force
  loop (4.5x measured) and fuse its multiply-adds. Its cost was a relative change of ~4e-15 in
  the accelerations. The flags live on each instruction, so they stay confined to the force sum
  even where a force kernel is inlined into a step. The integrators' own arithmetic
  (kicks, drifts, coefficient products) stays exact, with no contraction into FMAs, so orbitsim
  and REBOUND can agree step for step.
* ``error_model="numpy"``: division by zero gives inf/nan instead of raising, which lets the
  kernels skip Python's zero checks; non-finite states are caught by the divergence check.
* ``nogil=True``: lets callers run kernels from threads (Dask workers, progress bars).
* ``no_cfunc_wrapper=True``: no C-callable wrapper beside each function. Numba builds one for
  first-class function values (a jitted function passed as a ``types.FunctionType``), which
  orbitsim never uses; each cost a first run compile time (0.6-0.7 CPU-s of ``mercury_gr``'s).
* Overloads go through :func:`overload_inline` (the same flags, inlined by LLVM, see there).
* Inlining: :func:`jit_inline` inlines Numba's IR at each call site (typed there again);
  :func:`jit_llvm_inline` compiles once and lets LLVM inline the machine code, far cheaper to compile
  for a long function (see there).
* ``boundscheck=False`` (the default) in production; tests may run with ``NUMBA_DISABLE_JIT=1``.
* :func:`wide_vectors`: 512-bit vectors in the lane loops that ask for them.
* :func:`stop_requested`: the flag the O(N^2) kernels look at between row blocks, so that a stop
  (Ctrl-C, SIGTERM) reaches a kernel that runs for minutes (see its docstring).

Never build two dispatchers from one Python function with different flags while ``cache=True``:
they would share one cache entry.
"""

from __future__ import annotations

import ctypes
import hashlib
import os
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any, TypeVar

from orbitsim._version import __version__

F = TypeVar("F", bound=Callable[..., Any])

_PACKAGE_DIR = Path(__file__).resolve().parent


#: The parts of the package that hold jitted code, or objects that jitted code reaches; their source
#: keys the cache directory. The conventions test (test_conventions.py) computes that set from the
#: source and fails when a module is missing here.
_KERNEL_SOURCES = ("_jit.py", "physics", "integrators", "events", "forces", "chaos", "ensemble", "gpu",
                   "bench/ceiling.py", "bench/kernels.py")


def _source_hash() -> str:
    """Hash of every kernel source file: changes whenever any jitted function's source does."""
    digest = hashlib.sha256()
    paths = []
    for part in _KERNEL_SOURCES:
        target = _PACKAGE_DIR / part
        paths.extend([target] if target.is_file() else target.rglob("*.py"))
    for path in sorted(paths):
        digest.update(path.relative_to(_PACKAGE_DIR).as_posix().encode())
        digest.update(path.read_bytes())
    return digest.hexdigest()[:16]


def cache_root() -> tuple[Path, str]:
    """Directory that holds every orbitsim cache generation, and what chose it.

    ``$ORBITSIM_CACHE_DIR``; else ``$NUMBA_CACHE_DIR/orbitsim``: Numba's own setting is honoured as
    the place, with orbitsim's generations inside it (a flat Numba cache would keep running a
    callee's old machine code after an upgrade, see the module docstring); else
    ``$XDG_CACHE_HOME/orbitsim/numba`` (``~/.cache`` without XDG_CACHE_HOME).
    """
    env = os.environ.get("ORBITSIM_CACHE_DIR")
    if env:
        return Path(env), "ORBITSIM_CACHE_DIR"
    numba_dir = os.environ.get("NUMBA_CACHE_DIR")
    if numba_dir:
        return Path(numba_dir) / "orbitsim", "NUMBA_CACHE_DIR"
    xdg = os.environ.get("XDG_CACHE_HOME")
    return Path(xdg or str(Path.home() / ".cache")) / "orbitsim" / "numba", "XDG_CACHE_HOME" if xdg else "default"


#: Where the cache generations are, and the variable that said so (``cache_root``).
CACHE_ROOT, CACHE_ROOT_FROM = cache_root()
CACHE_DIR = CACHE_ROOT / f"{__version__}-{_source_hash()}"

# Must be set before numba reads its configuration, and before any function is decorated. The root
# is exported too, so that a child process (a Dask worker) finds the same generation rather than
# reading this NUMBA_CACHE_DIR as a user's and nesting another one inside it.
os.environ["ORBITSIM_CACHE_DIR"] = str(CACHE_ROOT)
os.environ["NUMBA_CACHE_DIR"] = str(CACHE_DIR)

import numba  # noqa: E402
from llvmlite import binding as _llvm_binding  # noqa: E402
from llvmlite import ir  # noqa: E402
from numba.core import event  # noqa: E402
from numba.extending import intrinsic, overload  # noqa: E402

if numba.config.CACHE_DIR != os.environ["NUMBA_CACHE_DIR"]:
    numba.config.CACHE_DIR = os.environ["NUMBA_CACHE_DIR"]

_COMMON: dict[str, Any] = {"cache": True, "nogil": True, "error_model": "numpy", "no_cfunc_wrapper": True,
                           "forceinline": False}

#: Flags allowed in the force sum only: reassociation vectorises the j-reduction, contraction
#: fuses its multiply-adds (7% more pairs/s at N = 2048-8192, 12% less per 5-body evaluation).
FORCE_FASTMATH = frozenset({"reassoc", "contract"})


def jit(func: F) -> F:
    """Compile ``func`` with exact IEEE arithmetic (no fastmath), cached on disk."""
    return numba.njit(fastmath=False, **_COMMON)(func)


def jit_inline(func: F) -> F:
    """As :func:`jit`, and inlined into every jitted caller at Numba's IR level.

    For the thin layers of a step (kick, drift, one step, the force dispatch): unless a function is
    :func:`jit_llvm_inline`, LLVM does not inline one jitted function into another, and each call
    passes every array as a struct and adjusts its reference count. At N = 5 those calls were 40 ns
    of a 120 ns verlet step (measured, benchmarks/README.md). Never for a force loop: inlined into a
    caller it stopped vectorising.
    """
    return numba.njit(fastmath=False, inline="always", **_COMMON)(func)


def jit_llvm_inline(func: F) -> F:
    """As :func:`jit`, and inlined into every jitted caller by LLVM (Numba's ``forceinline``: LLVM's
    ``alwaysinline``), not by Numba.

    :func:`jit_inline` copies the function's Numba IR into each call site, after running Numba's untyped
    passes on it again there, and the copy is typed again in the caller: for a long function (a whole
    operator of the lane kernels, itself made of inlined helpers) that work grows faster than the code, and
    one kernel holding every operator of a step took 61 of a first map's 82 CPU-s to compile. Here the
    function is typed and compiled once per signature, and LLVM puts its optimised code into each caller,
    so the machine code runs as if it were inlined. A literal argument is part of the signature, so each
    distinct constant compiles once more (as each call site would be typed once more by
    :func:`jit_inline`). ``forceinline`` is set explicitly everywhere else (:data:`_COMMON`): unset, a
    function compiled from within a ``forceinline`` one would inherit it.
    """
    return numba.njit(fastmath=False, **{**_COMMON, "forceinline": True})(func)


#: The flags of :func:`jit` for an overload's implementation (Numba's overloads default to no CPython
#: wrapper, a flag that :func:`jit` functions do not set: see :func:`overload_inline`).
_OVERLOAD_OPTIONS: dict[str, Any] = {key: _COMMON[key] for key in ("nogil", "error_model", "no_cfunc_wrapper")}
_OVERLOAD_OPTIONS["no_cpython_wrapper"] = False


def overload_inline(func: Callable[..., Any]) -> Callable[[F], F]:
    """``numba.extending.overload(func)``, its implementations compiled with the flags of :func:`jit` and
    inlined into their callers by LLVM (``forceinline``, as :func:`jit_llvm_inline`).

    Numba compiles an overload's implementation on its own once per argument types *and* the flags of
    the compilation that asked, whether it is inlined or not. With ``inline="always"`` (before) the
    caller then also copied the implementation's IR into each call site and typed it again there
    (Numba's ``inline_overloads`` pass), work that grows with the force walk's nesting: a first
    ``j2_satellite`` run 15.1 -> 13.9 CPU-s, ``mercury_gr_planets`` 15.6 -> 14.9, with the same bits and
    the same speed, now that LLVM inlines the compiled code instead. Overloads default to other flags
    than :func:`jit` (no CPython wrapper, ``nogil=False``, ``error_model="python"``), so an overload asked
    for from inside another overload's compilation (the force walk's nested records) missed the one asked
    for by a :func:`jit` function and was compiled again: each force overload twice in a first
    ``mercury_gr`` run. With :func:`jit`'s flags the two requests are one.
    """
    return overload(func, jit_options={**_OVERLOAD_OPTIONS, "forceinline": True})


def jit_force(func: F) -> F:
    """Compile a force-sum kernel: reassociation (the inner loop vectorises) and contraction."""
    return numba.njit(fastmath=set(FORCE_FASTMATH), **_COMMON)(func)


def jit_parallel(func: F) -> F:
    """Compile a ``prange`` kernel with reassociation in its force sum; results stay deterministic
    because every reduction is done in fixed-size blocks combined in a fixed order."""
    return numba.njit(fastmath=set(FORCE_FASTMATH), parallel=True, **_COMMON)(func)


def jit_parallel_exact(func: F) -> F:
    """Compile a ``prange`` kernel with exact arithmetic (element-wise updates, diagnostics)."""
    return numba.njit(fastmath=False, parallel=True, **_COMMON)(func)


def set_num_threads(n: int | None) -> int:
    """Set the number of Numba threads (``None`` keeps ``NUMBA_NUM_THREADS``); returns the count."""
    if n is not None:
        if n < 1 or n > numba.config.NUMBA_NUM_THREADS:
            raise ValueError(
                f"threads must be between 1 and {numba.config.NUMBA_NUM_THREADS} (NUMBA_NUM_THREADS), got {n}"
            )
        numba.set_num_threads(n)
    return int(numba.get_num_threads())


def launch_threads() -> int:
    """Start Numba's threading layer (once per process; later calls do nothing); returns the thread count.

    Machine code of a ``prange`` kernel loaded from the on-disk cache calls the layer's scheduler
    (``allocate_sched``), a symbol the loader resolves only once the layer has started. Compiling a
    parallel kernel starts it; loading one from the cache does not, and a process whose first parallel
    call is a cached kernel aborts with "LLVM ERROR: Symbol not found: allocate_sched". This module calls
    it once when it is imported, before any kernel of the package can be loaded (see below); the front
    doors to ``prange`` kernels still call it (or :func:`set_num_threads`, which does), which costs nothing.
    """
    return int(numba.get_num_threads())


# The layer starts here, when the package's first kernel module is imported, not at each front door: a
# plain @jit function that calls a prange kernel (gravity.accelerations, diagnostics.potential_energy)
# and was compiled in a process that loaded that kernel from the cache (its first compile killed between
# the two functions, or the kernel called on its own first) is cached with the layer's symbols in it, and
# a process that loads it before the layer starts dies of SIGSEGV (numba #8578), whichever Python caller
# reached it (tests/test_threading_layer.py). About 8 ms once per process; GNU OpenMP's pool is then up,
# which matters only to a fork()ed child that runs a prange kernel (orbitsim forks none: Dask spawns).
launch_threads()


# -- the kernels' stop flag --------------------------------------------------------------------------

#: The C symbol of :data:`_STOP_FLAG`, by which compiled code finds it.
_STOP_SYMBOL = "orbitsim_stop_kernels"
#: Non-zero while the kernels are asked to stop (:func:`stop_kernels`). A C int, not a numpy array:
#: Numba bakes a global array's contents into the machine code as constants, so a kernel would
#: never see it change; this int lives at a fixed address that the compiled code loads from.
_STOP_FLAG = ctypes.c_int32(0)
# Registered before any kernel that reads it is compiled or loaded from the on-disk cache: cached
# machine code names the symbol, and the loader resolves it in every new process from this table.
_llvm_binding.add_symbol(_STOP_SYMBOL, ctypes.addressof(_STOP_FLAG))


def stop_requested() -> bool:
    """True while the kernels are asked to stop (:func:`stop_kernels`).

    Jitted code calls it between row blocks of the O(N^2) loops (the force sum, the potential),
    where it is one atomic load of a C int through :func:`_load_stop_flag`: about a nanosecond per
    two rows of N pairs. A kernel that sees it returns early, leaving its output incomplete; the
    caller (:func:`orbitsim.stopping.run_interruptible`) throws the call's results away. Called
    from Python (and with ``NUMBA_DISABLE_JIT=1``) it reads the same flag.
    """
    return _STOP_FLAG.value != 0


#: Counts every raising and every lowering of the flag (odd while it is up): a kernel call made
#: where no stop is handled (another thread) compares it before and after, and redoes a call that a
#: stop meant for the main thread's run may have cut short (:func:`orbitsim.stopping.run_interruptible`).
_stop_sequence = 0


def stop_kernels(stop: bool) -> None:
    """Ask every running kernel of this process to stop (``True``), or let kernels run again (``False``)."""
    global _stop_sequence
    if stop and not _STOP_FLAG.value:
        _stop_sequence += 1
        _STOP_FLAG.value = 1
    elif not stop and _STOP_FLAG.value:
        _STOP_FLAG.value = 0
        _stop_sequence += 1


def stop_sequence() -> int:
    """How often the flag went up or down so far; odd while it is up (see :data:`_stop_sequence`)."""
    return _stop_sequence


@intrinsic
def _load_stop_flag(typingctx):
    """The flag as a boolean, by a monotonic atomic load: the compiler may neither keep the value
    in a register across a loop nor drop the load (a plain load of a value the loop never writes
    could be hoisted out of it, and the kernel would never see the flag change)."""
    def codegen(context, builder, signature, args):
        flag = builder.module.globals.get(_STOP_SYMBOL)
        if flag is None:
            flag = ir.GlobalVariable(builder.module, ir.IntType(32), _STOP_SYMBOL)
            flag.linkage = "external"
        value = builder.load_atomic(flag, "monotonic", 4)
        return builder.icmp_unsigned("!=", value, ir.Constant(ir.IntType(32), 0))

    return numba.types.boolean(), codegen


@overload_inline(stop_requested)
def _stop_requested_jitted():
    return lambda: _load_stop_flag()


# -- vector width -------------------------------------------------------------------------------------

def wide_vectors() -> None:
    """Called first in a jitted function: LLVM vectorises it with the CPU's widest registers (512 bits with
    AVX-512; for Intel's AVX-512 CPUs it otherwise prefers 256). Does nothing called from Python.

    For the ensemble's lane loops: each lane's arithmetic is the same IEEE operations at any register
    width (no fastmath), so the bits stay; the Jupiter-Saturn map's kernel took 0.71 s against 0.81 s on
    one thread of an Emerald Rapids Xeon (benchmarks/README.md). LLVM vectorises a function compiled on its
    own (:func:`jit`, :func:`jit_llvm_inline`) before inlining it, so each such lane function calls this
    itself; a :func:`jit_inline` one takes its caller's width. No effect without AVX-512.
    """


@intrinsic
def _prefer_wide_vectors(typingctx):
    """clang's ``-mprefer-vector-width=512`` on the function being lowered (the caller of :func:`wide_vectors`,
    into which Numba inlines it). llvmlite checks only keyword attributes; a ``"key"="value"`` one goes in
    past that check and is written as it is."""
    def codegen(context, builder, signature, args):
        set.add(builder.function.attributes, '"prefer-vector-width"="512"')
        return context.get_dummy_value()

    return numba.types.none(), codegen


@overload(wide_vectors, inline="always", jit_options=_OVERLOAD_OPTIONS)
def _wide_vectors_jitted():
    return lambda: _prefer_wide_vectors()


# -- what a run compiles -----------------------------------------------------------------------------

class CompileWatch:
    """The compilations Numba makes while it is installed (:func:`watch_compiles`).

    Numba announces a ``numba:compile`` event only for a function it actually compiles, not for one
    it loads from the on-disk cache, so a warm run sees none. :attr:`seconds` is the wall time of
    the outermost compilations (a callee compiled inside its caller's compilation is not counted
    twice), :attr:`count` how many functions were compiled, and ``on_first`` is called once, when
    the first compilation starts (a cold run's "compiling kernels" line, printed before the wait).
    """

    def __init__(self, on_first: Callable[[], None] | None = None) -> None:
        self.on_first = on_first
        self.seconds = 0.0
        self.count = 0
        self._depth = 0
        self._started = 0.0

    def on_start(self, _event: Any) -> None:
        if self.count == 0 and self.on_first is not None:
            self.on_first()
        self.count += 1
        if self._depth == 0:
            self._started = time.perf_counter()
        self._depth += 1

    def on_end(self, _event: Any) -> None:
        self._depth -= 1
        if self._depth == 0:
            self.seconds += time.perf_counter() - self._started


def watch_compiles(watch: CompileWatch) -> Any:
    """A context manager under which ``watch`` sees every Numba compilation (Numba compiles under
    one global lock, so the count is exact whichever thread compiles)."""

    class _Listener(event.Listener):
        def on_start(self, ev: Any) -> None:
            watch.on_start(ev)

        def on_end(self, ev: Any) -> None:
            watch.on_end(ev)

    return event.install_listener("numba:compile", _Listener())


# -- CUDA (numba-cuda), for orbitsim.gpu only ---------------------------------------------------------
# numba-cuda is imported inside these decorators, never here at module level: the CPU paths must not
# load it. Callers have passed orbitsim.gpu.device.require_cuda() first (the one gate, and numpy's
# row_stack shim). CUDA kernels compile on their first launch and are cached on disk beside the CPU's
# (CACHE_DIR; numba-cuda keys each entry by signature, closure values and compute capability).


def cuda_kernel(func: F) -> F:
    """Compile ``func`` as a CUDA kernel, fastmath off. The GPU compiler still contracts a * b + c into
    fused multiply-adds, so results are not the CPU's bits (docs/gpu.md; maps: docs/map.md, "On a GPU")."""
    from numba import cuda  # noqa: PLC0415 - lazy: loads numba-cuda, only for the GPU

    return cuda.jit(fastmath=False, cache=True)(func)


def cuda_device(func: F) -> F:
    """Compile ``func`` as a CUDA device function, inlined into its callers (NVVM's ``alwaysinline``
    on hardware; the simulator calls it as Python)."""
    from numba import cuda  # noqa: PLC0415 - lazy: loads numba-cuda, only for the GPU

    if "simulator" in cuda.jit.__module__:  # Numba's CUDA simulator: its jit has no forceinline
        return cuda.jit(device=True)(func)
    return cuda.jit(device=True, forceinline=True, fastmath=False)(func)
