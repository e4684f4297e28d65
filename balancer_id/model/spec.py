"""A model: the base plus effects joined by ``+`` (``variable_viscosity+karnopp``)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from balancer_id.errors import ModelSpecError
from balancer_id.model.effect import EXCLUSIVE_HOOKS, Effect, Param
from balancer_id.model.effects.base_model import Base
from balancer_id.model.registry import Registry, default_registry

if TYPE_CHECKING:
    from pathlib import Path

    import lmfit

#: The paper's model and the default of every command.
DEFAULT_SPEC = "variable_viscosity"


@dataclass(frozen=True)
class Model:
    """An ordered set of effects on top of the base, with a flat parameter list.

    Build one with :func:`parse_model`; compose with ``model + "karnopp"``.

    Attributes
    ----------
    effects : tuple of Effect subclasses
        The effects in spec order (the base not included).
    registry : Registry
        Where the effect names were resolved (for composition).
    """

    effects: tuple[type[Effect], ...]
    registry: Registry = field(compare=False, repr=False)

    @property
    def spec(self) -> str:
        """The spec string (``base`` alone for the bare model)."""
        return "+".join(e.name for e in self.effects) or "base"

    @property
    def all_effects(self) -> tuple[type[Effect], ...]:
        """The base followed by the model's effects."""
        return (Base, *self.effects)

    @property
    def params(self) -> tuple[Param, ...]:
        """Every parameter of the model, base first, minus those an effect replaces."""
        replaced = {name for e in self.effects for name in e.replaces}
        return tuple(p for e in self.all_effects for p in e.parameters if p.name not in replaced)

    @property
    def param_names(self) -> tuple[str, ...]:
        """Names of :attr:`params`, in order."""
        return tuple(p.name for p in self.params)

    @property
    def needs_reference_move(self) -> bool:
        """Whether an effect of the model needs the robot's reference move (``servo``)."""
        return any(e.needs_reference_move() for e in self.effects)

    def require_reference_move(self, given: object) -> None:
        """Refuse a model that needs the robot's reference move when none is given.

        Parameters
        ----------
        given : object
            The reference move (None: not given).

        Raises
        ------
        UsageError
            One message, whichever command or function finds it (exit 2).
        """
        if self.needs_reference_move and given is None:
            from balancer_id.errors import UsageError

            names = "+".join(e.name for e in self.effects if e.needs_reference_move())
            raise UsageError(
                f"a model with '{names}' needs the robot's reference move: give --trajectory "
                "'trapezoid:distance=...,speed=...,accel=...' or a CSV of time,position"
            )

    @property
    def drive_lag_names(self) -> tuple[str, ...]:
        """Parameters declared as the drive's lag (``T_a``, or ``T_up`` and ``T_down``)."""
        return tuple(p.name for p in self.params if p.drive_lag)

    @property
    def thrust_level_names(self) -> tuple[str, ...]:
        """Parameters only identifiable from two or more thrust levels (``A``)."""
        return tuple(p.name for p in self.params if p.needs_thrust_levels)

    def drive_lag(self, values: dict[str, float], default: float = 0.3) -> float:
        """The model's drive lag at ``values``: its first drive-lag parameter.

        Parameters
        ----------
        values : dict of str to float
            Parameter values (a fit's).
        default : float
            What to return when the model has no drive-lag parameter (s).

        Returns
        -------
        float
            ``T_a``, or ``T_up`` when an effect replaces it (s).
        """
        for name in self.drive_lag_names:
            if name in values:
                return float(values[name])
        return default

    def param(self, name: str) -> Param:
        """Look up one parameter by name.

        Parameters
        ----------
        name : str
            A parameter name of the model (``m_a``, ``D0`` ...).

        Returns
        -------
        Param

        Raises
        ------
        ModelSpecError
            When the model has no parameter of that name (the message lists those it has).
        """
        for p in self.params:
            if p.name == name:
                return p
        raise ModelSpecError(
            f"model '{self.spec}' has no parameter '{name}'; it has {', '.join(self.param_names)}"
        )

    def has(self, name: str) -> bool:
        """Whether the model includes the effect ``name``.

        Parameters
        ----------
        name : str
            Spec name of an effect (``karnopp``); ``base`` is not counted as an effect.

        Returns
        -------
        bool
        """
        return any(e.name == name for e in self.effects)

    def defaults(self) -> dict[str, float]:
        """Start values of every parameter."""
        return {p.name: p.value for p in self.params}

    def resolve(self, values: Mapping[str, float] | None = None) -> dict[str, float]:
        """Complete ``values`` with defaults, refusing unknown names and bad settings.

        Parameters
        ----------
        values : mapping of str to float, optional
            Parameter name -> value (SI units); parameters not given take their start
            value.

        Returns
        -------
        dict of str to float
            Every parameter of the model, in :attr:`param_names` order.

        Raises
        ------
        ModelSpecError
            When a name is not a parameter of the model or a value is out of range.
        """
        values = dict(values or {})
        full = self.defaults()
        for name, x in values.items():
            self.param(name)  # raises for unknown names
            full[name] = float(x)
        for e in self.all_effects:
            e.check(full)
        return full

    def vector(self, values: Mapping[str, float]) -> list[float]:
        """Values in :attr:`param_names` order (missing names take their defaults).

        Parameters
        ----------
        values : mapping of str to float
            Parameter name -> value (SI units).

        Returns
        -------
        list of float

        Raises
        ------
        ModelSpecError
            When a name is not a parameter of the model or a value is out of range.
        """
        full = self.resolve(values)
        return [full[n] for n in self.param_names]

    def lmfit_parameters(
        self, values: Mapping[str, float] | None = None, fixed: Sequence[str] = ()
    ) -> lmfit.Parameters:
        """The model's parameters as bounded ``lmfit.Parameters``.

        Parameters
        ----------
        values : mapping, optional
            Start values (defaults elsewhere).
        fixed : sequence of str
            Names held constant (``vary=False``).

        Returns
        -------
        lmfit.Parameters
            One parameter per :attr:`params` entry, bounded by its ``min`` and ``max``.

        Raises
        ------
        ModelSpecError
            When a name in ``values`` is not a parameter of the model or a value is out
            of range.
        """
        import lmfit

        full = self.resolve(values)
        params = lmfit.Parameters()
        for p in self.params:
            params.add(p.name, value=full[p.name], min=p.min, max=p.max, vary=p.name not in fixed)
        return params

    def __add__(self, other: str | type[Effect]) -> Model:
        names = [e.name for e in self.effects]
        extra = other if isinstance(other, str) else other.name
        if not isinstance(other, str):
            self.registry.add(other)
        return parse_model("+".join([*names, extra]), self.registry)

    def without(self, name: str) -> Model:
        """The same model without the effect ``name``.

        Parameters
        ----------
        name : str
            Spec name of the effect to drop; a name the model does not have changes
            nothing.

        Returns
        -------
        Model
            A new model on the same registry.
        """
        return Model(tuple(e for e in self.effects if e.name != name), self.registry)


