"""The layout and column decisions of a read, said with what they rest on.

:func:`layout_inference` and :func:`columns_inference` turn the choice of layout and the
run plans into :class:`~balancer_id.read.inference.Inference` objects for ``inspect``.
"""

from __future__ import annotations

from balancer_id.read.header import Column
from balancer_id.read.inference import Inference
from balancer_id.read.plan import RunPlan

#: What each layout is recognised by (its header), for the ``layout`` inference.
_LAYOUT_SIGNS = {
    "pasco-capstone": "run suffixes 'Run #N' or a shared 'Time (s) Auto'",
    "pasco-sparkvue": "a 'Date and Time <run>' column beside 'Time (s) <run>'",
    "phyphox": "'Time (s)' first, no run suffix, units written 'm/s^2' or numbers written "
    "as phyphox writes them (1.005775000E-2)",
    "sensor-logger": "'seconds_elapsed' with bare x, y, z columns",
    "vernier": "every column prefixed by its data set ('Run 1: Time (s)')",
}


def layout_inference(fmt: str, header: list[Column], columns: dict[str, str] | None) -> Inference:
    """The ``layout`` inference: which export the header was recognised as.

    Parameters
    ----------
    fmt : str
        The format read.
    header : list of Column
        The classified header.
    columns : dict or None
        The user's column map, if any.

    Returns
    -------
    Inference
    """
    if columns:
        return Inference("layout", fmt, "columns given in the column map")
    if fmt in _LAYOUT_SIGNS:
        return Inference("layout", fmt, "the header has " + _LAYOUT_SIGNS[fmt], "--columns ...")
    named = [c.raw for c in header if c.kind in ("time", "force", "accel")]
    return Inference(
        "layout",
        "generic",
        "no export layout claims the header; columns recognised by their names: "
        + ", ".join(repr(n) for n in named[:8]),
        "--columns time=...,force=...,ax=...,ay=...,az=...",
    )


def columns_inference(
    plan: RunPlan, header: list[Column], fmt: str, columns: dict[str, str] | None
) -> Inference:
    """The ``columns`` inference of a run: which column is time, force, each axis.

    Parameters
    ----------
    plan : RunPlan
        The run's plan.
    header : list of Column
        The classified header.
    fmt : str
        The format read.
    columns : dict or None
        The user's column map, if any.

    Returns
    -------
    Inference
    """
    names = {c.index: c.raw for c in header}
    roles = [f"time={names[plan.time]}"]
    if plan.force is not None:
        roles.append(f"force={names[plan.force]}")
    axes = ["a"] if len(plan.accel) == 1 else [f"a{a}" for a in plan.accel_axes]
    roles += [f"{r}={names[c]}" for r, c in zip(axes, plan.accel, strict=True)]
    if len(plan.accel) == 1:
        roles[-1] += " (one axis, taken as vertical)"
    if columns:
        return Inference("columns", ", ".join(roles), "given in the column map", run=plan.name)
    left = [names[i] for i in plan.extra.values()]
    evidence = "recognised by their names"
    if fmt != "generic":
        evidence += f" in the {fmt} layout"
    if left:
        evidence += "; kept as extra channels: " + ", ".join(repr(n) for n in left[:6])
    ignored = [
        c.raw
        for c in header
        if c.index not in plan.columns and c.kind in ("accel", "force", "ignore", "other")
    ]
    if ignored and fmt == "generic":
        evidence += "; not read: " + ", ".join(repr(n) for n in ignored[:6])
    return Inference(
        "columns",
        ", ".join(roles),
        evidence,
        "--columns time=...,force=...,ax=...,ay=...,az=... (or a=...)",
        run=plan.name,
    )
