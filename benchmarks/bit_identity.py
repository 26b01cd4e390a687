"""Hash every dataset of a fixed set of runs, so a refactor can prove it changed no bits.

    python benchmarks/bit_identity.py -o hashes.json            # take the hashes
    python benchmarks/bit_identity.py --against hashes.json     # compare, exit 1 on any change

The runs: every bundled scenario (capped at :data:`MAX_STEPS` steps or output intervals, with its
own integrator, sampling and forces), and every registered integrator on a small planetary
system three ways: plain, with every kind of event watched (collisions merge, encounters,
escapes, unresolved steps), and with each force it can apply (gr_potential, gr, harmonics,
migration). Each run's trace is read back and every dataset hashed (SHA-256 of its bytes; text by
its items); attributes that record the machine or the clock (wall time, threads, provenance) are
left out, everything else is in. Same input, same bits: two runs of the same tree give the same
file, whatever the thread count.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import tempfile
from pathlib import Path
from typing import Any

import h5py
import numpy as np

from orbitsim.integrators.registry import INTEGRATORS
from orbitsim.runner import run_scenario
from orbitsim.scenario import ScenarioError, bundled_scenarios, load_scenario, scenario_from_dict

#: Bundled scenarios are cut to this many steps (output intervals for an adaptive scheme), and those
#: of more than :data:`LARGE_N` bodies to :data:`LARGE_STEPS` (a 16,384-body step takes ~0.1 s).
MAX_STEPS = 3000
LARGE_N = 100
LARGE_STEPS = 10

#: Attributes that depend on the machine, the clock or the process, not on the arithmetic.
VOLATILE = ("wall_time", "threads", "provenance", "created", "host", "pid", "python", "numba", "numpy", "version",
            "started", "finished", "elapsed", "resumes", "command", "source", "threads_choice", "written_at")

PLANETS = [
    {"name": "star", "m": 1.0, "x": [0, 0, 0], "v": [0, 0, 0], "r": 0.005},
    {"name": "b", "m": 1e-3, "primary": "star", "a": 1.0, "e": 0.05, "inc": 1.0, "M": 10, "r": 0.0005},
    {"name": "c", "m": 5e-4, "primary": "star", "a": 1.6, "e": 0.1, "inc": 2.0, "M": 200, "r": 0.0005},
    {"name": "d", "m": 2e-4, "primary": "star", "a": 2.5, "e": 0.2, "inc": 0.5, "M": 300, "r": 0.0004},
]

EVENTS = {"collisions": {"detect": "line", "resolve": "merge"}, "encounters": {"hill": 1.0},
          "escape": {"distance": 50.0, "action": "remove"}, "unresolved": {"eta": 0.05}}

FORCES = {
    "gr_potential": [{"force": "gr_potential", "source": "star", "c": 100.0}],
    "gr": [{"force": "gr", "source": "star", "c": 100.0}],
    "harmonics": [{"force": "harmonics", "body": "star", "J2": 1e-3, "R_eq": 0.01}],
    "migration": [{"force": "migration", "bodies": {"d": {"tau_a": -2e4, "tau_e": -2e3}}}],
}


def _hash(arr: np.ndarray) -> str:
    if arr.dtype == object or arr.dtype.kind in "SU":
        data = "\x00".join(str(x) for x in np.ravel(arr)).encode()
    else:
        data = np.ascontiguousarray(arr).tobytes() + str(arr.dtype).encode() + str(arr.shape).encode()
    return hashlib.sha256(data).hexdigest()[:24]


def trace_hashes(path: Path) -> dict[str, str]:
    """Every dataset's hash, and every non-volatile attribute, of one trace."""
    found: dict[str, str] = {}

    def visit(name: str, obj: Any) -> None:
        if isinstance(obj, h5py.Dataset):
            found[name] = _hash(obj[()])
        for key, value in obj.attrs.items():
            if not any(word in key for word in VOLATILE):
                found[f"{name}@{key}"] = _hash(np.asarray(value))

    with h5py.File(path, "r") as f:
        for key, value in f.attrs.items():
            if not any(word in key for word in VOLATILE):
                found[f"@{key}"] = _hash(np.asarray(value))
        f.visititems(visit)
    return found


