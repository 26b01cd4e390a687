"""``orbitsim list``: the integrators and the bundled scenarios."""

from __future__ import annotations

import click

from orbitsim.cli.errors import one_line, reports_errors


@click.command("list")
@click.argument("what", type=click.Choice(["integrators", "scenarios"]), required=False)
@click.option("--settings", "settings", is_flag=True,
              help="List each integrator's settings (integrator: {name: ..., KEY: VALUE}): default and meaning. "
                   "Example: orbitsim list integrators --settings")
@reports_errors
def command(what: str | None, settings: bool) -> None:
    """List integrators (order, symplecticity) or bundled scenarios (N, integrator, description).

    With no argument, lists both. Bundled scenarios run by name: `orbitsim run NAME`.
    With --settings, the integrators' settings instead of the integrator table.

    \b
    Examples:
      orbitsim list
      orbitsim list integrators
      orbitsim list integrators --settings
      orbitsim list scenarios
    """
    if settings and what == "scenarios":
        raise click.UsageError("--settings lists the integrators' settings: orbitsim list integrators --settings")
    if what in (None, "integrators"):
        _settings() if settings else _integrators()
    if what is None:
        click.echo()
    if what in (None, "scenarios"):
        _scenarios()


def _integrators() -> None:
    from orbitsim.integrators.registry import INTEGRATORS

    rows = [(s.name, ", ".join(s.aliases) or "-", str(s.order), "adaptive" if s.adaptive else "fixed",
             "yes" if s.symplectic else "no", "yes" if s.reversible else "no", str(s.force_evals),
             f"{s.summary} [{s.reference}]") for s in INTEGRATORS]
    _table(("integrator", "aliases", "order", "step", "symplectic", "reversible", "forces/step",
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


def _table(header: tuple[str, ...], rows: list[tuple[str, ...]]) -> None:
    """Left-aligned columns; the last column is left free to run long."""
    widths = [max(len(r[i]) for r in [header, *rows]) for i in range(len(header) - 1)]
    for row in [header, *rows]:
        cells = [cell.ljust(width) for cell, width in zip(row[:-1], widths, strict=True)]
        click.echo("  ".join([*cells, row[-1]]).rstrip())
