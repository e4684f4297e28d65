"""Parameters tracked in time within a session (``fit --track``): the report's section."""

from __future__ import annotations

from typing import TYPE_CHECKING

from balancer_id.identify.tracking_plot import plot_tracking
from balancer_id.report.blocks import Paragraph, Plot, Section

if TYPE_CHECKING:
    from balancer_id.identify.tracking import Tracking


def tracking_section(tracking: Tracking) -> Section:
    """The report's section on the tracked parameters.

    Parameters
    ----------
    tracking : Tracking
        ``FitResult.tracking``.

    Returns
    -------
    Section
    """
    from balancer_id.identify.tracking import tracking_lines

    lines = tracking_lines(tracking.to_dict())
    return Section(
        "Parameters in time",
        blocks=[
            *(Paragraph(line.strip()) for line in lines),
            Plot(
                plot_tracking(tracking),
                "Each tracked parameter against time within the session: the curve and "
                "its 95 % band (a random walk through the blocks' own fits, its variance "
                "chosen by likelihood), the blocks' own estimates (± 95 %) and, dashed, "
                "the single value a fit over the whole session gives.",
            ),
        ],
    )
