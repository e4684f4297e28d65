"""The Python source of a model's kernel, generated from its effects' hooks.

A model's own kernel stitches its hooks into the templates of
:mod:`balancer_id.simulation.kernel_templates`; the models of the built-in effects share a
few kernels whose layout holds every switchable effect (:func:`shared_places`).
"""

from __future__ import annotations

import functools
import importlib.util
import sys
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

from balancer_id.model.effect import Effect
from balancer_id.model.registry import USER_MODULE_PREFIX
from balancer_id.model.spec import Model
from balancer_id.simulation.kernel_templates import (
    _FRICTION_EVENT,
    _INTEGRATOR,
    _LIMIT_CLAMP,
    _TEMPLATE,
    _VARIANTS,
    REL_STEP,
    SPEED_LIMIT_TAU,
    _variant,
)


def _import_line(alias: str, cls: type[Effect]) -> str | None:
    """A line importing ``cls`` by name in a fresh process, or None when impossible."""
    module = sys.modules.get(cls.__module__)
    if "<locals>" in cls.__qualname__ or module is None:
        return None
    if cls.__module__.startswith(USER_MODULE_PREFIX):
        # named by its file's content, not its path: the same file elsewhere (a copy, a
        # test's temporary folder) reuses the compiled kernel
        return (
            "from balancer_id.model.registry import loaded_effect as _loaded\n"
            f"{alias} = _loaded({cls.__module__!r}, {cls.__qualname__!r})"
        )
    if cls.__module__ == "__main__":
        return None
    try:
        if importlib.util.find_spec(cls.__module__) is None:
            return None
    except (ImportError, ValueError):
        return None
    return f"from {cls.__module__} import {cls.__qualname__.split('.')[0]} as {alias}" + (
        "" if "." not in cls.__qualname__ else f"\n{alias} = {alias}.{cls.__qualname__[1:]}"
    )


def _args(model: Model, cls: type[Effect]) -> str:
    index = {n: i for i, n in enumerate(model.param_names)}
    return "".join(f", p[{index[p.name]}]" for p in cls.parameters if p.name in index)


def generate_source(model: Model, *, cache: bool) -> tuple[str, dict[str, type[Effect]]]:
    """Write the kernel source of ``model``.

    Parameters
    ----------
    model : Model
        The model whose effects' hooks are stitched into the kernel.
    cache : bool
        True writes a module for disk caching: each effect is imported by name and the
        kernels are compiled with ``cache=True``. An effect that cannot be imported by
        name is then only named in a comment ``(in memory)``. False leaves every effect
        to be supplied through ``aliases`` in the namespace the source is run in.

    Returns
    -------
    source : str
        The module's source.
    aliases : dict
        Alias -> effect class, for in-memory compilation.

    Raises
    ------
    ValueError
        When an effect replaces ``T_a`` but no effect provides the ``time_constant``
        hook.
    """
    index = {n: i for i, n in enumerate(model.param_names)}
    layout = _Layout(
        spec=model.spec,
        effects=model.effects,
        args={cls: _args(model, cls) for cls in model.effects},
        switches={},
        mass=f"p[{index['m_a']}]",
        lag=f"p[{index['T_a']}]" if "T_a" in index else None,
        config_size=0,
    )
    return _assemble(layout, cache=cache)


@dataclass(frozen=True)
class _Layout:
    """How a kernel's source reaches its effects: which effects, each hook's parameter
    arguments, the switch that turns an effect on (1.0) or off (0.0; none: always on), the
    mass and the lag.
    """

    spec: str
    effects: tuple[type[Effect], ...]
    args: dict[type[Effect], str]
    switches: dict[type[Effect], str]
    mass: str
    lag: str | None
    config_size: int


