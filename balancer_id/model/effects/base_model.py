"""The base of every model: virtual mass with a first-order drive lag."""

from __future__ import annotations

from balancer_id.model.effect import Effect, Param


class Base(Effect):
    """Virtual equivalent mass ``m_a`` driven through a first-order lag ``T_a``.

    Equations (MODEL.md; paper section III.A and eq. 1)::

        T_a df/dt = u - f
        m_a dv/dt = f + (other effects)

    The step response of the acceleration rises to ``a_zc = f_in / m_a`` with time
    constant ``T_a`` (95 % at ``3 T_a``). The base is implied in every model; its
    terms live in the simulator itself, so it implements no hook.
    """

    name = "base"
    summary = "virtual mass m_a with first-order drive lag T_a (always present)"
    source = "paper III.A, eq. (1)"
    example = {"m_a": 15.1, "T_a": 0.33}
    parameters = (
        Param("m_a", 15.0, 0.01, 1e5, "kg", "virtual equivalent mass"),
        Param(
            "T_a", 0.3, 0.0005, 10.0, "s", "time constant of the drive's first-order lag",
            drive_lag=True,
        ),
    )
