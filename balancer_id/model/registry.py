"""Where effects come from: the built-ins, installed plug-ins and user effect files.

A :class:`Registry` maps spec names to effect classes. The default registry holds the
built-ins plus every effect that an installed package announces in the entry-point group
``balancer_id.effects``; ``--effects-file FILE.py`` adds the :class:`Effect` subclasses
defined in that file. Callers (and tests) may build their own registry.
"""

from __future__ import annotations

import hashlib
import sys
from collections.abc import Iterable, Iterator
from importlib.metadata import entry_points
from pathlib import Path

from balancer_id.errors import EffectError, ModelSpecError
from balancer_id.files import import_path
from balancer_id.model.effect import Effect

ENTRY_POINT_GROUP = "balancer_id.effects"


class Registry:
    """A name -> effect-class mapping with user extensions.

    Parameters
    ----------
    effects : iterable of Effect subclasses, optional
        The initial effects; by default the built-ins.
    """

    def __init__(self, effects: Iterable[type[Effect]] | None = None) -> None:
        from balancer_id.model.effects import BUILTIN_EFFECTS

        self._effects: dict[str, type[Effect]] = {}
        self._origin: dict[str, str] = {}
        for cls in BUILTIN_EFFECTS.values() if effects is None else effects:
            self.add(cls, origin="built-in")

    def add(self, cls: type[Effect], *, origin: str = "user") -> None:
        """Register one effect class.

        Registering the same class again is allowed; it only updates the recorded origin.

        Parameters
        ----------
        cls : type
            An :class:`~balancer_id.model.effect.Effect` subclass; its definition is
            checked with :meth:`~balancer_id.model.effect.Effect.validate_definition`.
        origin : str
            Where it came from (``built-in``, ``entry point ...``, a file path); shown in
            ``balancer-id effects`` and in error messages.

        Raises
        ------
        ModelSpecError
            When the class is malformed or its name is taken by another effect.
        """
        if not (isinstance(cls, type) and issubclass(cls, Effect)):
            raise ModelSpecError(f"{origin}: {cls!r} is not a subclass of balancer_id.Effect")
        cls.validate_definition()
        known = self._effects.get(cls.name)
        if known is not None and known is not cls:
            raise ModelSpecError(
                f"{origin}: effect name '{cls.name}' is already taken by the "
                f"{self._origin[cls.name]} effect; rename yours"
            )
        self._effects[cls.name] = cls
        self._origin[cls.name] = origin

    def __getitem__(self, name: str) -> type[Effect]:
        try:
            return self._effects[name]
        except KeyError:
            raise ModelSpecError(
                f"unknown effect '{name}'; known effects: {', '.join(self.names())}"
            ) from None

    def __contains__(self, name: object) -> bool:
        return name in self._effects

    def __iter__(self) -> Iterator[type[Effect]]:
        return iter(self._effects.values())

    def names(self) -> list[str]:
        """Spec names of every registered effect."""
        return list(self._effects)

    def origin(self, name: str) -> str:
        """Where an effect came from (``built-in``, ``entry point ...``, a file path).

        Parameters
        ----------
        name : str
            Spec name of a registered effect.

        Returns
        -------
        str

        Raises
        ------
        KeyError
            When no effect of that name is registered.
        """
        return self._origin[name]

    def load_entry_points(self) -> None:
        """Add the effects installed packages announce in ``balancer_id.effects``."""
        for ep in entry_points(group=ENTRY_POINT_GROUP):
            try:
                cls = ep.load()
            except Exception as exc:
                raise EffectError(
                    f"entry point {ep.name} = {ep.value} ({ENTRY_POINT_GROUP}) "
                    f"failed to load: {exc}"
                ) from None
            self.add(cls, origin=f"entry point {ep.value}")

    def load_file(self, path: str | Path) -> list[type[Effect]]:
        """Add every Effect subclass defined in a Python file.

        Parameters
        ----------
        path : str or Path
            A ``.py`` file with one or more ``Effect`` subclasses.

        Returns
        -------
        list of Effect subclasses
            The effects the file defined.

        Raises
        ------
        EffectError
            When the file is missing, fails to import or defines no effect.
        """
        classes = load_effects_file(path)
        for cls in classes:
            self.add(cls, origin=str(Path(path)))
        return classes


