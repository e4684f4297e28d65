"""Different drive lags for upward and downward motion."""

from __future__ import annotations

from balancer_id.model.effect import Effect, Param
from balancer_id.model.signature import Signature, SignatureContext, clip01


class AsymmetricLag(Effect):
    """The drive lag depends on the direction the drive force moves (paper Fig. 8)::

        T = T_up    if h - f >= 0 (drive force rising: upward push)
        T = T_down  otherwise

    Replaces the base ``T_a``.
    """

    name = "asymmetric_lag"
    summary = "separate drive lags T_up and T_down for upward and downward pushes (Fig. 8)"
    source = "paper III.A, Fig. 8"
    replaces = ("T_a",)
    example = {"T_up": 0.3, "T_down": 0.38}
    parameters = (
        Param("T_up", 0.3, 0.0005, 10.0, "s", "drive lag while the drive force rises", True),
        Param("T_down", 0.3, 0.0005, 10.0, "s", "drive lag while the drive force falls", True),
    )

    @staticmethod
    def time_constant(h: float, f: float, T_up: float, T_down: float) -> float:
        return T_up if h - f >= 0.0 else T_down

    @classmethod
    def signature(cls, ctx: SignatureContext) -> Signature:
        """The rise is too fast one way and too slow the other.

        Parameters
        ----------
        ctx : SignatureContext
            The fit and its residuals, trial by trial.

        Returns
        -------
        Signature
            Strength in [0, 1], the evidence in words and numbers, and the start values of
            ``T_up`` and ``T_down``: the current ``T_a`` (s).
        """
        import numpy as np

        by_dir: dict[str, list[float]] = {"up": [], "down": []}
        for tv in ctx.trials:
            m = tv.regimes["rise"]
            if m.sum() >= 5:
                by_dir[tv.data.direction].append(
                    float(np.mean(tv.residual[m]) * np.sign(tv.data.thrust_N))
                )
        if not by_dir["up"] or not by_dir["down"]:
            return Signature(0.0, "needs trials in both directions")
        up, down = np.mean(by_dir["up"]), np.mean(by_dir["down"])
        n = len(by_dir["up"]) + len(by_dir["down"])
        sigma = ctx.noise_floor / np.sqrt(max(30 * n / 2, 1))
        contrast = abs(up - down) / sigma
        opposite = np.sign(up) != np.sign(down)
        T = ctx.match.values().get("T_a", 0.3)
        return Signature(
            clip01((contrast - 3) / 10) * (1.0 if opposite else 0.3),
            f"during the rise the residual (along the thrust) is {up:+.4f} m/s^2 going up and "
            f"{down:+.4f} m/s^2 going down",
            {"T_up": T, "T_down": T},
        )
