"""A user effect: a supply hose (or spring cable) that pulls the load back to its start height.

Not built into balancer-id. Load it with ``--effects-file examples/effects/hose_spring.py``
and use it in a model as ``--model variable_viscosity+hose_spring``.
"""

from balancer_id import Effect, Param


class HoseSpring(Effect):
    """Restoring force of a hose hanging from the load: ``F = -k_h * z``.

    ``z`` is the load's travel since the start of the trial (m, up positive). The
    residual of a model without it grows with the travel, up and down alike.
    """

    name = "hose_spring"
    summary = "a hose or spring cable pulls the load back to its start height, F = -k_h z"
    source = "user example (README: 'Writing your own effect')"
    parameters = (Param("k_h", 2.0, 0.0, 200.0, "N/m", "stiffness of the hose"),)
    example = {"k_h": 4.0}

    @staticmethod
    def force(f, v, z, h, k_h):
        return -k_h * z
