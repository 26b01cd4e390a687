"""``run --from --integrator --dt`` under hard kills, end to end through real processes.

A leapfrog run finishes; ``orbitsim run --from first.h5 --integrator verlet --dt D2 -o second.h5
--checkpoint-every C`` continues it and is SIGKILLed twice (once in the first run, once in its
resume), each time after a checkpoint of its own past a chosen step, as ``test_checkpoint_kill.py``
does; ``orbitsim resume second.h5`` then finishes it. The finished trace must be the uninterrupted
continuation's, dataset for dataset and bit for bit, with the same ``integrator_history``: one
record of the switch from leapfrog to verlet at the first run's last step, not re-appended by a
resume.
"""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import h5py
import pytest
from test_checkpoint_kill import START_TIMEOUT, assert_same_datasets, orbitsim, run_and_kill

#: 64 bodies: the first run (leapfrog) is short; the continuation (verlet at half the step) takes
#: 600000 steps, a few seconds, so that both kills land mid-run on a machine of any speed.
FIRST = """\
name: switch_kill
integrator: leapfrog
dt: 0.001
steps: 2000
softening: 0.05
output: {every: 1000, positions: true}
generator: {kind: plummer, n: 64, seed: 5}
"""
K = 2000
DT2 = 0.0005
MORE = 600_000
TOTAL = K + MORE
CHECKPOINT_EVERY = 5000
#: Kill once a checkpoint past these steps is published (then 10 ms later): in the continuation, after
#: the switch, the second in the resumed process.
KILL_AT = (K + MORE // 4, K + (MORE * 3) // 5)
SWITCH = {"step": K, "time": 2.0, "t0": 1.0, "from": {"integrator": "leapfrog", "dt": 0.001},
          "to": {"integrator": "verlet", "dt": DT2}}


def cli(*args: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run(orbitsim(*args), capture_output=True, text=True, timeout=START_TIMEOUT)


def continuation(first: Path, out: Path) -> list[str]:
    return orbitsim("run", "--from", str(first), "--integrator", "verlet", "--dt", str(DT2), "--steps", str(MORE),
                    "-o", str(out), "--checkpoint-every", str(CHECKPOINT_EVERY), "-q")


def killed_state(out: Path) -> tuple[int, str]:
    """Steps done at the checkpoint a kill left (``info`` must call it resumable), and info's text."""
    info = cli("info", str(out))
    assert info.returncode == 0 and "resumable            yes" in info.stdout, info.stdout + info.stderr
    return int(info.stdout.split("steps_done")[1].split()[0]), info.stdout


@pytest.fixture(scope="module")
def runs(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path]:
    """The finished leapfrog run and its uninterrupted continuation (which also warms Numba's cache)."""
    folder = tmp_path_factory.mktemp("switch_kill")
    scenario = folder / "first.yaml"
    scenario.write_text(FIRST, encoding="utf-8")
    first = folder / "first.h5"
    done = cli("run", str(scenario), "-o", str(first), "-q")
    assert done.returncode == 0, done.stderr
    reference = folder / "reference.h5"
    done = subprocess.run(continuation(first, reference), capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    with h5py.File(reference, "r") as f:
        assert f.attrs["status"] == "complete" and int(f.attrs["steps_done"]) == TOTAL
    return first, reference


@pytest.mark.slow  # kills a continuation that switched schemes (~11 s)
def test_a_switched_continuation_survives_sigkill_and_resumes_bit_for_bit(runs: tuple[Path, Path],
                                                                          tmp_path: Path) -> None:
    first, reference = runs
    before = first.read_bytes()
    out = tmp_path / "second.h5"
    command = continuation(first, out)
    steps_at_kill = []
    for at in KILL_AT:
        code = run_and_kill(command, Path(f"{out}.ckpt"), at, 0.01)
        assert code is None, "the continuation finished before it was killed: make it longer"
        assert not out.exists()  # a killed run leaves no trace at the output path
        done, shown = killed_state(out)
        assert at <= done < TOTAL  # after the switch, short of the end: there is something to resume
        assert "integrator           verlet" in shown
        assert "history:  1 change of scheme or dt (run --from)" in shown  # info on the killed run shows it
        assert "step 2000 (t = 2): leapfrog (dt = 0.001) -> verlet (dt = 0.0005)" in shown
        with h5py.File(f"{out}.ckpt", "r") as f:  # the switch is in the state the resume starts from
            assert json.loads(f.attrs["history"]) == [SWITCH]
        steps_at_kill.append(done)
        command = orbitsim("resume", str(out), "-q")
    assert steps_at_kill[0] < steps_at_kill[1]

    # The run's own integrator is now verlet: resuming it as the leapfrog run it came from is refused.
    refused = cli("resume", str(out), "--integrator", "leapfrog", "-q")
    assert refused.returncode == 2 and refused.stderr.count("\n") == 1, refused.stderr
    assert refused.stderr.startswith("orbitsim: error: ") and killed_state(out)[0] == steps_at_kill[1]

    final = subprocess.run(command, capture_output=True, text=True, timeout=300)
    assert final.returncode == 0, final.stderr
    assert_same_datasets(reference, out)
    with h5py.File(reference, "r") as f, h5py.File(out, "r") as g:
        history = json.loads(g.attrs["integrator_history"])
        assert history == json.loads(f.attrs["integrator_history"]) == [SWITCH]
        assert g["checkpoint"].attrs["history"] == f["checkpoint"].attrs["history"]
        assert g["checkpoint"].attrs["resumes"] == 2 and f["checkpoint"].attrs["resumes"] == 0
        # Every attribute of the trace but the wall time is the uninterrupted run's.
        theirs = {k: v for k, v in f.attrs.items() if k != "wall_time_s"}
        ours = {k: v for k, v in g.attrs.items() if k != "wall_time_s"}
        assert sorted(ours) == sorted(theirs)
        assert [k for k in ours if str(ours[k]) != str(theirs[k])] == []
        assert (g.attrs["status"], g.attrs["integrator"], g.attrs["dt"], int(g.attrs["steps_done"])) == (
            "complete", "verlet", DT2, TOTAL)
    assert first.read_bytes() == before  # -o: the run it continued is left as it was
    assert sorted(p.name for p in tmp_path.iterdir()) == ["second.h5"]  # no checkpoint, journal or lock left
