"""The table of export layouts a log is recognised as: one line per layout.

Each :class:`Layout` says from the classified header whether a file is its layout and
plans its runs. :func:`~balancer_id.read.reader.read_log` tries them in order; a file no
layout claims is read as a generic CSV (columns guessed from their names, or given by the
column map). A new layout is one module (``detect`` and ``plan``), one line here, one
golden file in ``tests/golden/`` (and its name in
:data:`~balancer_id.read.recording.FORMATS`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

from balancer_id.read.header import Column
from balancer_id.read.pasco import looks_like_pasco, plan_runs
from balancer_id.read.phyphox import looks_like_phyphox, plan_phyphox
from balancer_id.read.plan import RunPlan
from balancer_id.read.sensorlogger import looks_like_sensor_logger, plan_sensor_logger
from balancer_id.read.vernier import looks_like_vernier, plan_vernier


@dataclass(frozen=True)
class Layout:
    """One export layout.

    Attributes
    ----------
    detect : callable
        Header -> the format name (one of ``FORMATS``) when the file is this layout,
        else None.
    plan : callable
        ``(path, header)`` -> the run plans (empty: no force or acceleration found).
    """

    detect: Callable[[list[Column]], str | None]
    plan: Callable[[Path, list[Column]], list[RunPlan]]


def _named(name: str, test: Callable[[list[Column]], bool]) -> Callable[[list[Column]], str | None]:
    return lambda columns: name if test(columns) else None


#: The layouts, tried in this order.
LAYOUTS: tuple[Layout, ...] = (
    Layout(looks_like_pasco, plan_runs),  # pasco-capstone, pasco-sparkvue
    Layout(_named("phyphox", looks_like_phyphox), plan_phyphox),
    Layout(_named("sensor-logger", looks_like_sensor_logger), plan_sensor_logger),
    Layout(_named("vernier", looks_like_vernier), plan_vernier),
)


def detect_layout(path: Path, columns: list[Column]) -> tuple[str, list[RunPlan]]:
    """The first layout that claims the header, and its plans; ``("generic", [])`` if none.

    Parameters
    ----------
    path : pathlib.Path
        The file.
    columns : list of Column
        The classified header.

    Returns
    -------
    tuple
        Format name and run plans.
    """
    for layout in LAYOUTS:
        name = layout.detect(columns)
        if name is not None:
            return name, layout.plan(path, columns)
    return "generic", []