@dataclass
class _Pieces:
    """The lines and expressions of a kernel, collected effect by effect."""

    h_lines: list[str] = field(default_factory=list)
    t_lines: list[str] = field(default_factory=list)
    force_lines: list[str] = field(default_factory=list)
    friction_lines: list[str] = field(default_factory=list)
    event_lines: list[str] = field(default_factory=list)
    limit_lines: str = ""
    vmax_of_expr: str = "0.0"
    delay_expr: str = "0.0"
    output_expr: str = "a"

    def add(self, alias: str, hooks: Sequence[str], a: str, switch: str | None) -> None:
        """The calls of one effect's hooks (``a``: its parameter arguments; ``switch``: the
        parameter that turns it on in a shared kernel)."""
        guard = None if switch is None else f"{switch} > 0.5"
        on = "" if switch is None else f"{switch} * "
        if "operating_force" in hooks:
            self.h_lines.append(f"    h = {alias}_operating_force(t, u, z, v, zr, vr{a})")
        if "time_constant" in hooks:
            self.t_lines.append(f"    T = {alias}_time_constant(h, f{a})")
        if "force" in hooks:
            self.force_lines.append(f"    F += {on}{alias}_force(f, v, z, h{a})")
        if "friction" in hooks:
            self.friction_lines.append(f"    F += {alias}_friction(v, F{a})")
            self.event_lines.append(_FRICTION_EVENT)
        if "speed_limit" in hooks:
            vmax = f"{alias}_speed_limit({a[2:]})"
            self.limit_lines = _speed_limit_lines(vmax)
            self.event_lines.append(_LIMIT_CLAMP)
            self.vmax_of_expr = vmax
        if "input_delay" in hooks:
            delay = f"{alias}_input_delay({a[2:]})"
            before = self.delay_expr
            self.delay_expr = delay if guard is None else f"({delay} if {guard} else {before})"
        if "output" in hooks:
            out = f"{alias}_output({self.output_expr}, v, z{a})"
            before = self.output_expr
            self.output_expr = out if guard is None else f"({out} if {guard} else {before})"


def _speed_limit_lines(vmax: str) -> str:
    """The right-hand side's approach to the speed limit ``vmax`` (smooth in every parameter)."""
    return (
        f"    vm = {vmax}\n"
        "    if a * v > 0.0:\n"
        "        gap = vm - abs(v)\n"
        f"        band = {2.0 * SPEED_LIMIT_TAU!r} * abs(a)\n"
        "        if gap < band:\n"
        "            if gap <= 0.0:\n"
        "                a = 0.0\n"
        "            else:\n"
        "                x = gap / band\n"
        "                a = a * x * (2.0 - x)"
    )


def _assemble(layout: _Layout, *, cache: bool) -> tuple[str, dict[str, type[Effect]]]:
    """The kernel module's source for ``layout`` (see :func:`generate_source`)."""
    aliases: dict[str, type[Effect]] = {}
    imports: list[str] = []
    hook_defs: list[str] = []
    pieces = _Pieces(t_lines=[f"    T = {layout.lag}"] if layout.lag else [])
    for j, cls in enumerate(layout.effects):
        alias = f"_E{j}"
        aliases[alias] = cls
        line = _import_line(alias, cls) if cache else None
        imports.append(line or f"# {alias} = {cls.__module__}.{cls.__qualname__} (in memory)")
        for hook in cls.hooks():
            hook_defs.append(f"{alias}_{hook} = jit({alias}.{hook})")
        # a switched hook's value is chosen without a branch around the call (a branch
        # there keeps the compiler from folding the right-hand side into RK4: 4x slower);
        # structural hooks cannot be switched so (see _STRUCTURAL_HOOKS)
        switch = layout.switches.get(cls)
        if switch is not None and _is_structural(cls):
            raise ValueError(f"effect '{cls.name}' has a structural hook: it cannot be switched")
        pieces.add(alias, cls.hooks(), layout.args[cls], switch)
    if not pieces.t_lines:
        raise ValueError(
            f"model '{layout.spec}' replaces T_a but no effect sets the time constant"
        )
    fields: dict[str, Any] = {
        "cache": "True" if cache else "False",
        "delay_expr": pieces.delay_expr,
        "output_expr": pieces.output_expr,
        "config_size": f" - {layout.config_size}" if layout.config_size else "",
        "ref_slopes": (
            "            szr = (zref[i] - zref[i - 1]) / (t - t0)\n"
            "            svr = (vref[i] - vref[i - 1]) / (t - t0)"
            if pieces.h_lines
            else "            szr = 0.0\n            svr = 0.0"
        ),
    }
    integrators = _integrators(fields, pieces)
    source = _TEMPLATE.format(
        **fields,
        spec=layout.spec,
        imports="\n".join(imports),
        hook_defs="\n".join(hook_defs),
        h_line="\n".join(pieces.h_lines),
        t_line="\n".join(pieces.t_lines),
        force_lines="\n".join(pieces.force_lines),
        friction_line="\n".join(pieces.friction_lines),
        m_expr=layout.mass,
        limit_lines=pieces.limit_lines,
        vmax_of_expr=pieces.vmax_of_expr,
        rel_step=REL_STEP,
        integrator=integrators[False],
        integrator_sens=integrators[True],
    )
    return source, aliases


