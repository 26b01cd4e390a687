"""SIMD across systems, measured: the Jacobi interaction kick for K systems of N bodies, laid out
[K][3][N] (one system at a time, the ensemble kernel's layout, calling the single-system operator) vs
[3][N][K] (the system index innermost, every loop over k, so LLVM can put 4 systems in one AVX2 register)."""
import math
import time

import numba
import numpy as np

from orbitsim._jit import jit
from orbitsim.integrators.wisdom_holman.operators import interaction_kick


@jit
def kick_per_system(jpos, jvel, m, weights, mu, ipos, iacc, reps):
    """System by system, its views taken once and all its kicks in a row, as the ensemble kernel steps."""
    for k in range(jpos.shape[0]):
        p, v, mk, w, u, ip, ia = jpos[k], jvel[k], m[k], weights[k], mu[k], ipos[k], iacc[k]
        for _ in range(reps):
            interaction_kick(p, v, mk, 1.0, 0.0, 1e-9, None, w, u, ip, ia, None)

@jit
def kick_lanes(jpos, jvel, m, weights, mu, ipos, acc, reps):
    """The same arithmetic, in the same order per system, with k innermost."""
    n = jpos.shape[1]
    K = jpos.shape[2]
    h = 1e-9
    for _ in range(reps):
        for c in range(3):
            for k in range(K):
                ipos[c, 0, k] = jpos[c, 0, k]
            for i in range(n - 1, 0, -1):
                for k in range(K):
                    rel = jpos[c, i, k]
                    com = ipos[c, 0, k] - weights[i, k] * rel
                    ipos[c, 0, k] = com
                    ipos[c, i, k] = rel + com
        for c in range(3):
            for i in range(n):
                for k in range(K):
                    acc[c, i, k] = 0.0
        for i in range(n):
            start = 2 if i == 0 else i + 1
            for j in range(start, n):
                for k in range(K):
                    dx = ipos[0, j, k] - ipos[0, i, k]
                    dy = ipos[1, j, k] - ipos[1, i, k]
                    dz = ipos[2, j, k] - ipos[2, i, k]
                    r2 = dx * dx + dy * dy + dz * dz
                    g_r3 = 1.0 / (r2 * math.sqrt(r2))
                    mj = m[j, k] * g_r3
                    mi = m[i, k] * g_r3
                    acc[0, i, k] += mj * dx
                    acc[1, i, k] += mj * dy
                    acc[2, i, k] += mj * dz
                    acc[0, j, k] -= mi * dx
                    acc[1, j, k] -= mi * dy
                    acc[2, j, k] -= mi * dz
        for c in range(3):
            for k in range(K):
                ipos[c, 0, k] = acc[c, 0, k]  # com accumulator
            for i in range(1, n):
                for k in range(K):
                    rel = acc[c, i, k] - ipos[c, 0, k]
                    acc[c, i, k] = rel
                    ipos[c, 0, k] = ipos[c, 0, k] + weights[i, k] * rel
        for i in range(1, n):
            for k in range(K):
                ax, ay, az = acc[0, i, k], acc[1, i, k], acc[2, i, k]
                if i > 1:
                    x, y, z = jpos[0, i, k], jpos[1, i, k], jpos[2, i, k]
                    r2 = x * x + y * y + z * z
                    kk = mu[i, k] / (r2 * math.sqrt(r2))
                    ax += kk * x
                    ay += kk * y
                    az += kk * z
                jvel[0, i, k] += h * ax
                jvel[1, i, k] += h * ay
                jvel[2, i, k] += h * az

def main() -> None:
    numba.set_num_threads(1)
    k_systems, n, reps = 4096, 4, 200
    rng = np.random.default_rng(1)
    m = np.tile(np.array([1.0, 1e-3, 3e-4, 0.0]), (k_systems, 1))
    interior = np.cumsum(m, axis=1)
    weights = m / interior
    weights[:, 0] = 1.0
    mu = interior.copy()
    jpos = rng.normal(size=(k_systems, 3, n)) * 5
    jvel = rng.normal(size=(k_systems, 3, n)) * 0.3
    per_system = [jpos.copy(), jvel.copy(), m, weights, mu, np.zeros((k_systems, 3, n)), np.zeros((k_systems, 3, n))]
    lanes = [np.ascontiguousarray(jpos.transpose(1, 2, 0)), np.ascontiguousarray(jvel.transpose(1, 2, 0)),
             np.ascontiguousarray(m.T), np.ascontiguousarray(weights.T), np.ascontiguousarray(mu.T),
             np.zeros((3, n, k_systems)), np.zeros((3, n, k_systems))]
    kick_per_system(*per_system, 1)
    kick_lanes(*lanes, 1)
    assert np.array_equal(per_system[1], lanes[1].transpose(2, 0, 1))  # the same bits per system
    for _ in range(3):  # interleaved rounds: both layouts see the same load
        started = time.perf_counter()
        kick_per_system(*per_system, reps)
        t_per_system = time.perf_counter() - started
        started = time.perf_counter()
        kick_lanes(*lanes, reps)
        t_lanes = time.perf_counter() - started
        print(f"kick, N = {n}, K = {k_systems}, 1 thread: [K][3][N] {t_per_system / (k_systems * reps) * 1e9:.1f} "
              f"ns/system, [3][N][K] {t_lanes / (k_systems * reps) * 1e9:.1f} ns/system, "
              f"ratio {t_per_system / t_lanes:.2f}")


if __name__ == "__main__":
    main()
