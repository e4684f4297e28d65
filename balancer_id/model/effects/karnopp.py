"""Karnopp stick-slip friction."""

from __future__ import annotations

from balancer_id.constants import KARNOPP_EPS
from balancer_id.model.effect import Effect, Param


class Karnopp(Effect):
    """Karnopp friction, paper eqs. (3)-(5), with ``f_d = f_s``::

        friction = -F              if |v| <= eps and |F| <= f_s   (stuck)
                 = -sgn(F) f_s     if |v| <= eps and |F| >  f_s   (break-away)
                 = -sgn(v) f_d     otherwise                       (sliding)

    ``F`` is the sum of all other forces on the load and ``eps = 1e-6`` m/s. The
    simulator snaps ``v`` to zero where it changes sign, so a load sticks without
    chattering. A thrust below ``f_s`` produces no motion.
    """

    name = "karnopp"
    summary = "stick-slip friction f_s = f_d with a zero-velocity band (paper eqs. 3-5)"
    source = "paper III.C, eqs. (3)-(5); Karnopp (1985)"
    example = {"f_s": 0.98}
    parameters = (Param("f_s", 1.0, 0.0, 1e5, "N", "static (= dynamic) friction force"),)

    @staticmethod
    def friction(v: float, F: float, f_s: float) -> float:
        if abs(v) <= KARNOPP_EPS:
            if abs(F) <= f_s:
                return -F
            return -f_s if F > 0.0 else f_s
        return -f_s if v > 0.0 else f_s
