"""Issue 11: results at home in a notebook (repr, summary, HTML, plot, frame) and the
terminal (help in words, -h, examples, messages on stderr, copyable commands)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import balancer_id as bid
from balancer_id.identify.display import format_with_uncertainty

THRUSTS = "2.45,-2.45,4.9,-4.9"


@pytest.fixture(scope="module")
def small_log(tmp_path_factory) -> Path:
    """Four short simulated trials (m_a = 0.5 kg by default), written by ``simulate``."""
    from typer.testing import CliRunner

    from balancer_id.cli import app

    path = tmp_path_factory.mktemp("display") / "small.csv"
    res = CliRunner().invoke(
        app, ["simulate", "--thrust", THRUSTS, "--out", str(path), "--duration", "4"]
    )
    assert res.exit_code == 0, res.stderr
    return path


@pytest.fixture(scope="module")
def fitted(small_log):
    return bid.fit(str(small_log), model="viscous")


def test_a_fit_shows_itself_short_and_in_full(fitted):
    text = repr(fitted)
    assert text.startswith("<FitResult viscous: m_a=") and len(text) < 200
    assert "\n" not in text
    report = fitted.summary()
    for block in ("[[Model]]", "[[Fit Statistics]]", "[[Variables]]", "[[Correlations]]"):
        assert block in report
    for name in fitted.values:
        assert f"    {name}" in report
    html = fitted._repr_html_()
    assert html.startswith("<div>") and "<table>" in html and "m_a" in html


def test_to_frame_holds_every_sample_and_its_residual(fitted):
    frame = fitted.to_frame()
    assert list(frame.columns[4:8]) == ["time", "measured", "simulated", "residual"]
    assert list(frame.columns[8:]) == ["model_low", "model_high", "noise_low", "noise_high"]
    assert len(frame) == len(fitted.match.y)
    assert sorted(frame["trial"].unique()) == [t.index for t in fitted.match.data.trials]
    np.testing.assert_allclose(frame["residual"], frame["measured"] - frame["simulated"])
    # the fit explains the measurement: the residual is far smaller than the signal
    assert frame["residual"].std() < 0.5 * frame["measured"].std()


def test_plot_returns_a_figure_of_measured_simulated_and_residual(fitted):
    from matplotlib.figure import Figure

    fig = fitted.plot()
    assert isinstance(fig, Figure)
    trials = fitted.match.data.trials
    assert len(fig.axes) == 2 * len(trials)  # small multiples: a panel and its residual
    tops, bottoms = fig.axes[0::2], fig.axes[1::2]
    for ax, td in zip(tops, trials, strict=True):
        assert len(ax.lines) == 4  # measured, simulated and the noise band's two edges
        assert len(ax.collections) == 1  # the model's 95 % band, shaded
        assert f"{td.thrust_N:+.3g} N" in ax.get_title()  # each trial named by its thrust
    assert bottoms[0].get_ylabel().startswith("residual")
    png = fig._repr_png_()  # a notebook shows it without %matplotlib inline
    assert png[:4] == b"\x89PNG"


def test_diagnosis_compare_and_improve_have_short_reprs_and_summaries(fitted, small_log):
    diagnosis = bid.diagnose(fitted)
    assert len(repr(diagnosis)) < 200 and diagnosis.verdict in repr(diagnosis)
    assert isinstance(diagnosis.summary, str)  # the verdict's paragraph, as before
    full = diagnosis.summary()
    assert "[[Diagnosis]]" in full and diagnosis.summary in full
    assert diagnosis.to_dict()["summary"] == str(diagnosis.summary)
    rows = bid.compare(str(small_log), ["viscous"])
    assert repr(rows[0]).startswith("<ModelComparison viscous: RMSE")
    assert len(rows[0].to_frame()) == len(rows[0].match.y)


@pytest.mark.parametrize(
    ("value", "stderr", "expected"),
    [
        (0.123456, 0.00567, "0.1235 ± 0.0057"),
        (15.1734, 0.035, "15.173 ± 0.035"),
        (6.0, 7253.0, "6.0 ± 7.3e+03"),
        (1.5, None, "1.500"),
    ],
)
def test_numbers_are_rounded_to_their_uncertainty(value, stderr, expected):
    assert format_with_uncertainty(value, stderr) == expected


def test_help_shows_types_in_words_an_example_and_takes_dash_h(cli):
    for args in (("fit", "-h"), ("diagnose", "--help"), ("simulate", "-h")):
        code, out, _ = cli(*args)
        assert code == 0
        assert "Example: balancer-id" in out
        # options name their values in words, flags none; typer >= 0.28 keeps its own
        # label for the arguments' type (``<list[Path]>``), never for an option
        options = out[out.index("Options"):]
        assert "<" not in options and "<bool>" not in out
    code, out, _ = cli("fit", "-h")
    assert "FILE..." in out and "TEXT" in out and "{LOGS}..." in out


def test_terminal_width_is_not_forced_and_commands_are_copyable(cli, small_log, monkeypatch):
    monkeypatch.setenv("COLUMNS", "80")
    code, out, err = cli("diagnose", small_log, "--model", "viscous")
    assert code == 0, err
    commands = [ln.strip() for ln in out.splitlines() if ln.strip().startswith("balancer-id ")]
    assert commands, out
    # tables fit the 80 columns; only the commands run longer (never wrapped)
    assert max(len(ln) for ln in out.splitlines() if ln.strip() not in commands) <= 80
    for command in commands:  # whole, on a line of its own
        assert "--model" in command and str(small_log) in command


def test_warnings_go_to_stderr_not_stdout(cli, small_log):
    # m_a held at a wrong value: the fit warns, and (its lag at a bound) is not trusted:
    # exit 5 (CONTRACT.md), the reasons and warnings on stderr
    code, out, err = cli("fit", small_log, "--model", "viscous", "--fix", "m_a=0.5")
    assert code == 5, err
    assert "warning:" not in out
    assert "warning:" in err
