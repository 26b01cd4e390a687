"""``orbitsim list``: the integrators, and the bundled scenarios, sweeps and benchmark matrices."""

from __future__ import annotations

from collections.abc import Callable

import click

from orbitsim.cli.errors import one_line, reports_errors


@click.command("list")
@click.argument("what", type=click.Choice(["integrators", "scenarios", "sweeps", "matrices"]), required=False)
@click.option("--settings", "settings", is_flag=True,
              help="List each integrator's settings (integrator: {name: ..., KEY: VALUE}): default and meaning. "
                   "Example: orbitsim list integrators --settings")
@reports_errors
def command(what: str | None, settings: bool) -> None:
    """List integrators (order, symplecticity, variational equations for MEGNO), bundled scenarios
    (N, integrator, description), bundled sweeps (base scenario, file) or bundled benchmark matrices
    (groups, file).

    With no argument, lists all four. Bundled files run by name: `orbitsim run NAME`,
    `orbitsim batch NAME`, `orbitsim bench NAME`; copy the file listed to start your own.
    With --settings, the integrators' settings instead of the integrator table.

    \b
    Examples:
      orbitsim list
      orbitsim list integrators
      orbitsim list integrators --settings
      orbitsim list scenarios
      orbitsim list sweeps
    """
    if settings and what not in (None, "integrators"):
        raise click.UsageError("--settings lists the integrators' settings: orbitsim list integrators --settings")
    listers = {"integrators": _settings if settings else _integrators, "scenarios": _scenarios, "sweeps": _sweeps,
               "matrices": _matrices}
    for k, (name, lister) in enumerate(listers.items()):
        if what in (None, name):
            if k and what is None:
                click.echo()
            lister()


def _integrators() -> None:
    from orbitsim.integrators.registry import RECORDS

    rows = [(s.name, ", ".join(s.aliases) or "-", str(s.order), "adaptive" if s.adaptive else "fixed",
             "yes" if s.symplectic else "no", "yes" if s.reversible else "no", str(s.force_evals),
             "yes" if record.run_chaos is not None else "no", f"{s.summary} [{s.reference}]")
            for record in RECORDS for s in (record.spec,)]
    _table(("integrator", "aliases", "order", "step", "symplectic", "reversible", "forces/step", "variational",
            "summary [reference]"), rows)


def _settings() -> None:
    """One row per setting of every integrator that has any: its default, its doc and its values."""
    from orbitsim.integrators.rebound_names import LEAPFROG_ORDERS
    from orbitsim.integrators.registry import RECORDS

    rows = [(record.spec.name, key, _yaml_value(setting.default),
             setting.doc + (f"; values: {', '.join(map(_yaml_value, setting.choices))}" if setting.choices else ""))
            for record in RECORDS for key, setting in record.settings.items()]
    _table(("integrator", "setting", "default", "meaning"), rows)
    without = [record.spec.name for record in RECORDS if not record.settings]
    if without:
        click.echo(f"no settings: {', '.join(without)}")
    orders = ", ".join(f"{order}: {name}" for order, name in LEAPFROG_ORDERS.items())
    click.echo(f"REBOUND's leapfrog order is a name here: {{name: leapfrog, order: 4}} is leapfrog4 ({orders})")


def _yaml_value(value: object) -> str:
    """A setting's value as a scenario writes it (``true``, not ``True``)."""
    return str(value).lower() if isinstance(value, bool) else str(value)


def _scenarios() -> None:
    from orbitsim.scenario import ScenarioError, bundled_scenarios, config_dir, load_scenario

    found = bundled_scenarios()
    if not found:
        click.echo(f"no bundled scenarios found in {config_dir()} (set ORBITSIM_CONFIG_DIR)")
        return
    rows = []
    for name in found:
        try:
            s = load_scenario(name)
            rows.append((name, str(s.n_bodies), s.integrator, s.description))
        except ScenarioError as err:  # list it anyway: a broken bundled file should be visible
            rows.append((name, "?", "?", f"INVALID: {one_line(err)}"))
    _table(("scenario", "N", "integrator", "description"), rows)


def _sweeps() -> None:
    from orbitsim.data import SWEEPS

    _files(SWEEPS, "sweep", "base", lambda doc: str(doc.get("base", "?")))


def _matrices() -> None:
    from orbitsim.data import MATRICES

    _files(MATRICES, "matrix", "groups",
           lambda doc: ", ".join(str(g.get("name", "?")) for g in doc.get("groups") or [] if isinstance(g, dict)))


def _files(kind: str, noun: str, column: str, summary: Callable[[dict], str]) -> None:
    """A table of the bundled files of one kind: name, one summary column read from the YAML, file."""
    import yaml

    from orbitsim.data import bundled_dir, bundled_files

    found = bundled_files(kind)
    if not found:
        click.echo(f"no bundled {noun} files found in {bundled_dir(kind)}")
        return
    rows = []
    for name, path in found.items():
        try:
            doc = yaml.safe_load(path.read_text(encoding="utf-8"))
            rows.append((name, summary(doc) if isinstance(doc, dict) else "INVALID: not a mapping", str(path)))
        except (OSError, UnicodeDecodeError, yaml.YAMLError) as err:
            rows.append((name, f"INVALID: {one_line(err)}", str(path)))
    _table((noun, column, "file"), rows)


def _table(header: tuple[str, ...], rows: list[tuple[str, ...]]) -> None:
    """Left-aligned columns; the last column is left free to run long."""
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header) - 1)]
    for row in [header, *rows]:
        cells = [cell.ljust(width) for cell, width in zip(row[:-1], widths, strict=True)]
        click.echo("  ".join([*cells, row[-1]]).rstrip())
