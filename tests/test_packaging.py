"""orbitsim as a user installs it: the imports that an editable install hides.

An editable install runs from the source tree through a finder that itself imports
``importlib.util``, and a test run imports half the package before any one module is used: a
module that reaches a submodule it never imported (``importlib.util`` after ``import importlib``)
works there and crashes in a wheel. These tests find such uses.
"""

from __future__ import annotations

import ast
import json
import subprocess
import sys
from pathlib import Path

import orbitsim

PACKAGE = Path(orbitsim.__file__).resolve().parent
REPO = PACKAGE.parent


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
