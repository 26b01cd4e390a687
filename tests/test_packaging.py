"""orbitsim as a user installs it: a wheel in a fresh venv outside the checkout, and the imports that
an editable install hides.

An editable install runs from the source tree through a finder that itself imports
``importlib.util``, and a test run imports half the package before any one module is used: a
module that reaches a submodule it never imported (``importlib.util`` after ``import importlib``)
works there and crashes in a wheel. The first test finds such uses statically; the slow one builds
the wheel and runs the commands a new user types first.
"""

from __future__ import annotations

import ast
import json
import os
import shutil
import subprocess
import sys
import venv
import zipfile
from importlib import metadata
from pathlib import Path

import pytest

import orbitsim

PACKAGE = Path(orbitsim.__file__).resolve().parent
REPO = PACKAGE.parent
#: The builds that decide a run's bits: compared between the wheel's venv and this one.
VERSIONED = ("numpy", "numba", "llvmlite")


def _dotted(node: ast.expr) -> list[str] | None:
    """``a.b.c`` as ["a", "b", "c"] when the chain starts at a plain name, else None."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    if not isinstance(node, ast.Name):
        return None
    return [node.id, *reversed(parts)]


def submodule_uses(source: str) -> dict[tuple[str, str], int]:
    """Attribute chains that may reach a submodule the module never imported.

    Returns ``{(parent, attribute): line}`` for each ``parent.attribute`` read through a name bound
    by ``import parent`` (or ``import parent as p``) where ``parent.attribute`` is not imported
    anywhere in the module; whether it is a submodule that ``import parent`` leaves unloaded is
    for :func:`unloaded_submodules` to say.
    """
    tree = ast.parse(source)
    bound: dict[str, str] = {}  # a name in the module -> the module it is bound to
    loaded: set[str] = set()  # every module the file imports, with each parent package
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                parts = alias.name.split(".")
                loaded.update(".".join(parts[:k]) for k in range(1, len(parts) + 1))
                if alias.asname:
                    bound[alias.asname] = alias.name
                else:
                    bound.setdefault(parts[0], parts[0])
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            parts = node.module.split(".")
            loaded.update(".".join(parts[:k]) for k in range(1, len(parts) + 1))
            loaded.update(f"{node.module}.{alias.name}" for alias in node.names)  # from a import b: a.b too
    found: dict[tuple[str, str], int] = {}
    for node in ast.walk(tree):
        chain = _dotted(node) if isinstance(node, ast.Attribute) else None
        if not chain or chain[0] not in bound:
            continue
        module = bound[chain[0]]
        for attr in chain[1:]:
            if f"{module}.{attr}" not in loaded:
                found.setdefault((module, attr), node.lineno)
                break
            module = f"{module}.{attr}"
    return found


def unloaded_submodules(parent: str, attrs: list[str]) -> list[str]:
    """Those of ``attrs`` that are submodules of ``parent`` and absent after a bare ``import parent``.

    Asked of a fresh interpreter started with ``-S`` (no ``site``, so no ``.pth`` file and no
    editable finder imports anything first), with this interpreter's ``sys.path``.
    """
    code = (f"import sys; sys.path[:] = {sys.path!r}\n"
            f"import {parent} as m\n"
            f"missing = [a for a in {attrs!r} if not hasattr(m, a)]\n"  # before anything else is imported
            "import importlib.util, json\n"
            f"print(json.dumps([a for a in missing if importlib.util.find_spec('{parent}.' + a) is not None]))\n")
    done = subprocess.run([sys.executable, "-S", "-c", code], capture_output=True, text=True, timeout=120,
                          check=False)
    assert done.returncode == 0, done.stderr[-2000:]
    return json.loads(done.stdout)


def hidden_imports(sources: dict[str, str]) -> list[str]:
    """``where: a.b without `import a.b``` for every submodule ``a.b`` that the sources (name ->
    text) reach through a bare ``import a`` although ``import a`` does not load it."""
    uses: dict[str, dict[str, str]] = {}
    for name, text in sources.items():
        for (parent, attr), line in submodule_uses(text).items():
            uses.setdefault(parent, {}).setdefault(attr, f"{name}:{line}")
    return [f"{attrs[attr]}: {parent}.{attr} without `import {parent}.{attr}`"
            for parent, attrs in sorted(uses.items()) for attr in unloaded_submodules(parent, sorted(attrs))]


def test_the_detector_finds_a_submodule_never_imported() -> None:
    """The crash this file guards against, as it was in orbitsim/cli/main.py, and its fix."""
    broken = "import importlib\n\ndef f(m):\n    return importlib.util.find_spec(m)\n"
    assert hidden_imports({"main.py": broken}) == ["main.py:4: importlib.util without `import importlib.util`"]
    fixed = "import importlib\nimport importlib.util\n" + broken.split("\n", 1)[1]
    assert hidden_imports({"main.py": fixed}) == []
    assert hidden_imports({"a.py": "import numpy as np\nnp.linalg.norm\nimport os\nos.path.join\n"}) == []


def test_no_module_uses_a_submodule_it_did_not_import() -> None:
    """Every ``a.b`` in the package, with ``a`` imported bare, is loaded by ``import a`` itself."""
    sources = {path.relative_to(REPO).as_posix(): path.read_text(encoding="utf-8")
               for path in sorted(PACKAGE.rglob("*.py"))}
    assert "orbitsim/cli/main.py" in sources
    bad = hidden_imports(sources)
    assert not bad, "\n".join(bad)


def _copy_source(target: Path) -> Path:
    """What the wheel is built from (pyproject.toml, README.md, the package), without caches, so
    the build leaves nothing in the checkout."""
    target.mkdir()
    for name in ("pyproject.toml", "README.md"):
        shutil.copy2(REPO / name, target / name)
    shutil.copytree(PACKAGE, target / "orbitsim", ignore=shutil.ignore_patterns("__pycache__", "*.pyc", "*.nb[ic]"))
    return target


def _run(args: list[str], timeout: float, **kwargs: object) -> subprocess.CompletedProcess[str]:
    done = subprocess.run(args, capture_output=True, text=True, timeout=timeout, check=False, **kwargs)
    assert done.returncode == 0, f"{' '.join(map(str, args))}\n{done.stdout[-3000:]}\n{done.stderr[-3000:]}"
    return done


@pytest.mark.slow
@pytest.mark.timeout(1800)
def test_the_wheel_runs_outside_the_checkout(tmp_path: Path) -> None:
    """Build the wheel, install it with its declared dependencies (and nothing else: REBOUNDx is not
    one) into a fresh venv, and from a folder outside the checkout run a bundled scenario by name
    and the demo: the bundled files ship in the wheel and the CLI needs nothing the tree gave it."""
    source = _copy_source(tmp_path / "source")
    dist = tmp_path / "dist"
    _run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--quiet", "-w", str(dist), str(source)], 600)
    [wheel] = dist.glob("orbitsim-*.whl")
    with zipfile.ZipFile(wheel) as archive:
        shipped = {name for name in archive.namelist() if name.startswith("orbitsim/data/")}
    bundled = {path.relative_to(REPO).as_posix() for path in (PACKAGE / "data").rglob("*.yaml")}
    assert bundled and bundled <= shipped, f"not in the wheel: {sorted(bundled - shipped)}"

    env_dir = tmp_path / "venv"
    venv.EnvBuilder(with_pip=True).create(env_dir)
    python, orbitsim_cmd = env_dir / "bin" / "python", env_dir / "bin" / "orbitsim"
    # Plain pip: the wheel's own dependencies come from the index (or pip's cache), as for a user.
    _run([str(python), "-m", "pip", "install", "--quiet", str(wheel)], 1200)

    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir()
    # A private Numba cache (the wheel's kernels compile from an empty cache, as a user's first run
    # does) and nothing that points back into the checkout.
    env = {k: v for k, v in os.environ.items()
           if not k.startswith(("VIRTUAL_ENV", "PYTHONPATH", "ORBITSIM_", "NUMBA_CACHE_DIR"))}
    env["XDG_CACHE_HOME"] = str(tmp_path / "cache")
    probe = ("import importlib.metadata as m, importlib.util as u, json, orbitsim; print(json.dumps(["
             "orbitsim.__file__, u.find_spec('reboundx') is not None, [m.version(p) for p in VERSIONED]]))")
    where, has_reboundx, versions = json.loads(_run([str(python), "-c", f"VERSIONED = {VERSIONED!r}; {probe}"],
                                                     120, cwd=elsewhere, env=env).stdout)
    assert Path(where).is_relative_to(env_dir) and not has_reboundx, (where, has_reboundx)

    ran = _run([str(orbitsim_cmd), "run", "two_body_eccentric", "-o", "ecc.h5"], 900, cwd=elsewhere, env=env)
    listed = _run([str(orbitsim_cmd), "list", "sweeps"], 120, cwd=elsewhere, env=env).stdout
    assert all(name in listed for name in ("integrators_dt", "plummer_seeds", "eccentricity_cases")), listed

    demo = _run([str(orbitsim_cmd), "demo", "-o", "demo-report"], 900, cwd=elsewhere, env=env)
    assert demo.stdout.strip().splitlines()[-1] == f"report: {elsewhere / 'demo-report' / 'report.html'}"
    summary = json.loads((elsewhere / "demo-report" / "summary.json").read_text(encoding="utf-8"))
    errors = {s["integrator"]: s["max_abs_energy_error"] for s in summary["schemes"]}
    assert summary["scenario"]["name"] == "lesson" and list(errors) == ["euler", "semi_implicit_euler", "verlet"]
    assert errors["euler"] > errors["semi_implicit_euler"] > errors["verlet"] > 0  # the lesson's point

    # The checkout's own run of that scenario: the same summary line; with the same numpy, numba and
    # llvmlite in both venvs, the same bits (another LLVM may vectorise the force sum differently).
    import h5py

    reference = tmp_path / "ref.h5"
    mine = _run([sys.executable, "-m", "orbitsim", "run", "two_body_eccentric", "-o", str(reference)], 900)
    assert "complete, 62832 of 62832 steps" in ran.stdout
    assert _physics(ran.stdout) == _physics(mine.stdout), (ran.stdout, mine.stdout)
    if versions == [metadata.version(p) for p in VERSIONED]:
        with h5py.File(elsewhere / "ecc.h5") as got, h5py.File(reference) as want:
            for name in ("time", "energy", "positions", "velocities"):
                assert got[name][()].tobytes() == want[name][()].tobytes(), name


def _physics(run_line: str) -> str:
    """The run line without its timing and output name: steps, max |dE/E|, samples, end time."""
    line = run_line.strip().splitlines()[-1]
    return line.split(" in ")[0] + " " + line.split("), ")[1].split(" -> ")[0]
