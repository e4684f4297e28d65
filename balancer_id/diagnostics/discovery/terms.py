"""The candidate terms and the library effect they make (its source generated and cached)."""

from __future__ import annotations

import hashlib
import keyword
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from balancer_id.constants import KARNOPP_EPS
from balancer_id.diagnostics.discovery.settings import (
    COULOMB,
    STRIBECK,
    STRIBECK_GRID,
)
from balancer_id.files import atomic_write_text, cache_root
from balancer_id.model.effect import Effect
from balancer_id.model.registry import load_effects_file

if TYPE_CHECKING:
    pass


@dataclass(frozen=True)
class Term:
    """One candidate force term.

    Parameters
    ----------
    expression : str
        Python in ``f, v, z, h`` (drive force N, velocity m/s, position m, operating force
        N), ``math`` and arithmetic; it may name shape constants of :attr:`shapes`.
    unit : str
        Unit of its coefficient (the term times the coefficient is a force in N).
    name : str
        Name of the coefficient in a written effect (a Python identifier).
    shapes : tuple of (str, float)
        Shape constants the expression names (``v_s``, ``p``) and their values.
    magnitude : str
        For a friction term (Coulomb, Stribeck): the expression is ``sign(v) *
        magnitude``. In a model without a friction effect such terms act through the
        ``friction`` hook with a stick band (a load at rest stays there while the other
        forces are below the static level, the magnitudes at ``v = 0``), as real dry
        friction does; elsewhere they are plain force terms. Empty for other terms.

    Examples
    --------
    A user term, a force growing with the position and the speed::

        Term("z*abs(v)", "N s/m^2", "c_zabsv")
    """

    expression: str
    unit: str
    name: str
    shapes: tuple[tuple[str, float], ...] = ()
    magnitude: str = ""

    @property
    def is_friction(self) -> bool:
        """Whether the term is a sliding law ``sign(v) * magnitude``."""
        return bool(self.magnitude)

    def concrete(self) -> str:
        """The expression with its shape constants written as numbers.

        Returns
        -------
        str
        """
        text = self.expression
        for key, value in self.shapes:
            text = re.sub(rf"\b{re.escape(key)}\b", f"{value:.4g}", text)
        return text

    def evaluate(self, f: np.ndarray, v: np.ndarray, z: np.ndarray, h: np.ndarray) -> np.ndarray:
        """The term at each sample of the states.

        Parameters
        ----------
        f, v, z, h : numpy.ndarray
            Drive force (N), velocity (m/s), position (m), operating force (N).

        Returns
        -------
        numpy.ndarray
        """
        fn = eval(f"lambda f, v, z, h: float({self.concrete()})", {"math": math, "abs": abs})
        cols = [np.asarray(x, dtype=float).tolist() for x in (f, v, z, h)]
        return np.array([fn(*x) for x in zip(*cols, strict=True)], dtype=float)


def default_terms(v_top: float, period: float | None) -> list[Term]:
    """The library of candidate terms for trials reaching speed ``v_top``.

    Parameters
    ----------
    v_top : float
        The highest speed the trials reach (m/s); the Stribeck velocities are shares of it
        (:data:`STRIBECK_GRID`).
    period : float or None
        The period over position of the residual (m); None sets it to 1 m (the ``sin`` and
        ``cos`` terms are then not tried: :data:`PERIODIC`).

    Returns
    -------
    list of Term
    """
    sign = "((v > 0.0) - (v < 0.0))"
    terms = [
        Term("z", "N/m", "k_z"),
        Term("v", "N s/m", "c_v"),
        Term("v*abs(v)", "N s^2/m^2", "c_vv"),
        Term("v**3", "N s^3/m^3", "c_v3"),
        Term(sign, "N", COULOMB, magnitude="1.0"),
    ]
    for k, share in enumerate(STRIBECK_GRID, 1):
        vs = max(share * v_top, 1e-9)
        stribeck = f"math.exp(-abs(v)/v_s{k})"
        terms.append(
            Term(f"{sign}*{stribeck}", "N", f"{STRIBECK}{k}", ((f"v_s{k}", vs),), stribeck)
        )
    # always in the library (one compiled kernel); without a period they are not tried
    p = (("p_z", float(period) if period else 1.0),)
    terms.append(Term("math.sin(2*math.pi*z/p_z)", "N", "a_sin", p))
    terms.append(Term("math.cos(2*math.pi*z/p_z)", "N", "a_cos", p))
    terms += [
        Term("h*v", "s/m", "c_hv"),
        Term("z*v", "N s/m^2", "c_zv"),
        Term("1.0", "N", "f_0"),
    ]
    return terms


# ---- effect sources ---------------------------------------------------------------------


def _py(x: float) -> str:
    return repr(float(x))


