"""The Jupiter-Saturn map, orbitsim beside REBOUND WHFast + MEGNO (Pool(2)), and the ensemble's ns/system-step.

Usage: ``.venv/bin/python benchmarks/map_speed.py [--n 20] [--years 1e4] [--figure FILE]``. It prints the
Markdown rows recorded in benchmarks/README.md (the measurements are :mod:`orbitsim.bench.ensemble`'s, the
same as ``orbitsim bench full --group ensemble``) and, with ``--figure``, draws REBOUND's MEGNO map beside
orbitsim's map of the same pixels.
"""

from __future__ import annotations

import argparse
import tempfile
from pathlib import Path

import numpy as np

from orbitsim.bench.ensemble import best_step_ns, orbitsim_map, rebound_map, side_by_side_step_ns


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--n", type=int, default=20)
    parser.add_argument("--years", type=float, default=1e4)
    parser.add_argument("--k", type=int, default=4096)
    parser.add_argument("--steps", type=int, default=2000)
    parser.add_argument("--indicator", default="megno")
    parser.add_argument("--figure", type=Path, default=None)
    args = parser.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(tmp)
        reb_s, megno = rebound_map(args.n, args.years)
        ours = orbitsim_map(args.n, args.years, out, args.indicator)
        if args.figure is not None:
            _figure(args.figure, megno, out / "timed" / "map.h5", args.indicator)
    ns = best_step_ns(side_by_side_step_ns(args.k, args.steps, rounds=1))
    print(f"| {args.n} x {args.n} map, {args.years:g} yr | REBOUND WHFast + MEGNO, Pool(2) | {reb_s:.2f} s |")
    print(f"| | orbitsim map ({args.indicator}), the map's computation (map.h5's wall_time_s) | "
          f"{ours.computation:.2f} s (kernels {ours.kernels:.2f} s; "
          f"REBOUND / orbitsim = {reb_s / ours.computation:.1f}) |")
    print(f"| | orbitsim map, readying the kernels before it (map.h5's setup_time_s) | {ours.setup:.2f} s |")
    print(f"| | orbitsim map ({args.indicator}), whole command, warm cache | {ours.whole:.2f} s "
          f"(REBOUND / orbitsim = {reb_s / ours.whole:.2f}) |")
    print(f"| K = {args.k} 4-body ensemble | ns per system-step | {ns['ensemble']:.0f} ns |")
    print(f"| one 4-body system | orbitsim wisdom_holman, 1 thread | {ns['single']:.0f} ns |")
    print(f"| one 4-body system | REBOUND WHFast | {ns['rebound']:.0f} ns |")


def _figure(path: Path, megno: np.ndarray, ours: Path, indicator: str) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from orbitsim.stability.driver import read_map

    data = read_map(ours)
    fig, axes = plt.subplots(1, 2, figsize=(12, 4.8), constrained_layout=True)
    extent = (5.8, 9.0, 0.0, 0.38)
    im = axes[0].imshow(np.clip(megno, 1.5, 8), origin="lower", extent=extent, aspect="auto", cmap="viridis")
    fig.colorbar(im, ax=axes[0], label="MEGNO (clipped to 1.5-8; white: escaped)")
    axes[0].set_title("REBOUND WHFast + init_megno")
    grid = np.where(data["status"] == 0, data["indicators"][indicator], np.nan)
    clipped = indicator == "megno"
    im = axes[1].imshow(np.clip(grid, 1.5, 8) if clipped else grid, origin="lower", extent=extent, aspect="auto",
                        cmap="viridis")
    fig.colorbar(im, ax=axes[1], label=f"orbitsim {indicator}{' (clipped to 1.5-8' if clipped else ' ('}"
                                       "; white: escaped)")
    axes[1].set_title("orbitsim map (ensemble, Wisdom-Holman tangent map)")
    for ax in axes:
        ax.set_xlabel("a [au]")
        ax.set_ylabel("e")
    fig.savefig(path, dpi=110)




if __name__ == "__main__":
    main()
