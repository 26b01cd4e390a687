"""The documentation cites only what exists, and the README's layout is the tree's.

Read, each with the line it is on:

* the Markdown documents (``README.md``, ``docs/*.md``, ``benchmarks/README.md``), whole;
* in the package, the tests and the benchmark scripts, what is prose: docstrings, comments and
  ``help=`` texts (code strings are left alone: a string there that looks like a path is often an
  HDF5 group's name).

What counts as a citation, and what it must resolve to:

* a repository path, its first folder one of ``orbitsim``, ``tests``, ``benchmarks``, ``docs`` and
  ``configs`` (globs and ``{a,b}`` alternatives expand; a ``...`` ends the path at its folder): a file
  or folder of the checkout;
* a package-relative module path such as ``physics/gravity.py`` (its first folder one of the
  package's): a file under ``orbitsim/``, or beside the citing file;
* a bare capitalised Markdown name (``README.md``; the design notes' old name was one): a file at
  the root, or beside the citing file;
* a ``path.md#anchor`` citation, and every Markdown link ``[text](target#anchor)``: the file, and a
  heading of it whose GitHub anchor is ``anchor``;
* a Sphinx role naming the package (``:func:`` and the like, then a dotted name under ``orbitsim``):
  a module of the package, and a name that module defines.

The README's "How it is built" block is checked against the tree as it is when the test runs:
every file and folder it names exists (a name in an entry's description is looked up in that
entry's folder), and every package folder of ``orbitsim/`` is there, a subpackage at least in its
parent's description.
"""

from __future__ import annotations

import ast
import io
import re
import tokenize
from collections.abc import Iterator
from dataclasses import dataclass
from glob import glob
from pathlib import Path


def _repo_root() -> Path:
    here = Path(__file__).resolve()
    return next(p for p in here.parents if (p / "pyproject.toml").is_file())


ROOT = _repo_root()
PACKAGE = ROOT / "orbitsim"

#: The first folders of a repository path (the bundled scenarios' old folder ``configs`` is gone: a
#: citation of it is a stale word).
ROOT_FOLDERS = ("orbitsim", "tests", "benchmarks", "docs", "configs")
#: Files that a make target writes and that a document links to on purpose -> the target's name.
GENERATED = {"demo-report/lesson.html": "demo"}

_LEFT = r"(?<![\w./~$\-])(?<!\[\")(?<!\[')"  # not the tail of a longer path or a variable, nor f["x"]
_PATH_CHARS = r"[\w./{},*\-]*"
ROOT_PATH = re.compile(_LEFT + r"(?:" + "|".join(ROOT_FOLDERS) + r")/" + _PATH_CHARS + r"(?:#[\w\-]+)?")
CAPS_MD = re.compile(r"(?<![\w./\-])[A-Z][A-Z0-9_]*\.md\b")
ROLE = re.compile(r":(?:mod|func|class|data|attr|meth|exc|obj|const):`~?(orbitsim(?:\.\w+)+)`")
MD_LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")


@dataclass(frozen=True)
class Prose:
    """A piece of documentation text: where it is, and the line its text starts on."""

    path: Path
    line: int
    text: str

    def at(self, offset: int, root: Path = ROOT) -> str:
        """``file:line`` of the character at ``offset``."""
        where = self.path.relative_to(root) if self.path.is_relative_to(root) else self.path
        return f"{where}:{self.line + self.text.count(chr(10), 0, offset)}"


def markdown_documents(root: Path = ROOT) -> list[Path]:
    return [root / "README.md", *sorted((root / "docs").rglob("*.md")), root / "benchmarks" / "README.md"]


def python_prose(path: Path) -> Iterator[Prose]:
    """Docstrings (and other bare strings), ``help=`` texts and comments of one Python file."""
    text = path.read_text(encoding="utf-8")
    for node in ast.walk(ast.parse(text, filename=str(path))):
        if isinstance(node, ast.Expr) and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str):
            yield Prose(path, node.lineno, node.value.value)
        elif isinstance(node, ast.keyword) and node.arg == "help":
            for part in ast.walk(node.value):
                if isinstance(part, ast.Constant) and isinstance(part.value, str):
                    yield Prose(path, part.lineno, part.value)
    for token in tokenize.generate_tokens(io.StringIO(text).readline):
        if token.type == tokenize.COMMENT:
            yield Prose(path, token.start[0], token.string)


