"""A disk that really fills up: a 2 MiB tmpfs the test mounts in a private mount namespace.

``unshare --user --map-root-user --mount`` gives an unprivileged process its own mount table, in
which it may mount a tmpfs; the mount vanishes with the process. Where the kernel does not allow
that (user namespaces disabled), the tests are skipped, and tests/io/test_write_faults.py still
covers the same promises with injected ENOSPC. Before these fixes, the run below ended in a
segfault inside libhdf5 (exit code 139) with 37 tracebacks and a 2 MiB ``.tmp`` left behind,
and under ``orbitsim batch`` it killed the workers and no summary was written.
"""

from __future__ import annotations

import csv
import shlex
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

SCENARIO = """\
name: filler
units: nbody
integrator: verlet
dt: 0.01
steps: 10
bodies:
  - {name: star, m: 1.0, x: [0, 0, 0], v: [0, 0, 0]}
  - {name: planet, m: 1.0e-3, primary: star, a: 1.0, e: 0.0, M: 0}
"""
#: A run that passes the free-space check at its start (its estimate is well under 2 MiB) and goes on
#: writing for a while, so that the disk can fill under it: samples are written in blocks of 1024.
LONG = ["--steps", "3000000", "--every", "300", "--no-positions"]
OLD = b"an older file at the output path\n"
#: Shell: fill what is left of the disk, as another program would.
FILL_DISK = "dd if=/dev/zero of=small/ballast bs=4096 2>/dev/null"


def _namespaces_work() -> bool:
    if shutil.which("unshare") is None or not sys.platform.startswith("linux"):
        return False
    probe = subprocess.run(["unshare", "-rm", "sh", "-c", "d=$(mktemp -d) && mount -t tmpfs -o size=1m tmpfs $d"],
                           capture_output=True, timeout=60)
    return probe.returncode == 0


pytestmark = pytest.mark.skipif(not _namespaces_work(), reason="cannot mount a private tmpfs (user namespaces off)")


def in_namespace(tmp_path: Path, script: str) -> None:
    """Run the shell ``script`` in ``tmp_path`` with ``small`` a fresh 2 MiB tmpfs holding ``t.h5``
    (an older file), ``$ORBITSIM`` the command, and ``filler.yaml`` a tiny scenario. ``report N``
    in the script saves the last exit code as ``rcN.txt``, the files of ``small`` as ``lsN.txt``
    and whether ``small/t.h5`` is still the older file as ``sameN.txt``."""
    (tmp_path / "small").mkdir()
    (tmp_path / "old.txt").write_bytes(OLD)
    (tmp_path / "filler.yaml").write_text(SCENARIO, encoding="utf-8")
    prologue = f"""
ORBITSIM={shlex.quote(shlex.join([sys.executable, "-m", "orbitsim"]))}
report() {{ echo $? > rc$1.txt; ls -A small | grep -v '^ballast$' > ls$1.txt
           cmp -s small/t.h5 old.txt; echo $? > same$1.txt; }}
wait_for() {{ for _ in $(seq 6000); do [ -e "$1" ] && return 0; sleep 0.01; done; return 1; }}
mount -t tmpfs -o size=2m tmpfs small
cp old.txt small/t.h5
"""
    subprocess.run(["unshare", "-rm", "sh", "-c", prologue + script], cwd=tmp_path, check=True, timeout=600)


def reported(tmp_path: Path, n: int) -> tuple[int, list[str], bool]:
    """Exit code, files in ``small`` (ballast left out) and whether the older file is intact, after ``report n``."""
    return (int((tmp_path / f"rc{n}.txt").read_text()), (tmp_path / f"ls{n}.txt").read_text().split(),
            (tmp_path / f"same{n}.txt").read_text().strip() == "0")


def one_line(path: Path) -> str:
    text = path.read_text()
    assert text.count("\n") == 1 and text.startswith("orbitsim: error: "), text
    return text


def test_a_full_disk_ends_the_run_in_one_line_and_leaves_the_old_file(tmp_path: Path) -> None:
    in_namespace(tmp_path, f"""
$ORBITSIM run filler.yaml -o small/t.h5 --force {shlex.join(LONG)} 2> err.txt & RUN=$!
wait_for small/t.h5.tmp && {FILL_DISK}
wait $RUN; report 0
""")
    rc, files, intact = reported(tmp_path, 0)
    line = one_line(tmp_path / "err.txt")
    assert rc == 4, line
    assert line.startswith("orbitsim: error: small/t.h5: No space left on device while writing small/t.h5.tmp")
    assert "small/t.h5 is unchanged" in line and "nothing is left behind" in line
    assert files == ["t.h5"] and intact  # no .tmp, no lock file