def _integrators(fields: dict[str, Any], pieces: _Pieces) -> dict[bool, str]:
    """The RK4 integrator's source, plain (False) and with sensitivities (True)."""
    integrators = {}
    for sens, names in _VARIANTS.items():
        events = "\n".join(
            _variant(e, sens).format(vmax_expr=pieces.vmax_of_expr, **names)
            for e in pieces.event_lines
        )
        save = sens and bool(pieces.friction_lines)  # the step's start, for a friction event
        integrators[sens] = _variant(_INTEGRATOR, sens).format(
            **fields,
            **names,
            event_lines=events,
            save_sens=(
                "    for r in range(3):\n"
                "        for c in range(nc):\n"
                "            S0[r, c] = S[r, c]"
                if save
                else ""
            ),
        )
    return integrators


def _shared_effects() -> tuple[type[Effect], ...]:
    """The built-in effects, in the order of the kernels they share (the base first)."""
    from balancer_id.model.effects import BUILTIN_EFFECTS, Base

    return (Base, *BUILTIN_EFFECTS.values())


#: Hooks that cannot be switched off without a branch in every evaluation of the
#: right-hand side or every step (a shared kernel holding one of them switched off runs
#: 2-8x slower): an effect with one of them is compiled, always on, into the shared
#: kernels of the models that have it.
_STRUCTURAL_HOOKS = ("operating_force", "time_constant", "friction", "speed_limit")


def _is_structural(cls: type[Effect]) -> bool:
    return any(h in _STRUCTURAL_HOOKS for h in cls.hooks())


@functools.cache
def _shared_names() -> tuple[str, ...]:
    """Every parameter name of the built-in effects, in the shared kernels' order."""
    return tuple(dict.fromkeys(q.name for cls in _shared_effects() for q in cls.parameters))


def _switched_effects() -> tuple[type[Effect], ...]:
    """The built-in effects every shared kernel holds, each behind its switch."""
    return tuple(c for c in _shared_effects()[1:] if not _is_structural(c))


@functools.cache
def _shared_layout(fixed: tuple[type[Effect], ...]) -> _Layout:
    """The layout of the kernel shared by every model whose effects that cannot be
    switched are ``fixed``: its built-in effects with a structural hook and its user
    effects.

    Its parameter vector holds every parameter name of the built-in effects (one place
    per name: a name means one thing in any model), those of the user effects in
    ``fixed``, then one switch (1.0 on, 0.0 off) per built-in effect without a structural
    hook. A switched force counts times its switch and a switched output or delay is
    chosen by it, without a branch, so one compiled kernel serves every combination of
    them as fast as a model's own kernel; ``fixed`` are always on.
    """
    names = _layout_names(fixed)
    place = {name: i for i, name in enumerate(names)}
    switched = _switched_effects()
    built_in = _shared_effects()[1:]
    effects = tuple(c for c in built_in if c in switched or c in fixed)
    effects += tuple(c for c in fixed if c not in built_in)
    return _Layout(
        spec="+".join(c.name for c in effects) + " (shared; switched: "
        + ", ".join(c.name for c in switched) + ")",
        effects=effects,
        args={
            cls: "".join(f", p[{place[q.name]}]" for q in cls.parameters) for cls in effects
        },
        switches={cls: f"p[{len(names) + j}]" for j, cls in enumerate(switched)},
        mass=f"p[{place['m_a']}]",
        lag=f"p[{place['T_a']}]",
        config_size=len(switched),
    )


