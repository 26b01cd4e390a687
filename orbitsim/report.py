"""Reports as a small document model written to Markdown and to self-contained HTML.

A :class:`Report` is a title, a lead paragraph and sections of paragraphs, tables and figures.
:func:`write_markdown` and :func:`write_html` render the same model, so the two files always say
the same thing. The HTML has its style inline and refers only to the PNGs beside it: it opens
offline, from a copied directory, or as an e-mail attachment bundle.

Every report ends with :func:`reproduce_section`: the exact command, the scenario and its SHA-256,
the versions of orbitsim, REBOUND, numpy, numba, Python and matplotlib, and the machine.
"""

from __future__ import annotations

import datetime as _dt
import html
import math
from dataclasses import dataclass, field
from importlib import metadata
from pathlib import Path
from typing import Any

from orbitsim.provenance import provenance


@dataclass
class Table:
    """A table: column headers and rows of already formatted cells."""

    header: list[str]
    rows: list[list[str]]
    caption: str = ""


@dataclass
class Figure:
    """A PNG beside the report (``filename`` is relative) and its caption."""

    filename: str
    caption: str


@dataclass
class Section:
    """A titled section; blocks are rendered in order."""

    title: str
    blocks: list[str | Table | Figure] = field(default_factory=list)


@dataclass
class Report:
    """A whole report; ``lead`` is shown under the title (e.g. the verdict)."""

    title: str
    lead: list[str]
    sections: list[Section]


def fmt(value: Any, digits: int = 3) -> str:
    """A number for a table: ``3.14e-09`` style, ``n/a`` for None/nan, ints as they are."""
    if value is None:
        return "n/a"
    if isinstance(value, bool):
        return "yes" if value else "no"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "n/a"
        return f"{value:.{digits}g}"
    return str(value)