def test_a_checkpointed_run_on_a_full_disk_resumes_once_there_is_room(tmp_path: Path) -> None:
    in_namespace(tmp_path, f"""
$ORBITSIM run filler.yaml -o small/t.h5 --force {shlex.join(LONG)} --checkpoint-every 5000 2> err.txt & RUN=$!
wait_for small/t.h5.ckpt && {FILL_DISK}
wait $RUN; report 0
rm small/ballast
$ORBITSIM resume small/t.h5 -q 2> err1.txt; report 1
$ORBITSIM run filler.yaml -o ref.h5 {shlex.join(LONG)} -q
""")
    rc, files, intact = reported(tmp_path, 0)
    line = one_line(tmp_path / "err.txt")
    assert rc == 4 and "No space left on device" in line, line
    assert "can be resumed from its checkpoint" in line and "`orbitsim resume small/t.h5`" in line
    assert files == ["t.h5", "t.h5.ckpt", "t.h5.journal"] and intact
    rc, files, intact = reported(tmp_path, 1)
    assert rc == 0, (tmp_path / "err1.txt").read_text()
    assert files == ["t.h5"] and not intact  # the finished trace replaced the older file; side files gone


def test_a_sweep_records_the_full_disk_goes_on_and_a_rerun_finishes_it(tmp_path: Path) -> None:
    """The disk fills during the third of five cases (one worker runs them in order): that row says
    why, the sweep goes on and writes its summary, and once there is room again a rerun completes it."""
    (tmp_path / "sweep.yaml").write_text(
        "name: fill\nbase: filler.yaml\ngrid:\n  steps: [200, 300, 3000000, 400, 500]\n"
        "overrides: {output: {every: 300, positions: false}}\n", encoding="utf-8")
    in_namespace(tmp_path, f"""
$ORBITSIM batch sweep.yaml -o small/sweep --workers 1 --no-progress > out0.txt 2> err0.txt & RUN=$!
for _ in $(seq 12000); do
    [ "$(ls small/sweep/runs 2>/dev/null | grep -c 'h5$')" = 2 ] && TMP=$(ls small/sweep/runs | grep tmp) && break
    sleep 0.005
done
{FILL_DISK}
while [ -e "small/sweep/runs/$TMP" ]; do sleep 0.005; done; rm small/ballast
wait $RUN; report 0
cp small/sweep/summary.csv first.csv
$ORBITSIM batch sweep.yaml -o small/sweep --workers 1 --no-progress > out1.txt 2> err1.txt; report 1
cp small/sweep/summary.csv second.csv
""")
    rc, _, _ = reported(tmp_path, 0)
    assert rc == 1, (tmp_path / "err0.txt").read_text()  # a run failed; the sweep itself finished
    assert (tmp_path / "err0.txt").read_text().splitlines()[-1].startswith("orbitsim: error: ")
    with open(tmp_path / "first.csv", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    assert [row["status"] for row in rows[:3]] == ["complete", "complete", "failed"]
    assert "No space left on device" in rows[2]["error"] and rows[2]["trace"] == ""
    for row in rows[3:]:  # started at once, before the disk was freed, or after: either is reported
        assert row["status"] == "complete" or "free" in row["error"] or "No space left" in row["error"], row
    rc, _, _ = reported(tmp_path, 1)
    assert rc == 0, (tmp_path / "err1.txt").read_text()
    with open(tmp_path / "second.csv", encoding="utf-8") as fh:
        again = list(csv.DictReader(fh))
    assert [row["status"] for row in again] == ["complete"] * 5
    assert [row["resumed"] for row in again[:2]] == ["true", "true"]


def test_a_read_only_directory_is_one_line_naming_it(tmp_path: Path) -> None:
    """Not the raw HDF5 text, and no mention of a checkpoint nobody asked for (``x.h5.ckpt``)."""
    in_namespace(tmp_path, """
mount -o remount,ro small
$ORBITSIM run filler.yaml -o small/x.h5 2> err0.txt; report 0
$ORBITSIM run filler.yaml -o small/t.h5 --force --checkpoint-every 5 2> err1.txt; report 1
""")
    for n in (0, 1):
        rc, files, intact = reported(tmp_path, n)
        line = one_line(tmp_path / f"err{n}.txt")
        assert rc == 2 and line.endswith("cannot write in small: Read-only file system\n"), line
        assert ".ckpt" not in line and files == ["t.h5"] and intact