def all_prose(root: Path = ROOT) -> Iterator[Prose]:
    for doc in markdown_documents(root):
        yield Prose(doc, 1, doc.read_text(encoding="utf-8"))
    for folder in ("orbitsim", "tests", "benchmarks"):
        for path in sorted((root / folder).rglob("*.py")):
            yield from python_prose(path)


# -- what a citation resolves to -----------------------------------------------------------------------


def _expand(pattern: str) -> list[str]:
    """``a/{b,c}.py`` -> ``a/b.py``, ``a/c.py``."""
    found = re.search(r"\{([^{}]*)\}", pattern)
    if not found:
        return [pattern]
    return [e for alt in found.group(1).split(",")
            for e in _expand(pattern[: found.start()] + alt + pattern[found.end():])]


def path_exists(cited: str, *bases: Path) -> bool:
    """True when every expansion of ``cited`` names something under one of ``bases`` (a glob: anything)."""
    for each in _expand(cited):
        if not any(glob(str(base / each)) if "*" in each else (base / each).exists() for base in bases):
            return False
    return True


def _clean(cited: str) -> str:
    cited = cited.split("...")[0]  # orbitsim/... : the folder
    return cited.rstrip(".,;:") if not cited.endswith("/...") else cited


def heading_anchors(markdown: str) -> set[str]:
    """GitHub's anchors of a Markdown text's headings (code blocks skipped; repeats get -1, -2, ...)."""
    anchors: set[str] = set()
    seen: dict[str, int] = {}
    fence = None
    for line in markdown.splitlines():
        stripped = line.lstrip()
        if stripped.startswith(("```", "~~~")):
            fence = None if fence and stripped.startswith(fence) else (fence or stripped[:3])
            continue
        heading = re.match(r"#{1,6}\s+(.*?)\s*#*\s*$", line)
        if fence or not heading:
            continue
        slug = re.sub(r"[^\w\- ]", "", heading.group(1).strip().lower()).replace(" ", "-")
        anchors.add(slug if slug not in seen else f"{slug}-{seen[slug]}")
        seen[slug] = seen.get(slug, 0) + 1
    return anchors


def _anchor_missing(target: Path, anchor: str) -> bool:
    return target.suffix == ".md" and target.is_file() and anchor not in heading_anchors(target.read_text("utf-8"))


def _module_names(package: Path = PACKAGE) -> dict[str, Path]:
    names = {}
    for path in package.rglob("*.py"):
        parts = list(path.relative_to(package.parent).with_suffix("").parts)
        names[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return names


def _defined_names(path: Path) -> set[str]:
    """Names a module binds (functions, classes, assignments, imports), and, when it has a module
    ``__getattr__``, the string constants it compares against (its lazily provided names)."""
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names: set[str] = set()
    lazy = False
    for node in ast.walk(tree):
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.ClassDef)):
            names.add(node.name)
            lazy = lazy or node.name == "__getattr__"
        elif isinstance(node, (ast.Import, ast.ImportFrom)):
            names.update((a.asname or a.name).split(".")[0] for a in node.names)
        elif isinstance(node, ast.Name) and isinstance(node.ctx, ast.Store):
            names.add(node.id)
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Store):
            names.add(node.attr)
    if lazy:
        names.update(n.value for n in ast.walk(tree) if isinstance(n, ast.Constant) and isinstance(n.value, str))
    return names


