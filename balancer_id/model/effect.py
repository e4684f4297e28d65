"""The building block of every model: an :class:`Effect` and its :class:`Param` list.

An effect is a small class around pure, scalar force terms (STYLE.md). It names its
parameters (unit, start value, bounds) and implements one or more *hooks*, each a
``staticmethod`` written in plain scalar Python (only ``math`` and arithmetic, so that
numba can compile it; it also runs as plain Python). The simulator composes the hooks
of all effects of a model into one right-hand side::

    h   = operating_force(t, u, z, v, z_ref, v_ref, *p)   # default: u (the thrust)
    T   = time_constant(h, f, *p)                          # default: T_a
    df  = (h - f) / T
    F   = f + sum(force(f, v, z, h, *p))                   # additive force terms
    F  += friction(v, F, *p)                               # stick-slip, given the other forces
    a   = F / m_a, held at 0 when |v| >= speed_limit(*p) and a pushes outward
    out = output(a, v, z, *p)                              # default: a (what the sensor sees)

and ``input_delay(*p)`` shifts the thrust in time. Each hook receives the effect's own
parameters, in the order of :attr:`Effect.parameters`, after the state arguments.
"""

from __future__ import annotations

import inspect
import math
from dataclasses import dataclass
from typing import Any, ClassVar

from balancer_id.errors import ModelSpecError

#: Hook name -> the state arguments it receives before the effect's own parameters.
HOOKS: dict[str, tuple[str, ...]] = {
    "operating_force": ("t", "u", "z", "v", "z_ref", "v_ref"),
    "time_constant": ("h", "f"),
    "force": ("f", "v", "z", "h"),
    "friction": ("v", "F"),
    "speed_limit": (),
    "input_delay": (),
    "output": ("a", "v", "z"),
}

#: Hooks of which at most one effect of a model may provide.
EXCLUSIVE_HOOKS = ("operating_force", "time_constant", "friction", "speed_limit", "input_delay")


@dataclass(frozen=True)
class Param:
    """One parameter of an effect.

    Parameters
    ----------
    name : str
        The MODEL.md name (``m_a``, ``T_a``, ``D0`` ...); unique in a model.
    value : float
        Start value of a fit and default of a simulation.
    min, max : float
        Bounds of a fit; values outside are refused by :meth:`Effect.check`.
    unit : str
        SI unit, for tables and reports.
    description : str
        One line of meaning.
    drive_lag : bool
        The parameter is a time constant of the drive's lag (``T_a``, ``T_up``,
        ``T_down``): the paper's method's ``T_a`` starts it, and the diagnosis reads the
        first one of a model as its lag.
    needs_thrust_levels : bool
        The parameter is only identifiable from trials at two or more thrust levels
        (``A``); with one level the fit holds it at its start value and says so.
    """

    name: str
    value: float
    min: float
    max: float
    unit: str
    description: str
    drive_lag: bool = False
    needs_thrust_levels: bool = False

    def to_dict(self) -> dict[str, object]:
        """Return the parameter as a JSON-ready dict."""
        return {
            "name": self.name,
            "value": self.value,
            "min": self.min,
            "max": self.max,
            "unit": self.unit,
            "description": self.description,
        }


