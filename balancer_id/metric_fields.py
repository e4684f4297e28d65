"""The error metrics of a fit as every renderer shows them: key, label, unit and format.

The fit computes them (:func:`balancer_id.identify.metrics.error_metrics`, the JSON's
``metrics``); the notebook text, the terminal and the HTML report list them from
:data:`FIT_METRICS`, so a new metric is its computation and one line here.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass

from balancer_id.numbers import format_number

__all__ = ["FIT_METRICS", "MetricField", "metric_cells", "metric_line"]


@dataclass(frozen=True)
class MetricField:
    """One error metric of a fit.

    Attributes
    ----------
    key : str
        Its key in the fit's ``metrics`` (JSON).
    label : str
        Its short name in tables and lines.
    unit : str
        Its unit ('' for none).
    digits : int
        Significant digits shown.
    decimals : int or None
        Fixed decimals instead (information criteria: their differences matter).
    integer : bool
        Shown as a whole number (a count).
    """

    key: str
    label: str
    unit: str = ""
    digits: int = 4
    decimals: int | None = None
    integer: bool = False

    @property
    def heading(self) -> str:
        """The label with its unit, for a table's column or a text line."""
        return f"{self.label} ({self.unit})" if self.unit else self.label

    def format(self, value: object) -> str:
        """The value as shown: '-' when missing.

        Parameters
        ----------
        value : float, int or None
            The metric.

        Returns
        -------
        str
        """
        if value is None:
            return "-"
        if self.integer:
            return str(int(value))  # type: ignore[call-overload]
        if self.decimals is not None:
            return f"{float(value):.{self.decimals}f}"  # type: ignore[arg-type]
        return format_number(value, self.digits)


#: The metrics of a fit, in the order every renderer shows them.
FIT_METRICS: tuple[MetricField, ...] = (
    MetricField("rmse", "RMSE", "m/s²"),
    MetricField("nrmse_fit_percent", "fit", "%"),
    MetricField("aic", "AIC", decimals=1),
    MetricField("bic", "BIC", decimals=1),
    MetricField("n_samples", "samples", integer=True),
    # the residual's integrated autocorrelation time: the standard errors are widened by
    # its square root (1 for white residuals)
    MetricField("residual_tau", "residual τ", "samples", digits=3),
    # how far the acceleration leads the recorded force at the optimum (a Rao score test,
    # identify/timing.py; negative: it lags), and that lead's standard error
    MetricField("timing_lead_s", "timing lead", "s", digits=2),
    MetricField("timing_lead_stderr_s", "timing lead s.e.", "s", digits=2),
    # the largest ratio of a standard error from the trials' scatter to the one from the
    # noise within them (identify/trial_scatter.py; the standard errors take the larger)
    MetricField("trial_scatter_ratio", "trial scatter", digits=3),
    # the largest ratio of a standard error with the thrust levels' errors (each hold's
    # mean of a noisy force, less its zero; identify/level_errors.py) to the one without
    MetricField("level_error_ratio", "level errors", digits=3),
)


def metric_cells(metrics: Mapping[str, object]) -> list[tuple[MetricField, str]]:
    """Each metric of :data:`FIT_METRICS` that ``metrics`` holds, with its text.

    Parameters
    ----------
    metrics : mapping
        A fit's ``metrics``.

    Returns
    -------
    list of (MetricField, str)
    """
    return [(f, f.format(metrics[f.key])) for f in FIT_METRICS if metrics.get(f.key) is not None]


def metric_line(metrics: Mapping[str, object]) -> str:
    """The metrics ``metrics`` holds as one line: ``RMSE = 0.04435 m/s², fit = ...``.

    Parameters
    ----------
    metrics : mapping
        A fit's ``metrics``.

    Returns
    -------
    str
    """
    cells = metric_cells(metrics)
    return ", ".join(f"{f.label} = {text}" + (f" {f.unit}" if f.unit else "") for f, text in cells)