class Resolver:
    """Checks citations against one checkout (``root``)."""

    def __init__(self, root: Path = ROOT) -> None:
        self.root = root
        self.package = root / "orbitsim"
        self.modules = _module_names(self.package)
        self.package_folders = sorted(p.name for p in self.package.iterdir() if (p / "__init__.py").is_file())
        self._names: dict[Path, set[str]] = {}
        self.relative_py = re.compile(_LEFT + r"(?:" + "|".join(self.package_folders) + r")/[\w/]*\.py\b")

    def dead(self, prose: Prose) -> Iterator[str]:
        """``file:line: citation`` for each citation in ``prose`` that resolves to nothing."""
        here = prose.path.parent
        for match in ROOT_PATH.finditer(prose.text):
            cited, _, anchor = _clean(match.group(0)).partition("#")
            if not path_exists(cited, self.root):
                yield f"{prose.at(match.start(), self.root)}: {match.group(0)}"
            elif anchor and _anchor_missing(self.root / cited, anchor):
                yield f"{prose.at(match.start(), self.root)}: {match.group(0)} (no such heading)"
        for match in self.relative_py.finditer(prose.text):
            if not path_exists(match.group(0), self.package, here):
                yield f"{prose.at(match.start(), self.root)}: {match.group(0)}"
        for match in CAPS_MD.finditer(prose.text):
            if not path_exists(match.group(0), self.root, here):
                yield f"{prose.at(match.start(), self.root)}: {match.group(0)}"
        for match in ROLE.finditer(prose.text):
            if not self._resolves(match.group(1)):
                yield f"{prose.at(match.start(), self.root)}: {match.group(1)}"
        if prose.path.suffix == ".md":
            yield from self._dead_links(prose)

    def _resolves(self, dotted: str) -> bool:
        parts = dotted.split(".")
        for k in range(len(parts), 0, -1):
            module = ".".join(parts[:k])
            if module in self.modules:
                if k == len(parts):
                    return True
                path = self.modules[module]
                if path not in self._names:
                    self._names[path] = _defined_names(path)
                return parts[k] in self._names[path]
        return False

    def _dead_links(self, prose: Prose) -> Iterator[str]:
        for match in MD_LINK.finditer(prose.text):
            target = match.group(1)
            if re.match(r"[a-z]+:", target):  # https:, mailto:
                continue
            cited, _, anchor = target.partition("#")
            path = (prose.path.parent / cited).resolve() if cited else prose.path
            rel = path.relative_to(self.root).as_posix() if path.is_relative_to(self.root) else str(path)
            if not path.exists() and rel not in GENERATED:
                yield f"{prose.at(match.start(), self.root)}: {target}"
            elif anchor and _anchor_missing(path, anchor):
                yield f"{prose.at(match.start(), self.root)}: {target} (no such heading)"


# -- the README's layout ---------------------------------------------------------------------------------

LAYOUT_HEADING = "## How it is built"
_PATH_TOKEN = re.compile(r"[\w.]+(?:/[\w.]+)*/?")


@dataclass
class LayoutEntry:
    """One entry of the layout block: the paths it names (from the root) and its description."""

    paths: list[str]
    description: str
    line: int


def layout_entries(readme: str) -> list[LayoutEntry]:
    """The entries of the first code block under :data:`LAYOUT_HEADING`.

    A line at indent 0 names a top folder (``orbitsim/``); the lines at the next indent are its
    entries, whose leading words that are paths (with a ``/`` or ending in ``.py``), before the first
    run of two spaces, are what they describe; deeper lines continue the description above them.
    """
    lines = readme.splitlines()
    start = next(i for i, line in enumerate(lines) if line.strip() == LAYOUT_HEADING)
    opening = next(i for i in range(start, len(lines)) if lines[i].startswith("```"))
    entries: list[LayoutEntry] = []
    top, entry_indent = "", None
    for number in range(opening + 1, len(lines)):
        line = lines[number]
        if line.startswith("```"):
            break
        if not line.strip():
            continue
        indent = len(line) - len(line.lstrip())
        words = line.split()
        if indent == 0:
            top = words[0]
            entries.append(LayoutEntry([top], " ".join(words[1:]), number + 1))
            continue
        if entry_indent is None:
            entry_indent = indent
        if indent > entry_indent and entries:
            entries[-1].description += " " + line.strip()
            continue
        field, _, rest = line.strip().partition("  ")
        names, paths = field.split(), []
        while names and _PATH_TOKEN.fullmatch(names[0]) and ("/" in names[0] or names[0].endswith(".py")):
            paths.append(top + names.pop(0))
        entries.append(LayoutEntry(paths, " ".join([*names, rest.strip()]).strip(), number + 1))
    return entries


