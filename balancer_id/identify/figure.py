"""A matplotlib Figure that shows itself in a notebook, with no pyplot and no backend set.

Results build their figures without pyplot (no GUI, no global state). Jupyter shows a
bare :class:`matplotlib.figure.Figure` as its ``repr`` unless the inline backend was
activated; :class:`NotebookFigure` renders itself as PNG (``_repr_png_``) so that
``fig = result.plot(); fig`` shows the plot in any notebook.
"""

from __future__ import annotations

import io

from matplotlib.backends.backend_agg import FigureCanvasAgg
from matplotlib.figure import Figure

from balancer_id.text import make_figure_text_safe

__all__ = ["NotebookFigure"]


class NotebookFigure(Figure):
    """A Figure on the Agg canvas that Jupyter displays as a PNG image."""

    def __init__(self, *args: object, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        FigureCanvasAgg(self)

    def _repr_png_(self) -> bytes:
        """The figure as PNG bytes (what Jupyter shows).

        Returns
        -------
        bytes
        """
        buffer = io.BytesIO()
        make_figure_text_safe(self).savefig(buffer, format="png", dpi=100)
        return buffer.getvalue()