def friction_hook(coefficients: Sequence[str], magnitudes: Sequence[str], args: str) -> str:
    """Source of a ``friction`` hook: sliding law ``sign(v) * sum c_j * magnitude_j``
    with a stick band, as Karnopp's (paper eqs. 3-5) with the static level at ``v = 0``.

    Parameters
    ----------
    coefficients : sequence of str
        The coefficients' names (negative values oppose the motion).
    magnitudes : sequence of str
        The terms' magnitudes in ``v``.
    args : str
        The hook's parameter list after ``v, F``.

    Returns
    -------
    str
        Indented source of the static method (two lines of decorator and signature
        included).
    """
    slide = " + ".join(
        c if m == "1.0" else f"{c} * {m}" for c, m in zip(coefficients, magnitudes, strict=True)
    )
    return (
        "    @staticmethod\n"
        f"    def friction(v, F, {args}):\n"
        "        # the sliding force while moving forward; at rest, the static level\n"
        f"        slide = {slide}\n"
        f"        if abs(v) <= {KARNOPP_EPS!r}:\n"
        "            if abs(F) <= -slide:\n"
        "                return -F  # stuck: friction holds the other forces\n"
        "            if F == 0.0:\n"
        "                return 0.0  # nothing pushes: nothing to break away from\n"
        "            return slide if F > 0.0 else -slide  # break-away\n"
        "        return slide if v > 0.0 else -slide\n"
    )


def library_source(terms: Sequence[Term], stick: bool = False) -> str:
    """Source of the library effect: ``sum q_j * term_j`` with the shapes as parameters.

    The source depends on the expressions only (not on the shape values, which are held
    parameters), so its compiled kernel serves every log.

    Parameters
    ----------
    terms : sequence of Term
    stick : bool
        Put the friction terms (:attr:`Term.is_friction`) in a ``friction`` hook with a
        stick band (for a model without a friction effect of its own); False keeps every
        term a plain force.

    Returns
    -------
    str
    """
    shapes: list[str] = []
    for t in terms:
        for key, _ in t.shapes:
            if key not in shapes:
                shapes.append(key)
    params = [
        f'        Param("q{j}", 0.0, -1e15, 1e15, "{t.unit}", "coefficient of {t.expression}"),'
        for j, t in enumerate(terms)
    ]
    params += [f'        Param("{s}", 1.0, 1e-12, 1e12, "", "shape constant"),' for s in shapes]
    args = ", ".join([*(f"q{j}" for j in range(len(terms))), *shapes])
    dry = [j for j, t in enumerate(terms) if stick and t.is_friction]
    body = (
        " + ".join(f"q{j} * ({t.expression})" for j, t in enumerate(terms) if j not in dry) or "0.0"
    )
    friction = (
        "\n" + friction_hook([f"q{j}" for j in dry], [terms[j].magnitude for j in dry], args)
        if dry
        else ""
    )
    return (
        '"""Candidate terms of the discovery (generated by balancer_id.diagnostics.discover)."""\n'
        "import math\n\n"
        "from balancer_id.model.effect import Effect, Param\n\n\n"
        "class DiscoveryLibrary(Effect):\n"
        '    """Every candidate force term, each with its coefficient."""\n\n'
        '    name = "discovery_library"\n'
        '    summary = "candidate force terms of the discovery"\n'
        "    parameters = (\n" + "\n".join(params) + "\n    )\n\n"
        "    @staticmethod\n"
        f"    def force(f, v, z, h, {args}):\n"
        f"        return {body}\n" + friction
    )


def library_effect(terms: Sequence[Term], stick: bool = False) -> type[Effect]:
    """The library effect of ``terms``, written to the cache folder and loaded from there.

    Parameters
    ----------
    terms : sequence of Term
    stick : bool
        Friction terms with a stick band (:func:`library_source`).

    Returns
    -------
    type
        The :class:`~balancer_id.model.effect.Effect` subclass.
    """
    text = library_source(terms, stick)
    digest = hashlib.sha1(text.encode()).hexdigest()[:12]
    folder = cache_root() / "discovery"
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / f"library_{digest}.py"
    if not path.is_file() or path.read_text(encoding="utf-8") != text:
        atomic_write_text(path, text)
    (cls,) = load_effects_file(path)
    return cls


def effect_name(path: str | Path) -> str:
    """The effect's spec name for a file: its stem as an identifier, else ``discovered``.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    str
    """
    stem = re.sub(r"\W", "_", Path(path).stem).strip("_").lower()
    if not stem or not stem.isidentifier() or keyword.iskeyword(stem) or stem[0].isdigit():
        return "discovered"
    return stem


def _class_name(name: str) -> str:
    return "".join(p.capitalize() for p in name.split("_") if p) or "Discovered"