def layout_problems(readme: str, root: Path = ROOT) -> list[str]:
    """What the layout block names that is not in the tree, and which package folders it leaves out."""
    entries = layout_entries(readme)
    problems = []
    for entry in entries:
        if not entry.paths:
            problems.append(f"README.md:{entry.line}: an entry that names no file or folder")
        for path in entry.paths:
            if not (root / path).exists():
                problems.append(f"README.md:{entry.line}: {path} does not exist")
            folder = root / path if path.endswith("/") else (root / path).parent
            top = root / path.split("/")[0]
            for word in re.findall(r"[\w/]+\.py\b|\b\w+/(?=[\s,;:)]|$)", entry.description):
                if not any((base / word).exists() or (word.endswith(".py") and any(base.rglob(word)))
                           for base in (folder, top)):
                    problems.append(f"README.md:{entry.line}: {word} (under {path}) does not exist")
    named = {p.rstrip("/") for entry in entries for p in entry.paths}
    for init in sorted((root / "orbitsim").rglob("__init__.py")):
        folder = init.parent.relative_to(root).as_posix()
        if folder == "orbitsim":
            continue
        parent, name = folder.rsplit("/", 1)
        in_parent = any(re.search(rf"(?<![\w/]){re.escape(name)}/", e.description)
                        for e in entries for p in e.paths if p.rstrip("/") == parent)
        listed = folder in named or any(n.startswith(folder + "/") for n in named)
        if not (listed or (parent != "orbitsim" and in_parent)):
            problems.append(f"README.md: the package folder {folder}/ is not in '{LAYOUT_HEADING}'")
    return problems


# -- the tests -------------------------------------------------------------------------------------------


def test_the_documentation_cites_only_what_exists() -> None:
    resolver = Resolver()
    dead = sorted({hit for prose in all_prose() for hit in resolver.dead(prose)})
    assert not dead, "cited but not in the checkout (rephrase, or fix the path):\n" + "\n".join(dead)


def test_generated_link_targets_are_made_by_their_make_target() -> None:
    makefile = (ROOT / "Makefile").read_text(encoding="utf-8")
    for path, target in GENERATED.items():
        recipe = re.search(rf"^{target}:.*\n((?:\t.*\n)+)", makefile, re.MULTILINE)
        assert recipe and path.split("/")[0] in recipe.group(1), f"make {target} no longer writes {path}"


def test_the_readme_layout_matches_the_tree() -> None:
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert len(layout_entries(readme)) >= 10
    problems = layout_problems(readme)
    assert not problems, "\n".join(problems)


# -- the checks on a fake checkout that breaks each rule -------------------------------------------------


def _fake_checkout(tmp_path: Path) -> Path:
    for folder in ("orbitsim/physics", "orbitsim/integrators/trace", "orbitsim/io", "docs", "tests"):
        (tmp_path / folder).mkdir(parents=True)
    for module in ("__init__", "units", "physics/__init__", "physics/gravity", "integrators/__init__",
                   "integrators/base", "integrators/trace/__init__", "io/__init__", "io/trace"):
        (tmp_path / "orbitsim" / f"{module}.py").write_text("def accelerations(): pass\n", encoding="utf-8")
    (tmp_path / "docs" / "guide.md").write_text("# Guide\n\n## The forces\n\n```\n# not a heading\n```\n",
                                                encoding="utf-8")
    return tmp_path