class Effect:
    """Base class of every physical effect, built in or user-written.

    Subclasses set :attr:`name`, :attr:`summary`, :attr:`parameters` and implement one
    or more hooks (see the module docstring) as ``staticmethod``. The docstring of a
    subclass states its equation and its source.

    Attributes
    ----------
    name : str
        Spec name used in ``--model`` (``variable_viscosity``).
    summary : str
        One line of meaning for ``balancer-id effects``.
    parameters : tuple of Param
        The effect's own parameters.
    excludes : tuple of str
        Effects that cannot be in the same model, with this one.
    replaces : tuple of str
        Base parameters this effect makes meaningless (they are dropped from the model).
    source : str
        Where the equation comes from.
    example : dict
        Typical true values of the effect's parameters (tests, docs, ``simulate``);
        parameters missing here use their start value.
    needs_reference : bool or None
        The effect needs the robot's reference move (``--trajectory``) to be simulated or
        fitted; None (the default) infers it: an effect with an ``operating_force`` hook
        needs it.

    Notes
    -----
    Besides the force hooks, an effect can provide two optional hooks that the fitting
    and the diagnosis call when present; both are plain Python, not compiled:

    ``guess(trials, current) -> dict``
        A ``classmethod``: start values of the effect's own parameters from the data, as
        lmfit's ``Model.guess``. ``trials`` are the fitted trials (``TrialData``: time,
        measured acceleration, thrust), ``current`` the values of the fit the effect is
        added to. The diagnosis starts the effect's quick refit from them (a start
        value the signature check gives wins). Values are clipped into the bounds.
    ``signature(ctx) -> Signature``
        A ``classmethod``: how strongly the residual of a fit without the effect shows
        its footprint (``ctx`` is a
        :class:`~balancer_id.diagnostics.context.DiagnosisContext`, typed as the
        :class:`~balancer_id.model.signature.SignatureContext` it satisfies; return a
        :class:`~balancer_id.model.signature.Signature` with a strength in [0, 1], one
        line of evidence and start values). Every built-in effect but ``viscous`` has
        its own in its module (a test checks it); an effect without one is ranked by
        its refit alone, the residual's correlation with the states as its evidence.

    A new built-in effect is its module in ``balancer_id/model/effects/`` (the class,
    its hooks and its ``signature``), one line in ``balancer_id/model/effects/__init__.py``
    (:data:`~balancer_id.model.effects.BUILTIN_EFFECTS`) and a test (MODEL.md, "Residual
    signatures").
    """

    name: ClassVar[str] = ""
    summary: ClassVar[str] = ""
    parameters: ClassVar[tuple[Param, ...]] = ()
    excludes: ClassVar[tuple[str, ...]] = ()
    replaces: ClassVar[tuple[str, ...]] = ()
    source: ClassVar[str] = ""
    example: ClassVar[dict[str, float]] = {}
    needs_reference: ClassVar[bool | None] = None
    #: Optional ``guess(trials, current)`` classmethod (see Notes); None: no guess.
    guess: ClassVar[Any] = None
    #: Optional ``signature(ctx)`` classmethod (see Notes); None: the generic check.
    signature: ClassVar[Any] = None

    @classmethod
    def needs_reference_move(cls) -> bool:
        """Whether the effect needs the robot's reference move (see :attr:`needs_reference`).

        Returns
        -------
        bool
            The declared :attr:`needs_reference`, or, when undeclared, whether the effect
            has an ``operating_force`` hook.
        """
        if cls.needs_reference is not None:
            return bool(cls.needs_reference)
        return "operating_force" in cls.hooks()

    @classmethod
    def hooks(cls) -> tuple[str, ...]:
        """Names of the hooks this effect implements."""
        return tuple(h for h in HOOKS if callable(getattr(cls, h, None)))

    @classmethod
    def param_names(cls) -> tuple[str, ...]:
        """Names of the effect's own parameters, in hook-argument order."""
        return tuple(p.name for p in cls.parameters)

    @classmethod
    def check(cls, values: dict[str, float]) -> None:
        """Refuse settings outside the parameters' bounds or not finite.

        Parameters
        ----------
        values : dict
            Parameter name -> value; names of other effects are ignored.

        Raises
        ------
        ModelSpecError
            When a value is not finite or outside ``[min, max]``.
        """
        for p in cls.parameters:
            if p.name not in values:
                continue
            x = float(values[p.name])
            if not math.isfinite(x) or x < p.min or x > p.max:
                raise ModelSpecError(
                    f"{cls.name}: {p.name}={values[p.name]} is outside its range "
                    f"[{p.min:g}, {p.max:g}] {p.unit}; give a value inside it"
                )

    @classmethod
    def describe(cls) -> dict[str, object]:
        """Return the effect as a JSON-ready dict (``balancer-id effects --json``)."""
        return {
            "name": cls.name,
            "summary": cls.summary,
            "parameters": [p.to_dict() for p in cls.parameters],
            "hooks": list(cls.hooks()),
            "excludes": list(cls.excludes),
            "replaces": list(cls.replaces),
            "source": cls.source,
            "example": dict(cls.example),
        }

    @classmethod
    def validate_definition(cls) -> None:
        """Check that a (user-written) effect class is well formed.

        Raises
        ------
        ModelSpecError
            When the name, parameters or hooks are missing or malformed.
        """
        label = cls.name or cls.__name__
        if not cls.name or not cls.name.isidentifier():
            raise ModelSpecError(
                f"effect class {cls.__name__}: set a class attribute name = 'snake_case_name'"
            )
        if not cls.hooks():
            raise ModelSpecError(
                f"effect {label}: implement at least one hook ({', '.join(HOOKS)}) "
                "as a staticmethod"
            )
        seen: set[str] = set()
        for p in cls.parameters:
            if not isinstance(p, Param):
                raise ModelSpecError(f"effect {label}: parameters must be Param(...) entries")
            if p.name in seen or not p.name.isidentifier():
                raise ModelSpecError(f"effect {label}: bad or repeated parameter name {p.name!r}")
            if not (p.min <= p.value <= p.max):
                raise ModelSpecError(
                    f"effect {label}: start value of {p.name} ({p.value}) is outside its bounds"
                )
            seen.add(p.name)
        for hook in cls.hooks():
            _check_hook_signature(cls, label, hook)


def _check_hook_signature(cls: type[Effect], label: str, hook: str) -> None:
    """Refuse a hook that is not a staticmethod taking the state, then the parameters."""
    expected = [*HOOKS[hook], *(p.name for p in cls.parameters)]
    wanted = f"@staticmethod def {hook}({', '.join(expected)})"
    if not isinstance(inspect.getattr_static(cls, hook), staticmethod):
        raise ModelSpecError(
            f"effect {label}: hook '{hook}' must be a staticmethod without self: {wanted}"
        )
    try:
        params = list(inspect.signature(getattr(cls, hook)).parameters.values())
    except (TypeError, ValueError):
        return  # a builtin or compiled function: numba will judge it
    kinds = {p.kind for p in params}
    if inspect.Parameter.VAR_POSITIONAL in kinds:
        return
    positional = [
        p
        for p in params
        if p.kind in (p.POSITIONAL_ONLY, p.POSITIONAL_OR_KEYWORD) and p.default is p.empty
    ]
    keyword_only = [p for p in params if p.kind is p.KEYWORD_ONLY and p.default is p.empty]
    if len(positional) != len(expected) or keyword_only:
        got = ", ".join(p.name for p in params)
        raise ModelSpecError(
            f"effect {label}: hook {hook}({got}) takes {len(positional)} argument(s); it must "
            f"take the state ({', '.join(HOOKS[hook]) or 'nothing'}) then the effect's own "
            f"parameters in order: {wanted}"
        )