def _small(spec: Any, extra: dict[str, Any]) -> dict[str, Any]:
    timing = ({"t_end": 1.2, "output": {"interval": 0.1, "elements": True}} if spec.adaptive
              else {"steps": 600, "output": {"every": 50, "elements": True}})
    doc: dict[str, Any] = {"name": f"bits_{spec.name}", "units": "au-yr-msun", "integrator": spec.name,
                           "dt": 0.002, **timing, "bodies": PLANETS}
    doc.update(extra)
    return doc


def cases() -> dict[str, Any]:
    """name -> a Scenario to run."""
    found: dict[str, Any] = {}
    for name in bundled_scenarios():
        sc = load_scenario(name)
        cap = MAX_STEPS if sc.n_bodies <= LARGE_N else LARGE_STEPS
        if sc.steps > cap:
            if sc.adaptive:
                sc = sc.with_overrides(t_end=sc.t_start + cap * sc.interval)
            else:
                sc = sc.with_overrides(steps=cap, every=max(1, cap // 10))
        found[f"bundled/{name}"] = sc
    for spec in INTEGRATORS:
        found[f"plain/{spec.name}"] = scenario_from_dict(_small(spec, {}))
        found[f"events/{spec.name}"] = scenario_from_dict(_small(spec, {"events": EVENTS}))
        for force, entries in FORCES.items():
            try:
                found[f"forces/{force}/{spec.name}"] = scenario_from_dict(_small(spec, {"forces": entries}))
            except ScenarioError as err:  # the scheme cannot apply this force: validate refuses it
                if "cannot" not in str(err) and "only" not in str(err):
                    raise
                continue
    return found


def take(selected: list[str] | None = None) -> dict[str, dict[str, str]]:
    result: dict[str, dict[str, str]] = {}
    with tempfile.TemporaryDirectory() as folder:
        for name, sc in cases().items():
            if selected and not any(name.startswith(s) for s in selected):
                continue
            out = Path(folder) / (name.replace("/", "_") + ".h5")
            summary = run_scenario(sc, out, handle_signals=False)
            result[name] = {"status": summary.status, **trace_hashes(out)}
            print(f"{name:<45} {summary.status:<10} {len(result[name]) - 1} entries", file=sys.stderr)
    return result


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("-o", "--output", type=Path, help="write the hashes here (JSON)")
    parser.add_argument("--against", type=Path, help="compare with hashes taken before")
    parser.add_argument("--only", nargs="*", help="run only the cases whose names start with these")
    args = parser.parse_args()
    now = take(args.only)
    if args.output:
        args.output.write_text(json.dumps(now, indent=1, sort_keys=True))
    if args.against:
        before = json.loads(args.against.read_text())
        changed = []
        # a run the baseline has no hashes for (a scenario bundled since) is new, not changed: it is listed
        new = sorted(set(now) - set(before))
        for name in sorted(set(before) | set(now)):
            if (args.only and name not in now) or name in new:
                continue
            a, b = before.get(name), now.get(name)
            if a != b:
                keys = sorted(k for k in set(a or {}) | set(b or {}) if (a or {}).get(k) != (b or {}).get(k))
                changed.append(f"{name}: {', '.join(keys[:8])}" + (" ..." if len(keys) > 8 else ""))
        total = sum(len(v) - 1 for name, v in now.items() if name not in new)
        if new:
            print(f"new since the baseline (no hashes to compare): {', '.join(new)}")
        if changed:
            print(f"{len(changed)} of {len(now) - len(new)} runs changed:\n  " + "\n  ".join(changed))
            return 1
        print(f"bit-identical: {len(now) - len(new)} runs, {total} hashes")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
