"""``orbitsim bench``: run a benchmark matrix against REBOUND and write results and figures."""

from __future__ import annotations

import click

from orbitsim.cli.errors import fail, reports_errors
from orbitsim.cli.options import threads_option

#: The bundled matrices run without MATRIX (orbitsim/data/bench/, see orbitsim.data).
FULL_MATRIX = "full"
QUICK_MATRIX = "quick"


@click.command("bench")
@click.argument("matrix", required=False, type=click.Path(dir_okay=False), metavar="[MATRIX]")
@click.option("--quick", is_flag=True,
              help="Without MATRIX: run the bundled `quick` matrix (under a minute). With MATRIX: at most "
                   "3 repeats, a tenth of the work, no long trace run. Example: --quick")
@click.option("-o", "--outdir", type=click.Path(file_okay=False), default="benchmarks/results",
              show_default=True, help="Directory for results.json, results.md and the figures. "
                                      "Example: -o out/bench")
@click.option("--group", "groups", multiple=True, metavar="NAME",
              help="Run only this group of the matrix (repeatable). Example: --group trace")
@threads_option(free_cores_default=False)
@click.option("--no-plots", is_flag=True, help="Skip the figures. Example: --no-plots")
@click.option("-q", "--quiet", is_flag=True, help="No progress lines; errors only. Example: -q")
@reports_errors
def command(matrix: str | None, quick: bool, outdir: str, groups: tuple[str, ...], threads: int | None,
            no_plots: bool, quiet: bool) -> None:
    """Benchmark orbitsim against REBOUND, side by side in one run.

    Runs every group of MATRIX (a matrix file or a bundled name, `orbitsim list matrices`;
    default: the bundled `full`, the recorded benchmarks) and writes OUTDIR/results.json
    (machine, versions, thread count, every case with median/min/max and JIT time apart),
    OUTDIR/results.md (the targets table first) and figures (throughput against N with the
    measured hardware ceiling; small-N time per step per integrator). Ratios against REBOUND
    come from cases measured interleaved, so they hold on a busy machine; absolute times do not.

    \b
    Examples:
      orbitsim bench --quick -o out/bench
      orbitsim bench full -o benchmarks/results --threads 2
      orbitsim bench --group trace -o benchmarks/results/trace --no-plots
      orbitsim bench my_matrix.yaml -o out/mine
    """
    from orbitsim.bench.matrix import BenchMatrixError, load_matrix
    from orbitsim.data import MATRICES, bundled_dir

    try:
        loaded = load_matrix(matrix or bundled_dir(MATRICES) / f"{QUICK_MATRIX if quick else FULL_MATRIX}.yaml")
        if groups:
            loaded = loaded.select(groups)
    except BenchMatrixError as err:
        fail(str(err))
    from orbitsim.bench.runner import run_matrix, write_results

    try:
        doc = run_matrix(loaded, threads=threads, quick=quick and matrix is not None,
                         progress=None if quiet else (lambda msg: click.echo(msg, err=True)))
    except ValueError as err:  # a thread count above NUMBA_NUM_THREADS
        fail(str(err))
    files = write_results(doc, outdir, plots=not no_plots)
    if not quiet:
        from orbitsim.bench.report import targets_table

        click.echo(targets_table(doc))
        click.echo(f"wrote {', '.join(str(f) for f in files)}")