def parse_model(spec: str | None = None, registry: Registry | None = None) -> Model:
    """Build a :class:`Model` from a spec string.

    Parameters
    ----------
    spec : str, optional
        Effects joined by ``+``; ``base`` (or an empty string) is the bare model.
        Default :data:`DEFAULT_SPEC`.
    registry : Registry, optional
        Where names are looked up; default: built-ins plus installed plug-ins.

    Returns
    -------
    Model

    Raises
    ------
    ModelSpecError
        Unknown names (with the list of known ones), repeated effects, effects that
        exclude each other (with the reason) or parameter names that clash.
    """
    if registry is None:
        from balancer_id.model.registry import default_registry

        registry = default_registry()
    spec = DEFAULT_SPEC if spec is None else spec
    raw = spec.replace(" ", "").split("+")
    if spec.strip() and not all(raw):
        raise ModelSpecError(
            f"model '{spec}': an empty effect name; give effects joined by '+', "
            "e.g. viscous+karnopp"
        )
    names = [n for n in raw if n]
    names = [n for n in names if n != "base"]
    effects: list[type[Effect]] = []
    for name in names:
        cls = registry[name]
        if cls in effects:
            raise ModelSpecError(f"model '{spec}': effect '{name}' is given twice")
        effects.append(cls)
    _check_compatible(spec, effects)
    return Model(tuple(effects), registry)


def _check_compatible(spec: str, effects: list[type[Effect]]) -> None:
    names = {e.name for e in effects}
    for e in effects:
        for other in e.excludes:
            if other in names:
                raise ModelSpecError(
                    f"model '{spec}': '{e.name}' and '{other}' exclude each other "
                    f"(both set the same term of the equations); keep one"
                )
    for hook in EXCLUSIVE_HOOKS:
        owners = [e.name for e in effects if hook in e.hooks()]
        if len(owners) > 1:
            raise ModelSpecError(
                f"model '{spec}': {' and '.join(owners)} both set the {hook.replace('_', ' ')}; "
                "keep one"
            )
    seen: dict[str, str] = {p.name: "base" for p in Base.parameters}
    for e in effects:
        for p in e.parameters:
            if p.name in seen and p.name not in e.replaces:
                raise ModelSpecError(
                    f"model '{spec}': parameter '{p.name}' of '{e.name}' clashes with "
                    f"'{seen[p.name]}'; rename it in the effect"
                )
            seen[p.name] = e.name


def resolve_model(
    model: str | Model | None,
    effects_files: Sequence[str | Path] = (),
    registry: Registry | None = None,
) -> Model:
    """A Model from a spec string (loading user effect files) or a ready Model.

    Parameters
    ----------
    model : str or Model or None
        A spec such as ``"viscous+karnopp"``, a ready Model (returned as is), or None for
        the default spec (``variable_viscosity``).
    effects_files : sequence of str or Path
        Python files with user effects; only read when ``registry`` is None.
    registry : Registry, optional
        The registry to resolve effect names in; None builds the default registry plus
        ``effects_files``.

    Returns
    -------
    Model

    Raises
    ------
    ModelSpecError
        When the spec names an unknown effect or an invalid combination.
    """
    if isinstance(model, Model):
        return model
    registry = registry or default_registry(effects_files)
    return parse_model(model or DEFAULT_SPEC, registry)