def _layout_names(fixed: tuple[type[Effect], ...]) -> tuple[str, ...]:
    """The parameter places of the shared kernel with the effects ``fixed``."""
    user = [q.name for c in fixed if c not in _shared_effects() for q in c.parameters]
    return tuple(dict.fromkeys([*_shared_names(), *user]))


@dataclass(frozen=True)
class SharedPlaces:
    """Where a model's parameters sit in the parameter vector of its shared kernel.

    Attributes
    ----------
    template : numpy.ndarray
        The shared vector: the model's effects switched on, every parameter at its start
        value (an effect switched off stays finite).
    places : numpy.ndarray
        The place of each of the model's parameters (``model.param_names`` order).
    n_names : int
        How many parameter places the vector has before its switches.
    fixed : tuple of Effect subclasses
        The model's effects that cannot be switched (built-in ones with a structural
        hook, user ones): which shared kernel it runs on.
    """

    template: Any
    places: Any
    n_names: int
    fixed: tuple[type[Effect], ...]

    def parameters(self, values: Any) -> Any:
        """The shared vector holding the model's parameters.

        Parameters
        ----------
        values : numpy.ndarray
            The model's parameters, in ``model.param_names`` order.

        Returns
        -------
        numpy.ndarray
        """
        out = self.template.copy()
        out[self.places] = values
        return out

    def columns(self, cols: Any) -> Any:
        """The shared kernel's sensitivity columns for the model's.

        Parameters
        ----------
        cols : numpy.ndarray
            Columns of the model: its parameters, then ``n + 0, 1, 2`` for the initial
            state (``n`` parameters).

        Returns
        -------
        numpy.ndarray
        """
        import numpy as np

        cols = np.asarray(cols, dtype=np.int64)
        n = self.places.size
        return np.where(cols < n, self.places[np.minimum(cols, n - 1)], cols - n + self.n_names)


def shared_places(model: Model) -> SharedPlaces | None:
    """Where ``model``'s parameters sit in its shared kernel, or None when it cannot share
    one and gets a kernel of its own.

    A model shares the kernel of its effects that cannot be switched (its built-in effects
    with a structural hook, and its user effects) with every model that has the same ones.
    A user effect that cannot be imported by name (defined inside a function), has an
    ``output`` hook (the order of outputs matters) or names a parameter as a built-in
    effect that can be switched does not share.

    Parameters
    ----------
    model : Model
        The model.

    Returns
    -------
    SharedPlaces or None
    """
    import numpy as np

    effects = _shared_effects()
    switched = _switched_effects()
    switched_names = {q.name for c in switched for q in c.parameters}
    for cls in model.effects:
        if cls in effects:
            continue
        if (
            "output" in cls.hooks()
            or any(q.name in switched_names for q in cls.parameters)
            or _import_line("_E", cls) is None
        ):
            return None
    fixed = tuple(c for c in effects if c in model.effects and _is_structural(c))
    fixed += tuple(c for c in model.effects if c not in effects)
    names = _layout_names(fixed)
    place = {name: i for i, name in enumerate(names)}
    template = np.zeros(len(names) + len(switched))
    for cls in reversed((*effects, *fixed)):  # an effect that is off sees its start values
        for q in cls.parameters:
            template[place[q.name]] = q.value
    for cls in model.effects:
        if cls in switched:
            template[len(names) + switched.index(cls)] = 1.0
    places = np.array([place[name] for name in model.param_names], dtype=np.int64)
    return SharedPlaces(template, places, len(names), fixed)