def json_safe(value: Any) -> Any:
    """A copy that is strict JSON: nan/inf -> None, numpy scalars -> Python numbers."""
    if isinstance(value, dict):
        return {k: json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if hasattr(value, "item") and not isinstance(value, str):
        value = value.item()
    if isinstance(value, float) and not math.isfinite(value):
        return None
    return value


def scenario_table(scenario: Any, *, steps: int, samples: int, end_time: float | None = None) -> Table:
    """The scenario's defining numbers (what a reader needs to rerun it); ``end_time`` defaults to
    ``steps * dt``."""
    rows = [
        ["name", str(scenario.name)],
        ["description", str(getattr(scenario, "description", "") or "")],
        ["source", str(getattr(scenario, "source", "") or "")],
        ["SHA-256", str(getattr(scenario, "sha256", "") or "")],
        ["bodies", str(len(scenario.masses))],
        ["units (G)", f"{getattr(scenario, 'units', '')} (G = {scenario.G!r})"],
        ["softening", repr(float(scenario.softening))],
        ["frame", str(getattr(scenario, "frame", "") or "")],
        ["scenario integrator", str(scenario.integrator)],
        ["dt", repr(float(scenario.dt))],
        ["steps", str(steps)],
        ["end time", fmt(steps * float(scenario.dt) if end_time is None else end_time, 10)],
        ["samples", str(samples)],
    ]
    return Table(["", "value"], [r for r in rows if r[1]])


def _version(package: str) -> str:
    try:
        return metadata.version(package)
    except metadata.PackageNotFoundError:
        return "not installed"


def reproduce_section(command: str, scenario: Any) -> Section:
    """Command, scenario identity, software versions and the machine."""
    info = provenance()
    rows = [
        ["command", f"`{command}`"],
        ["scenario", f"{scenario.name} (sha256 {getattr(scenario, 'sha256', 'n/a')})"],
        ["orbitsim", str(info["orbitsim_version"])],
        ["REBOUND", str(info["rebound_version"])],
        ["numpy", str(info["numpy_version"])],
        ["numba", str(info["numba_version"])],
        ["matplotlib", _version("matplotlib")],
        ["Python", f"{info['python_version']} ({info['python_implementation']})"],
        ["platform", str(info["platform"])],
        ["CPU", f"{info['cpu_model']}, {info['cpu_count']} logical cores"],
        ["Numba threads", str(info["numba_threads"])],
        ["generated", _dt.datetime.now(_dt.UTC).strftime("%Y-%m-%d %H:%M:%S UTC")],
    ]
    return Section("Reproduce", [Table(["", "value"], rows)])


def _md_cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def to_markdown(report: Report) -> str:
    """The report as GitHub-flavoured Markdown."""
    out = [f"# {report.title}", "", *[line + "\n" for line in report.lead]]
    for section in report.sections:
        out += [f"## {section.title}", ""]
        for block in section.blocks:
            if isinstance(block, Table):
                out.append("| " + " | ".join(_md_cell(h) for h in block.header) + " |")
                out.append("|" + "|".join("---" for _ in block.header) + "|")
                out += ["| " + " | ".join(_md_cell(c) for c in row) + " |" for row in block.rows]
                out += [""] + ([f"*{block.caption}*", ""] if block.caption else [])
            elif isinstance(block, Figure):
                out += [f"![{Path(block.filename).stem}]({block.filename})", "", f"*{block.caption}*", ""]
            else:
                out += [block, ""]
    return "\n".join(out).rstrip() + "\n"


_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;max-width:1180px;margin:2em auto;
padding:0 1.2em;color:#1d1d1f;line-height:1.45}
h1{font-size:1.7em;margin-bottom:.3em}h2{margin-top:1.8em;border-bottom:1px solid #ddd;padding-bottom:.2em}
table{border-collapse:collapse;margin:.8em 0;font-size:.92em}
th,td{border:1px solid #d0d0d0;padding:.3em .6em;text-align:left;vertical-align:top}
th{background:#f2f2f2}td.num{text-align:right;font-variant-numeric:tabular-nums}
figure{margin:1.2em 0}figure img{max-width:100%;height:auto;border:1px solid #eee}
figcaption{font-size:.9em;color:#555;margin-top:.3em}code{background:#f5f5f5;padding:0 .25em}
.pass{color:#0a7d32;font-weight:600}.fail{color:#b00020;font-weight:600}.warn{color:#a35200;font-weight:600}
"""


#: Lead lines that start with a verdict are coloured by it; an untestable one is not green.
_LEAD_CLASSES = (("FAIL", "fail"), ("PASS", "pass"), ("NOT TESTABLE", "warn"))


def _inline(text: str) -> str:
    """Escape, then render `code` spans (the only inline markup reports use)."""
    parts = html.escape(text).split("`")
    return "".join(f"<code>{p}</code>" if i % 2 else p for i, p in enumerate(parts))


def _html_cell(text: str, tag: str) -> str:
    numeric = tag == "td" and text.replace(".", "", 1).replace("e-", "").replace("e+", "").lstrip(
        "-").isdigit()
    cls = ' class="num"' if numeric else ""
    return f"<{tag}{cls}>{_inline(text)}</{tag}>"


def to_html(report: Report) -> str:
    """The report as one HTML page (inline CSS; images are the PNG files beside it)."""
    out = ["<!DOCTYPE html>", '<html lang="en"><head><meta charset="utf-8">',
           f"<title>{html.escape(report.title)}</title><style>{_CSS}</style></head><body>",
           f"<h1>{html.escape(report.title)}</h1>"]
    for line in report.lead:
        cls = next((f' class="{c}"' for prefix, c in _LEAD_CLASSES if line.startswith(prefix)), "")
        out.append(f"<p{cls}>{_inline(line)}</p>")
    for section in report.sections:
        out.append(f"<h2>{html.escape(section.title)}</h2>")
        for block in section.blocks:
            if isinstance(block, Table):
                out.append("<table><thead><tr>" + "".join(_html_cell(h, "th") for h in block.header)
                           + "</tr></thead><tbody>")
                out += ["<tr>" + "".join(_html_cell(c, "td") for c in row) + "</tr>" for row in block.rows]
                out.append("</tbody></table>")
                if block.caption:
                    out.append(f"<p><em>{_inline(block.caption)}</em></p>")
            elif isinstance(block, Figure):
                out.append(f'<figure><img src="{html.escape(block.filename)}" alt="{html.escape(block.caption)}">'
                           f"<figcaption>{_inline(block.caption)}</figcaption></figure>")
            else:
                out.append(f"<p>{_inline(block)}</p>")
    out.append("</body></html>")
    return "\n".join(out) + "\n"


def write_report(report: Report, outdir: Path, stem: str = "report") -> tuple[Path, Path]:
    """Write ``<stem>.md`` and ``<stem>.html`` into ``outdir``; returns both paths."""
    md = outdir / f"{stem}.md"
    page = outdir / f"{stem}.html"
    md.write_text(to_markdown(report), encoding="utf-8")
    page.write_text(to_html(report), encoding="utf-8")
    return md, page
