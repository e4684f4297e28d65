"""Every public function and method has a docstring naming each of its arguments.

The test walks every module of :mod:`balancer_id` and checks each public function defined
there and each public method or property of a public class defined there: a docstring must
exist and, when the callable takes arguments besides ``self``/``cls``, its numpydoc
``Parameters`` section must name every one of them (``name : type`` or
``name1, name2 : type`` lines; ``*args``/``**kwargs`` spelled with their stars). A new
undocumented argument fails here, and the failure lists every offender at once.

Left out: :mod:`balancer_id.cli`, whose typer commands document their options through
``help=``, the hook staticmethods of the effects in :mod:`balancer_id.model.effects`,
whose equation is the class docstring, and a method that overrides one of a base class
whose docstring is complete for the same arguments (documented once, where the contract is
stated: an explanation kind's ``propose`` or ``sentence``).
"""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re
from collections.abc import Callable, Iterator
from types import ModuleType

import balancer_id
from balancer_id.model.effect import HOOKS, Effect

SKIP_MODULES = {"balancer_id.cli"}
EFFECTS_PACKAGE = "balancer_id.model.effects."

#: A numpydoc section header: a title line underlined by dashes.
_SECTION = re.compile(r"^(\S[^\n]*)\n-{3,}[ \t]*$", re.MULTILINE)


def _modules() -> Iterator[ModuleType]:
    """Import and yield every module of the package except the ones left out."""
    yield balancer_id
    for info in pkgutil.walk_packages(balancer_id.__path__, "balancer_id."):
        if not any(info.name == m or info.name.startswith(m + ".") for m in SKIP_MODULES):
            yield importlib.import_module(info.name)


def _public(name: str) -> bool:
    return not name.startswith("_")


def _callables(module: ModuleType) -> Iterator[tuple[str, Callable, bool]]:
    """Yield ``(qualified name, function, drops first argument)`` for the module's API."""
    for name, obj in vars(module).items():
        if not _public(name):
            continue
        if inspect.isfunction(obj) and obj.__module__ == module.__name__:
            yield name, obj, False
        elif inspect.isclass(obj) and obj.__module__ == module.__name__:
            yield from _methods(module, obj)


def _methods(module: ModuleType, cls: type) -> Iterator[tuple[str, Callable, bool]]:
    """Yield the public methods (and properties) a class defines itself, not inherited ones."""
    is_effect = issubclass(cls, Effect) and module.__name__.startswith(EFFECTS_PACKAGE)
    for name, member in vars(cls).items():
        if not _public(name) or (is_effect and name in HOOKS):
            continue
        if isinstance(member, staticmethod):
            func, bound = member.__func__, False
        elif isinstance(member, classmethod):
            func, bound = member.__func__, True
        elif isinstance(member, property) and member.fget is not None:
            func, bound = member.fget, True
        elif inspect.isfunction(member):
            func, bound = member, True
        else:
            continue
        if inspect.isfunction(func) and func.__module__ == module.__name__:
            if _documented_by_base(cls, name, func, bound):
                continue
            yield f"{cls.__name__}.{name}", func, bound


def _documented_by_base(cls: type, name: str, func: Callable, bound: bool) -> bool:
    """Whether a base class defines ``name`` with the same arguments and a complete
    docstring (the override is documented there)."""
    for base in cls.__mro__[1:]:
        member = vars(base).get(name)
        if member is None:
            continue
        parent = getattr(member, "__func__", None) or getattr(member, "fget", None) or member
        if not inspect.isfunction(parent):
            return False
        same = _arguments(parent, bound) == _arguments(func, bound)
        return same and _offences(parent, bound) is None
    return False


def _arguments(func: Callable, bound: bool) -> list[str]:
    """The argument names a docstring must name, stars included for ``*args``/``**kwargs``."""
    params = list(inspect.signature(func).parameters.values())
    if bound and params:
        params = params[1:]
    names = []
    for p in params:
        prefix = {p.VAR_POSITIONAL: "*", p.VAR_KEYWORD: "**"}.get(p.kind, "")
        names.append(prefix + p.name)
    return names


def _parameters_section(doc: str) -> str | None:
    """The body of the ``Parameters`` section of a docstring, or None when there is none."""
    headers = list(_SECTION.finditer(doc))
    for i, match in enumerate(headers):
        if match.group(1).strip() == "Parameters":
            end = headers[i + 1].start() if i + 1 < len(headers) else len(doc)
            return doc[match.end() : end]
    return None


def _documented(section: str) -> set[str]:
    """Names given by the unindented ``name[, name2] [: type]`` lines of a section."""
    names: set[str] = set()
    for line in section.splitlines():
        if not line.strip() or line[0].isspace():
            continue
        for name in line.split(":", 1)[0].split(","):
            names.add(name.strip().strip("`").lstrip("\\"))
    return names


def _offences(func: Callable, bound: bool) -> str | None:
    """What is missing from a callable's docstring, or None when it is complete."""
    doc = inspect.getdoc(func)
    if not doc:
        return "no docstring"
    args = _arguments(func, bound)
    if not args:
        return None
    section = _parameters_section(doc)
    if section is None:
        return f"no Parameters section (arguments: {', '.join(args)})"
    missing = [a for a in args if a not in _documented(section)]
    return f"undocumented: {', '.join(missing)}" if missing else None


def test_section_parser_reads_numpydoc():
    """The parser finds grouped names, starred names and stops at the next section."""
    doc = inspect.cleandoc(
        """Summary.

        Parameters
        ----------
        a, b : float
            Two numbers.
        *args
            More.
        **kwargs : dict
            Options.

        Returns
        -------
        c : float
            Not a parameter.
        """
    )
    section = _parameters_section(doc)
    assert section is not None
    assert _documented(section) == {"a", "b", "*args", "**kwargs"}


def test_every_public_argument_is_documented():
    offenders = []
    checked = 0
    for module in _modules():
        for qualname, func, bound in _callables(module):
            checked += 1
            problem = _offences(func, bound)
            if problem:
                offenders.append(f"{module.__name__}.{qualname}: {problem}")
    assert checked > 100, f"only {checked} callables found; is the package walk broken?"
    assert not offenders, f"{len(offenders)} incomplete docstrings:\n" + "\n".join(offenders)
