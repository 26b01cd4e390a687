"""Run the recorded benchmark suite: the bundled matrix ``full`` into benchmarks/results.

    .venv/bin/python benchmarks/run_suite.py                  # one run (what `make bench` does)
    .venv/bin/python benchmarks/run_suite.py --runs 3 --quiet-load 1.0

With ``--runs K`` the matrix runs K times; every run is kept under ``results/runs/<k>/`` and the
last one is also written to ``results/`` (the recorded results). ``results/runs.md`` lists each
target's margin in every run, so the spread from run to run is in plain sight: on a shared
machine only ratios measured side by side within one run count, and this shows how stable they
are. ``--quiet-load L`` waits (up to ``--wait`` seconds) until the 1-minute load average is
below L before each run, so a run does not start in the middle of someone else's test suite.

The recorded run's tables are copied into benchmarks/README.md between the ``results:start`` and
``results:end`` markers, so the README always shows the recorded results file.
"""

from __future__ import annotations

import argparse
import os
import shutil
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "benchmarks" / "README.md"
MARKERS = ("<!-- results:start -->", "<!-- results:end -->")


def wait_for_quiet(limit: float | None, timeout: float) -> float:
    """Wait until the 1-minute load average is below ``limit``; returns the load at the start."""
    if limit is None or not hasattr(os, "getloadavg"):
        return os.getloadavg()[0] if hasattr(os, "getloadavg") else float("nan")
    deadline = time.monotonic() + timeout
    while os.getloadavg()[0] >= limit and time.monotonic() < deadline:
        print(f"load average {os.getloadavg()[0]:.2f} >= {limit}: waiting", file=sys.stderr)
        time.sleep(30)
    return os.getloadavg()[0]


def stability_table(docs: list[dict]) -> str:
    """Markdown: one row per target, one column per run (the margin, >= 1 means met)."""
    header = "| target | " + " | ".join(f"run {k + 1}" for k in range(len(docs))) + " |"
    lines = [header, "|---|" + "---|" * len(docs)]
    for row_index, row in enumerate(docs[0]["targets"]):
        cells = []
        for doc in docs:
            r = doc["targets"][row_index]
            cells.append("-" if r["margin"] is None else f"{r['measured_text']} ({r['margin']:.2f})")
        lines.append(f"| {row['target']} | " + " | ".join(cells) + " |")
    return "\n".join(lines) + "\n"


def update_readme(results_md: str, readme: Path = README) -> bool:
    """Replace the README's block between :data:`MARKERS` with the recorded tables; False if absent."""
    if not readme.exists():
        return False
    text = readme.read_text(encoding="utf-8")
    start, end = text.find(MARKERS[0]), text.find(MARKERS[1])
    if start < 0 or end < start:
        return False
    sections = results_md.split("\n## ")
    # The machine line, the targets, orbitsim beside REBOUND and the probes; the per-group case
    # tables stay in results/results.md.
    keep = [sections[0].split("\n", 2)[2]] + [sec for sec in sections[1:] if sec.startswith(
        ("Targets", "orbitsim beside", "Kernels"))]
    body = "\n### ".join(keep) + "\n\nEvery case, with min and max: [results/results.md](results/results.md).\n"
    readme.write_text(text[: start + len(MARKERS[0])] + "\n" + body.strip() + "\n" + text[end:], encoding="utf-8")
    return True


def main(argv: list[str] | None = None) -> int:
    """Run the suite; returns the process exit status."""
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--matrix", default="full", help="a matrix file or a bundled name")
    parser.add_argument("-o", "--outdir", default=str(ROOT / "benchmarks" / "results"))
    parser.add_argument("--runs", type=int, default=1)
    parser.add_argument("--threads", type=int, default=None)
    parser.add_argument("--quiet-load", type=float, default=None, help="start a run only below this load average")
    parser.add_argument("--wait", type=float, default=1800.0, help="longest wait for a quiet machine (s)")
    args = parser.parse_args(argv)

    from orbitsim.bench.matrix import load_matrix
    from orbitsim.bench.runner import run_matrix, write_results

    matrix = load_matrix(args.matrix)
    out = Path(args.outdir)
    docs = []
    for k in range(args.runs):
        load = wait_for_quiet(args.quiet_load, args.wait)
        print(f"run {k + 1}/{args.runs} (load average {load:.2f})", file=sys.stderr)
        doc = run_matrix(matrix, threads=args.threads, progress=lambda msg: print(msg, file=sys.stderr))
        docs.append(doc)
        if args.runs > 1:
            write_results(doc, out / "runs" / str(k + 1))
    write_results(docs[-1], out)
    if args.runs > 1:
        (out / "runs.md").write_text("# Targets in every run (margin >= 1: met)\n\n" + stability_table(docs),
                                     encoding="utf-8")
    else:  # drop stale runs of an earlier multi-run invocation
        shutil.rmtree(out / "runs", ignore_errors=True)
        (out / "runs.md").unlink(missing_ok=True)
    results_md = (out / "results.md").read_text(encoding="utf-8")
    if out.resolve() == (ROOT / "benchmarks" / "results").resolve() and update_readme(results_md):
        print(f"updated {README}", file=sys.stderr)
    print(results_md.split("## orbitsim beside")[0])
    return 0


if __name__ == "__main__":
    sys.exit(main())
