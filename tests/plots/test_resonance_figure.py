"""``orbitsim plot --resonance P:Q``: the resonant angles, the libration measure and the figure."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from click.testing import CliRunner

from orbitsim.cli.main import cli
from orbitsim.plots.resonance import libration_amplitude, parse_resonance, pick_pair, resonant_angles

PNG = b"\x89PNG\r\n\x1a\n"


def test_parse_resonance() -> None:
    assert parse_resonance("2:1") == (2, 1) and parse_resonance(" 5 : 3 ") == (5, 3)
    for bad in ("1:2", "2:2", "2", "a:b", "3:0"):
        with pytest.raises(ValueError, match="P:Q"):
            parse_resonance(bad)


def test_resonant_angles_combine_the_longitudes() -> None:
    """phi = P lambda_out - Q lambda_in - (P-Q) varpi, lambda = Omega + omega + M, varpi = Omega + omega."""
    el = {"Omega": np.array([[0.0, 10.0, 20.0]]), "omega": np.array([[0.0, 30.0, 50.0]]),
          "M": np.array([[0.0, 100.0, 7.0]])}
    phi_in, phi_out = resonant_angles(el, 1, 2, 3, 1)
    lam_in, lam_out, varpi_in, varpi_out = 140.0, 77.0, 40.0, 70.0
    assert np.allclose(phi_in, (3 * lam_out - lam_in - 2 * varpi_in + 180) % 360 - 180)
    assert np.allclose(phi_out, (3 * lam_out - lam_in - 2 * varpi_out + 180) % 360 - 180)


def test_libration_amplitude_separates_libration_from_circulation() -> None:
    t = np.linspace(0.0, 50.0, 2000)
    librating = 170.0 + 40.0 * np.sin(t)  # about 170 deg, across the +-180 wrap
    circulating = np.degrees(t) % 360.0 - 180.0
    assert libration_amplitude((librating + 180) % 360 - 180) == pytest.approx(40.0, abs=0.1)
    assert libration_amplitude(circulating) > 179.0


def test_pick_pair() -> None:
    a = np.array([[np.nan, 2.0, 1.0], [np.nan, 2.1, 1.0]])
    assert pick_pair(["star", "c", "b"], a, None) == (2, 1)  # inner first, by a
    assert pick_pair(["star", "c", "b"], a, "c,b") == (2, 1)
    with pytest.raises(ValueError, match="--pair"):
        pick_pair(["star", "c", "b", "d"], np.ones((2, 4)), None)


def test_cli_draws_the_capture(tmp_path: Path) -> None:
    """The bundled migration example, shortened to its capture, through run and plot."""
    trace = tmp_path / "rc.h5"
    runner = CliRunner()
    result = runner.invoke(cli, ["run", "resonance_capture", "-o", str(trace), "--t-end", "1000"])
    assert result.exit_code == 0, result.output
    result = runner.invoke(cli, ["plot", str(trace), "--resonance", "2:1"])
    assert result.exit_code == 0, result.output
    figure = tmp_path / "rc_resonance.png"
    assert figure.read_bytes()[:8] == PNG
    result = runner.invoke(cli, ["plot", str(trace), "--resonance", "2:1", "--elements"])
    assert result.exit_code == 2 and "give one" in result.output
