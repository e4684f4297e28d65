"""A slow, independent reference: the same right-hand side through ``scipy.integrate.solve_ivp``.

Used by the tests (agreement within 1e-3) and by the benchmarks (the speed ratio). The
right-hand side is the generated one run as plain Python; integration is adaptive
(DOP853 by default) between the thrust's breakpoints.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping

import numpy as np
from scipy.integrate import solve_ivp

from balancer_id.model.spec import Model
from balancer_id.simulation.engine import Simulation, TrialInput
from balancer_id.simulation.kernel import generate_source

_PLAIN_JIT = "def jit(f=None, **kw):\n    return f if f is not None else (lambda g: g)\n"


def python_rhs(model: Model):
    """The model's right-hand side ``rhs(t, f, v, z, u, zr, vr, p)`` as plain Python.

    Parameters
    ----------
    model : Model
        The model; its generated kernel source is run without numba.

    Returns
    -------
    callable
        ``rhs(t, f, v, z, u, zr, vr, p)`` of the generated kernel, where ``p`` is the
        parameter vector in ``model.param_names`` order.
    """
    source, aliases = generate_source(model, cache=False)
    source = source.replace("from balancer_id.simulation.jit import jit\n", _PLAIN_JIT)
    namespace: dict[str, object] = dict(aliases)
    exec(compile(source, "<balancer_id reference rhs>", "exec"), namespace)
    return namespace["rhs"]


def _delay(model: Model, values: dict[str, float]) -> float:
    for e in model.effects:
        if "input_delay" in e.hooks():
            hook = e.input_delay  # type: ignore[attr-defined]
            return float(hook(*[values[p.name] for p in e.parameters]))
    return 0.0


def _output(model: Model, values: dict[str, float], a: float, v: float, z: float) -> float:
    for e in model.effects:
        if "output" in e.hooks():
            hook = e.output  # type: ignore[attr-defined]
            a = hook(a, v, z, *[values[p.name] for p in e.parameters])
    return a


def simulate_reference(
    model: Model,
    params: Mapping[str, float],
    trial: TrialInput,
    *,
    method: str = "DOP853",
    rtol: float = 1e-10,
    atol: float = 1e-12,
    max_step: float = np.inf,
) -> Simulation:
    """Simulate one trial with ``solve_ivp`` (slow; for checks and benchmarks).

    Parameters
    ----------
    model : Model
        The model.
    params : mapping
        Parameter values (defaults for missing ones).
    trial : TrialInput
        Times, thrust and reference.
    method, rtol, atol, max_step
        Passed to :func:`scipy.integrate.solve_ivp`.

    Returns
    -------
    Simulation
    """
    values = model.resolve(params)
    pvec = np.array([values[n] for n in model.param_names])
    rhs = python_rhs(model)
    t_out = np.asarray(trial.time, float)
    zref = np.zeros_like(t_out) if trial.z_ref is None else np.asarray(trial.z_ref, float)
    vref = np.zeros_like(t_out) if trial.v_ref is None else np.asarray(trial.v_ref, float)
    delay = _delay(model, values)
    breaks = trial.thrust.times + delay
    edges = np.unique(
        np.concatenate(
            [[t_out[0]], breaks[(breaks > t_out[0]) & (breaks < t_out[-1])], [t_out[-1]]]
        )
    )
    state = np.zeros(3)
    out = np.zeros((t_out.size, 5))

    def u_at(t: float) -> float:
        k = np.searchsorted(breaks, t, side="right") - 1
        return float(trial.thrust.values[k]) if k >= 0 else 0.0

    for k, (a, b) in enumerate(itertools.pairwise(edges)):
        u = u_at(a)

        def fun(t: float, x: np.ndarray, u: float = u) -> list[float]:
            zr = float(np.interp(t, t_out, zref))
            vr = float(np.interp(t, t_out, vref))
            df, acc, _ = rhs(t, x[0], x[1], x[2], u, zr, vr, pvec)
            return [df, acc, x[1]]

        last = k == edges.size - 2
        inside = np.flatnonzero((t_out >= a) & ((t_out <= b) if last else (t_out < b)))
        t_eval = np.unique(np.concatenate([t_out[inside], [b]]))
        sol = solve_ivp(
            fun,
            (a, b),
            state,
            method=method,
            rtol=rtol,
            atol=atol,
            max_step=max_step,
            t_eval=t_eval,
        )
        for i in inside:
            f, v, z = sol.y[:, int(np.searchsorted(sol.t, t_out[i]))]
            _, acc, h = rhs(t_out[i], f, v, z, u_at(t_out[i]), zref[i], vref[i], pvec)
            out[i] = (_output(model, values, acc, v, z), v, z, f, h)
        state = sol.y[:, -1]
    return Simulation(t_out, out[:, 0], out[:, 1], out[:, 2], out[:, 3], out[:, 4])