def test_each_kind_of_dead_citation_is_found(tmp_path: Path) -> None:
    root = _fake_checkout(tmp_path)
    resolver = Resolver(root)
    good = ("orbitsim/physics/gravity.py, orbitsim/{units,io/trace}.py, orbitsim/physics/*.py and "
            "orbitsim/integrators/..., docs/guide.md#the-forces; physics/gravity.py; "
            ":func:`orbitsim.physics.gravity.accelerations`, :mod:`~orbitsim.io.trace`; "
            'h5["orbitsim/leapfrog4"] and ~/.cache/orbitsim/numba')
    bad = ("orbitsim/physics/kepler.py; configs/solar.yaml; docs/guide.md#not-a-heading; DESIGN.md section 4; "
           "integrators/leapfrog4.py; :func:`orbitsim.integrators.bs_core.step`; "
           ":func:`orbitsim.physics.gravity.jerk`")
    path = root / "orbitsim" / "units.py"
    assert list(resolver.dead(Prose(path, 1, good))) == []
    dead = list(resolver.dead(Prose(path, 3, bad)))
    assert [d.split(": ", 1)[1] for d in dead] == [
        "orbitsim/physics/kepler.py", "configs/solar.yaml", "docs/guide.md#not-a-heading (no such heading)",
        "integrators/leapfrog4.py", "DESIGN.md", "orbitsim.integrators.bs_core.step",
        "orbitsim.physics.gravity.jerk"]
    assert all(d.startswith("orbitsim/units.py:3: ") for d in dead)
    links = "[ok](guide.md#the-forces), [gone](gone.md), [nowhere](guide.md#not-a-heading), [web](https://x.org)"
    dead = list(resolver.dead(Prose(root / "docs" / "other.md", 1, links)))
    assert [d.split(": ", 1)[1] for d in dead] == ["gone.md", "guide.md#not-a-heading (no such heading)"]


def test_python_prose_is_docstrings_comments_and_help_only(tmp_path: Path) -> None:
    path = tmp_path / "m.py"
    path.write_text('"""Doc: orbitsim/a.py."""\nX = "orbitsim/b.py"  # orbitsim/c.py\n'
                    'f(help="see docs/d.md")\n', encoding="utf-8")
    texts = sorted(p.text for p in python_prose(path))
    assert texts == ["# orbitsim/c.py", "Doc: orbitsim/a.py.", "see docs/d.md"]


def test_heading_anchors_follow_github() -> None:
    text = "# A `x` (y)\n## Backwards: dt < 0\n## Events\n### Events\n```\n# no\n```\n"
    assert heading_anchors(text) == {"a-x-y", "backwards-dt--0", "events", "events-1"}


def test_each_kind_of_layout_drift_is_found(tmp_path: Path) -> None:
    root = _fake_checkout(tmp_path)
    readme = ("## How it is built\n\n```\norbitsim/\n  units.py        constants\n"
              "  physics/        gravity.py and kepler.py\n  integrators/    base.py, leapfrog.py; families:\n"
              "                  trace/, ias15/\n  io/trace.py the trace\n  gone/           a folder no more\n"
              "```\n")
    assert [e.paths for e in layout_entries(readme)] == [
        ["orbitsim/"], ["orbitsim/units.py"], ["orbitsim/physics/"], ["orbitsim/integrators/"],
        ["orbitsim/io/trace.py"], ["orbitsim/gone/"]]
    assert layout_problems(readme, root) == [
        "README.md:6: kepler.py (under orbitsim/physics/) does not exist",
        "README.md:7: leapfrog.py (under orbitsim/integrators/) does not exist",
        "README.md:7: ias15/ (under orbitsim/integrators/) does not exist",
        "README.md:10: orbitsim/gone/ does not exist"]
    (root / "orbitsim" / "lesson").mkdir()
    (root / "orbitsim" / "lesson" / "__init__.py").write_text("", encoding="utf-8")
    (root / "orbitsim" / "integrators" / "ias15").mkdir()
    (root / "orbitsim" / "integrators" / "ias15" / "__init__.py").write_text("", encoding="utf-8")
    (root / "orbitsim" / "physics" / "ode").mkdir()
    (root / "orbitsim" / "physics" / "ode" / "__init__.py").write_text("", encoding="utf-8")
    assert layout_problems(readme, root)[-2:] == [
        "README.md: the package folder orbitsim/lesson/ is not in '## How it is built'",
        "README.md: the package folder orbitsim/physics/ode/ is not in '## How it is built'"]