def load_effects_file(path: str | Path) -> list[type[Effect]]:
    """Import a user effects file and return the Effect subclasses it defines.

    The module is imported under a name derived from the file's absolute path, so the
    simulator's compiled kernels can import it again in another process.

    Parameters
    ----------
    path : str or Path
        A ``.py`` file.

    Returns
    -------
    list of Effect subclasses
        The subclasses defined in the file itself (not those it imports).

    Raises
    ------
    EffectError
        When the file is missing, fails to import or defines no effect.
    """
    file = Path(path).resolve()
    if not file.is_file():
        raise EffectError(f"{path}: effects file not found; give the path of a .py file")
    module = import_file_module(file)
    classes = [
        obj
        for obj in vars(module).values()
        if isinstance(obj, type)
        and issubclass(obj, Effect)
        and obj is not Effect
        and obj.__module__ == module.__name__
    ]
    if not classes:
        raise EffectError(
            f"{path}: defines no subclass of balancer_id.Effect; "
            "see README 'Writing your own effect'"
        )
    return classes


def module_name_for(file: Path) -> str:
    """The import name used for a user effects file (stable across processes).

    Parameters
    ----------
    file : Path
        The file's absolute path.

    Returns
    -------
    str
        ``balancer_id_user_effects_<stem>_<hash>``, where the hash is taken from the file's
        content (its path when it cannot be read): the compiled kernels name the module
        of their effects, so a copy of the file elsewhere (another folder, a test's
        temporary one) reuses them, and a changed file gets its own.
    """
    try:
        digest = hashlib.sha1(Path(file).read_bytes()).hexdigest()[:12]
    except OSError:
        digest = hashlib.sha1(str(file).encode()).hexdigest()[:12]
    return f"{USER_MODULE_PREFIX}{file.stem}_{digest}"


def import_file_module(file: Path):
    """Import a Python file by path once per process (cached in ``sys.modules``).

    Parameters
    ----------
    file : Path
        The file's absolute path; it is imported under :func:`module_name_for`.

    Returns
    -------
    module
        The imported module.

    Raises
    ------
    EffectError
        When the file cannot be imported; it is then not left in ``sys.modules``.
    """
    import importlib.util

    name = module_name_for(file)
    if name not in sys.modules:  # decided on the spec itself, never on an error's wording
        spec = importlib.util.spec_from_file_location(name, file)
        if spec is None or spec.loader is None:
            raise EffectError(f"{file}: cannot be imported as a Python module")
    try:
        return import_path(name, file)
    except Exception as exc:
        raise EffectError(f"{file}: importing the effects file failed: {exc!r}") from None


USER_MODULE_PREFIX = "balancer_id_user_effects_"


def loaded_effect(module: str, qualname: str) -> type[Effect]:
    """The user effect class ``qualname`` of the effects file loaded in this process as
    ``module`` (see :func:`module_name_for`: named after the file's content).

    A generated kernel takes its user effects from here, so its source does not name
    the file's path: the same effects file in another folder reuses the compiled kernel.

    Parameters
    ----------
    module : str
        The module name the effects file was imported under.
    qualname : str
        The class's qualified name in its file.

    Returns
    -------
    type

    Raises
    ------
    ImportError
        When no such effects file is loaded in this process.
    """
    obj: object = sys.modules.get(module)
    for part in qualname.split("."):
        obj = getattr(obj, part, None)
    if not isinstance(obj, type):
        raise ImportError(f"no effects file loaded in this process defines {module}.{qualname}")
    return obj


def default_registry(effects_files: Iterable[str | Path] = ()) -> Registry:
    """The built-ins, the installed plug-ins and the given effect files.

    Parameters
    ----------
    effects_files : iterable of str or Path
        User effects files to load, in order.

    Returns
    -------
    Registry

    Raises
    ------
    EffectError
        When a plug-in or an effects file fails to load.
    ModelSpecError
        When an effect is malformed or its name is already taken.
    """
    registry = Registry()
    registry.load_entry_points()
    for path in effects_files:
        registry.load_file(path)
    return registry


def describe_effects(effects_files: Iterable[str | Path] = ()) -> list[dict[str, object]]:
    """Every effect available (``balancer-id effects``): the base model first, built in,
    then the plug-ins' and the files', each with its parameters and its origin.

    Parameters
    ----------
    effects_files : iterable of str or Path
        User effects files to load, in order.

    Returns
    -------
    list of dict
        :meth:`Effect.describe` of each, with ``origin``.
    """
    from balancer_id.model.effects.base_model import Base

    registry = default_registry(effects_files)
    items = [{**Base.describe(), "origin": "built-in (always present)"}]
    return items + [{**cls.describe(), "origin": registry.origin(cls.name)} for cls in registry]
