"""Discovery of the missing term: the model's discrepancy as a sparse sum of candidate forces.

When no explanation of the arena (library effects, a parameter changed or drifting, the
sensor's low-pass) brings the residual to the noise floor, the missing force is searched as
a sparse combination of candidate terms in the states (SINDy for model discrepancy,
Kaheman et al. 2019), in the model's own units (N), and the whole model is refitted with
the chosen terms as one effect, so that the other parameters move with it.

How
---
1. The candidate terms (:func:`default_terms`: ``z``, ``v``, ``v*abs(v)``, ``v**3``,
   Coulomb ``sign(v)``, Stribeck ``sign(v)*exp(-abs(v)/v_s)`` over a grid of ``v_s``,
   ``sin``/``cos(2*pi*z/p)`` with ``p`` from the residual's spectrum over position,
   ``h*v``, ``z*v``, a constant; users add theirs) become one *library* effect whose force
   is ``sum q_j * term_j``, written as a user effect file in the cache folder and loaded
   through the same path as ``--effects-file`` (its kernel is compiled once and cached).
2. The fitted model plus the library at ``q = 0`` is simulated once with the output's
   sensitivities to every free parameter and every ``q_j``: the discrepancy force is then
   a linear regression (the Gauss-Newton step of the full output-error problem), in which
   the model's own parameters move freely and the terms compete. Rows are prewhitened with
   the resting noise's AR(2) coefficients (the arena's likelihood of coloured noise).
3. The sparse regression is scikit-learn's orthogonal matching pursuit path; the support
   with the lowest BIC wins, and a term stays only when removing it costs more than
   :data:`TERM_BIC` and it lowers the error on held-out trials (K-fold over trials).
   Bootstrap resamples of the trials give each kept term's inclusion probability (the
   share in which removing it from the model linearized at the refit still costs more
   than :data:`TERM_BIC`).
4. The whole model is refitted (nonlinear, simulation matching) with the chosen terms free
   and the others held at 0, scored by the arena's criterion (:func:`arena.score`): the
   discovery stands only when it beats the arena's best explanation on the same BIC.

The discovered effect is written by :func:`effect_source` in the README's plug-in form.
"""

from __future__ import annotations

import hashlib
import json
import keyword
import math
import re
import warnings
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from balancer_id.constants import KARNOPP_EPS
from balancer_id.diagnostics import arena
from balancer_id.diagnostics.arena import ArenaInput, Explanation
from balancer_id.diagnostics.context import DiagnosisContext, TrialView
from balancer_id.errors import BalancerIdError
from balancer_id.files import atomic_write_text, cache_root
from balancer_id.identify.data import FitData
from balancer_id.identify.matching import MatchResult, match_trials
from balancer_id.model.effect import Effect
from balancer_id.model.registry import Registry, load_effects_file
from balancer_id.model.spec import Model

#: A kept term must lower the BIC of the linear step by at least this (as the arena's
#: :data:`~balancer_id.diagnostics.diagnosis.BIC_THRESHOLD`).
TERM_BIC = 30.0
#: BIC by which a discovered law must beat a library dry-friction law that reached the
#: noise floor (:func:`challenges`). Both are dry friction: the choice is of its shape,
#: and the discovered law's extra parameters are already counted in its BIC. 10 is
#: "very strong" on Kass and Raftery's scale; where the library's law is the truth, the
#: two extra parameters of Coulomb with Stribeck reach it by chance with a probability of
#: about exp(-(10 + 2 ln n) / 2) (n the independent samples, thousands in a log).
CHALLENGE_BIC = 10.0
#: Terms tried at most along the pursuit path.
MAX_TERMS = 4
#: Terms the linear step ranks highest that are refitted whole in each round.
REFITTED = 3
#: ... those whose linear BIC fall is at least this share of the best one's.
CLOSE = 0.3
#: A term refitted whole within this BIC of the chosen one fits about as well.
CLOSE_BIC = 10.0
#: Bootstrap resamples of the trials for the inclusion probabilities.
BOOTSTRAP = 40
#: Stribeck velocities, as shares of the highest speed the trials reach.
STRIBECK_GRID = (0.02, 0.07, 0.25)
#: The error above the noise floor (x the noise) that the arena's best may leave before
#: discovery is tried (the level test's tolerance, adequacy.LEVEL_MIN).
LEFT_OVER = 0.5
#: Samples (at most, by a regular stride) of the residual force's spectrum over position.
PERIOD_SAMPLES = 3000
#: The Coulomb term, and the prefix of the Stribeck terms (tried with it as a pair).
COULOMB, STRIBECK = "f_c", "f_st"
#: Terms tried only when the residual's spectrum over position has a period.
PERIODIC = ("a_sin", "a_cos")
#: Marker of a file written by ``improve --discover`` (only such a file is ever replaced).
MARKER = "# Written by balancer-id improve --discover."


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


# ---- the result -------------------------------------------------------------------------


@dataclass
class DiscoveredTerm:
    """One kept term of a discovery (CONTRACT.md ``discovery.terms``)."""

    term: Term
    coefficient: float
    stderr: float | None
    inclusion: float

    @property
    def expression(self) -> str:
        """The term as Python in ``f, v, z, h``, shape constants as numbers."""
        return self.term.concrete()

    def to_dict(self) -> dict[str, object]:
        """CONTRACT.md ``discovery.terms`` record."""
        return {
            "expression": self.expression,
            "coefficient": self.coefficient,
            "stderr": self.stderr,
            "unit": self.term.unit,
            "inclusion": self.inclusion,
        }


@dataclass
class Discovery:
    """A discovered force and the refit of the whole model with it.

    Attributes
    ----------
    terms : list of DiscoveredTerm
        The kept terms.
    delta_bic : float
        Fall of BIC against the current fit (the arena's criterion).
    rmse : float
        RMSE of the refit (m/s^2).
    rival : str or None
        The arena's best explanation it beat, and its BIC fall.
    command : str
        The command that writes it as an effect and refits.
    refit : MatchResult
        The whole model refitted with the terms (the library effect, other terms at 0).
    states : dict of str to numpy.ndarray
        ``f, v, z, h`` of the refit and ``residual_force``: the refit's force discrepancy
        plus the discovered force (what the terms were fitted to), over every sample.
    """

    terms: list[DiscoveredTerm]
    delta_bic: float
    rmse: float
    command: str
    refit: MatchResult = field(repr=False)
    rival: dict[str, object] | None = None
    excess_drop: float = 0.0
    #: What the refit held: the fit's own held values, the shapes, the other terms at 0.
    fixed: dict[str, float] = field(default_factory=dict, repr=False)
    #: Terms that fit about as well as a chosen one (within :data:`CLOSE_BIC`):
    #: ``{instead_of, expression, coefficient, bic_drop}``; the data cannot tell them apart.
    alternatives: list[dict[str, object]] = field(default_factory=list)
    states: dict[str, np.ndarray] = field(default_factory=dict, repr=False)
    #: Whether the friction terms act with a stick band (the model has no friction effect).
    stick: bool = False

    @property
    def formula(self) -> str:
        """``F = c1*(term1) + c2*(term2)`` (N)."""
        parts = []
        for t in self.terms:
            c = f"{t.coefficient:.4g}"
            e = t.expression
            simple = re.fullmatch(r"\w+", e)
            parts.append(c if e == "1.0" else f"{c}*{e}" if simple else f"{c}*({e})")
        return "F = " + (" + ".join(parts).replace("+ -", "- ") if parts else "0")

    def force(self, f: np.ndarray, v: np.ndarray, z: np.ndarray, h: np.ndarray) -> np.ndarray:
        """The discovered force at the given states (N).

        Parameters
        ----------
        f, v, z, h : numpy.ndarray
            States.

        Returns
        -------
        numpy.ndarray
        """
        out = np.zeros(np.shape(v), dtype=float)
        for t in self.terms:
            out = out + t.coefficient * t.term.evaluate(f, v, z, h)
        return out

    def main_state(self) -> str:
        """The state the first term depends on most (``z`` or ``v``, for the plot)."""
        e = self.terms[0].term.expression if self.terms else "z"
        return "z" if re.search(r"\bz\b", e) else "v" if re.search(r"\bv\b", e) else "h"

    def to_dict(self) -> dict[str, object]:
        """The CONTRACT.md ``discovery`` object."""
        return {
            "formula": self.formula,
            "terms": [t.to_dict() for t in self.terms],
            "bic_drop": self.delta_bic,
            "rmse_after": self.rmse,
            "excess_error_drop": self.excess_drop,
            "beats": self.rival,
            "alternatives": self.alternatives,
            "command": self.command,
        }

    def explanation(self) -> Explanation:
        """The discovery as one of the arena's explanations (kind ``discovered``)."""
        from balancer_id.diagnostics.explanations import kind_of

        e = kind_of("discovered").make(
            f"discovered force {self.formula}",
            self.delta_bic,
            self.rmse,
            detail={
                "formula": self.formula,
                "values": self.refit.values(),
                "alternatives": self.alternatives,
            },
        )
        e.excess_drop = self.excess_drop
        e.source = self
        return e

    def effect_source(self, name: str = "discovered", evidence: str = "") -> str:
        """The discovered force as a user effect file (the README's plug-in form).

        Parameters
        ----------
        name : str
            The effect's spec name (a Python identifier).
        evidence : str
            What the docstring says about the evidence (log, BIC, held-out error).

        Returns
        -------
        str
            Python source: one :class:`~balancer_id.model.effect.Effect` subclass whose
            ``force`` hook is the formula, its coefficients Params started at the
            discovered values, with units from the terms.
        """
        q = json.dumps
        params, args, body, doc = [], [], [], []
        for t in self.terms:
            c, e = t.coefficient, t.expression
            span = float(f"{max(1e3 * abs(c), 1e-6):.3g}")
            se = f" +- {t.stderr:.2g}" if t.stderr is not None and np.isfinite(t.stderr) else ""
            fields = [q(t.term.name), _py(float(f"{c:.6g}")), _py(-span), _py(span)]
            fields += [q(t.term.unit), q("coefficient of " + e)]
            one = f"        Param({', '.join(fields)}),"
            params.append(
                one
                if len(one) <= 100
                else "        Param(\n"
                + "".join(f"            {x},\n" for x in fields)
                + "        ),"
            )
            args.append(t.term.name)
            if not (self.stick and t.term.is_friction):
                body.append(_product(t.term.name, e))
            doc.append(
                f"    {t.term.name} = {c:.4g}{se} {t.term.unit} (term {e}),\n"
                f"    kept in {t.inclusion:.0%} of the bootstrap resamples of the trials."
            )
        dry = [t for t in self.terms if self.stick and t.term.is_friction]
        sliding = " + ".join(_product(t.term.name, t.expression) for t in dry)
        formula = " + ".join(body) or "0.0"
        whole = " + ".join(x for x in (" + ".join(body), sliding) if x)
        hooks = (
            [
                "    @staticmethod",
                f"    def force(f, v, z, h, {', '.join(args)}):",
                f"        return {formula}",
            ]
            if body
            else []
        )
        if dry:
            magnitudes = [t.term.magnitude for t in dry]
            for key, value in (kv for t in dry for kv in t.term.shapes):
                magnitudes = [re.sub(rf"\b{key}\b", f"{value:.4g}", m) for m in magnitudes]
            hook = friction_hook([t.term.name for t in dry], magnitudes, ", ".join(args))
            hooks += [*([""] if hooks else []), *hook.rstrip("\n").split("\n")]
            doc.append(
                "    The sign(v) terms are dry friction: a load at rest sticks while the other\n"
                "    forces stay below their level at v = 0 (the friction hook)."
            )
        rival = (
            f" (the best library explanation, {self.rival['label']}, by "
            f"{float(self.rival['delta_bic']):.0f})"  # type: ignore[arg-type]
            if self.rival
            else ""
        )
        lines = [
            MARKER,
            f'"""A force found by balancer-id (improve --discover): F = {whole} (N)."""',
            "",
            "import math  # noqa: F401  (the terms may use it)",
            "",
            "from balancer_id import Effect, Param",
            "",
            "",
            f"class {_class_name(name)}(Effect):",
            f'    """Discovered force ``F = {whole}`` (N).',
            "",
            f"    Fitted: {self.formula} (N).",
            *doc,
            f"    Evidence: BIC falls by {self.delta_bic:.0f} against the model without it"
            f"{rival}; RMSE {self.rmse:.4g} m/s^2.",
            *([f"    {evidence}"] if evidence else []),
            "    Edit the formula or the bounds freely: it is a user effect like any other.",
            '    """',
            "",
            f"    name = {q(name)}",
            f"    summary = {q('discovered force ' + self.formula)}",
            f"    source = {q('balancer-id improve --discover')}",
            "    parameters = (",
            *params,
            "    )",
            "",
            *hooks,
            "",
        ]
        return "\n".join(lines)


def _product(coef: str, expression: str) -> str:
    """``coef*expression``, with brackets only around a compound expression."""
    if expression == "1.0":
        return coef
    return f"{coef}*{expression}" if re.fullmatch(r"\w+", expression) else f"{coef}*({expression})"


# ---- the regression ---------------------------------------------------------------------


def _whiten(x: np.ndarray, ar: tuple[float, float]) -> np.ndarray:
    """Rows of one trial prewhitened with AR(2) coefficients (drops the first two)."""
    p1, p2 = ar
    return x[2:] - p1 * x[1:-1] - p2 * x[:-2]


def _gram_rss(xx: np.ndarray, xy: np.ndarray, yy: float, keep: Sequence[int]) -> float:
    """Residual sum of squares of ``y`` on the columns ``keep``, from the Gram matrix
    ``xx`` of the columns, their products ``xy`` with ``y`` and ``yy = y.y``."""
    keep = list(keep)
    if not keep:
        return max(yy, 1e-300)
    b = np.linalg.lstsq(xx[np.ix_(keep, keep)], xy[keep], rcond=1e-12)[0]
    return max(yy - float(xy[keep] @ b), 1e-300)


def _project(base: np.ndarray, x: np.ndarray) -> np.ndarray:
    """``x`` with its part along the columns of ``base`` removed."""
    if base.shape[1] == 0:
        return x
    q, _ = np.linalg.qr(base)
    return x - q @ (q.T @ x)


@dataclass
class _Linear:
    """The linearized problem: per trial, whitened residual, parameter and term columns."""

    r: list[np.ndarray]
    p: list[np.ndarray]
    q: list[np.ndarray]
    #: The model's parameters behind the columns of ``p``, in order.
    free: list[str] = field(default_factory=list)
    #: Per trial, the Gram matrix of ``[p, q, r]`` (filled on first use).
    grams: list[np.ndarray] = field(default_factory=list, repr=False)

    def gram(self, trials: Sequence[int]) -> tuple[np.ndarray, int]:
        """The Gram matrix of ``[p, q, r]`` over ``trials`` (repeats allowed) and its rows.

        A bootstrap resample of the trials is a sum of the trials' own Gram matrices, so
        the sparse regression never touches the rows again.
        """
        if not self.grams:
            for r, p, q in zip(self.r, self.p, self.q, strict=True):
                a = np.hstack([p, q, r[:, None]])
                self.grams.append(a.T @ a)
        g = np.sum([self.grams[i] for i in trials], axis=0)
        return g, int(sum(self.r[i].size for i in trials))

    def rows(self, trials: Sequence[int]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return (
            np.concatenate([self.r[i] for i in trials]),
            np.vstack([self.p[i] for i in trials]),
            np.vstack([self.q[i] for i in trials]),
        )


def select(lin: _Linear, trials: Sequence[int], usable: Sequence[int]) -> list[int]:
    """The sparse support: the pursuit path's lowest BIC, then each term must pay.

    The model's parameter columns are projected out (the Schur complement of their block
    of the Gram matrix), the term columns normalized, and scikit-learn's orthogonal
    matching pursuit runs on the Gram matrix.

    Parameters
    ----------
    lin : _Linear
        The linearized problem.
    trials : sequence of int
        The trials (rows) used (repeats allowed: a bootstrap resample).
    usable : sequence of int
        Term columns that may enter.

    Returns
    -------
    list of int
        The chosen term columns, in the order the path took them.
    """
    from sklearn.linear_model import orthogonal_mp_gram  # type: ignore[import-untyped]

    g, n = lin.gram(trials)
    if n < 20 or not usable:
        return []
    npar = lin.p[0].shape[1]
    idx = [npar + c for c in usable] + [g.shape[0] - 1]
    s = g[np.ix_(idx, idx)]
    if npar:
        gpx = g[:npar, idx]
        s = s - gpx.T @ np.linalg.lstsq(g[:npar, :npar], gpx, rcond=1e-12)[0]
    k = len(usable)
    norms = np.sqrt(np.maximum(np.diag(s)[:k], 0.0))
    ok = norms > 1e-9 * max(float(norms.max()), 1e-300)
    cols = [c for c, good in zip(usable, ok, strict=True) if good]
    if not cols:
        return []
    scale = norms[ok]
    xx = s[:k, :k][np.ix_(ok, ok)] / np.outer(scale, scale)
    xy = s[:k, k][ok] / scale
    yy = float(s[k, k])

    def rss(support: list[int]) -> float:
        return _gram_rss(xx, xy, yy, support)

    kmax = min(MAX_TERMS, len(cols))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        path = orthogonal_mp_gram(xx, xy, n_nonzero_coefs=kmax, return_path=True)
    path = np.atleast_2d(path.T) if path.ndim == 2 else path[:, None].T
    best: list[int] = []
    best_bic = n * np.log(max(yy, 1e-300) / n)
    for coefs in path:
        support = [int(j) for j in np.flatnonzero(np.abs(coefs) > 0)]
        b = n * np.log(rss(support) / n) + len(support) * np.log(n)
        if b < best_bic - 1e-9:
            best, best_bic = support, b
    # each term must pay: removing it costs more than TERM_BIC
    changed = True
    while changed and best:
        changed = False
        full = rss(best)
        costs = [n * np.log(rss([k for k in best if k != j]) / full) - np.log(n) for j in best]
        worst = int(np.argmin(costs))
        if costs[worst] < TERM_BIC:
            best = [k for k in best if k != best[worst]]
            changed = True
    return [cols[j] for j in best]


def _ranked(r: np.ndarray, p: np.ndarray, q: np.ndarray) -> list[tuple[int, float]]:
    """Each term column with the BIC fall it alone brings to the linear step, best first."""
    n = r.size
    qp = _project(p, q)
    rp = _project(p, r[:, None])[:, 0]
    rss0 = max(float(rp @ rp), 1e-300)
    out = []
    for c in range(qp.shape[1]):
        x = qp[:, c]
        xx = float(x @ x)
        if xx <= 1e-300:
            continue
        rss = max(rss0 - float(x @ rp) ** 2 / xx, 1e-300)
        out.append((c, n * np.log(rss0 / rss) - np.log(n)))
    return sorted(out, key=lambda t: -t[1])


def held_out_gain(lin: _Linear, support: Sequence[int], folds: int = 3) -> list[float]:
    """For each term of ``support``: held-out error without it over with it (> 1: it helps).

    K-fold across trials: the model's parameter steps and the terms are fitted on the other
    trials and predict the held-out trial's residual.

    Parameters
    ----------
    lin : _Linear
    support : sequence of int
    folds : int

    Returns
    -------
    list of float
        One ratio per term (1.0 with fewer than three trials: no test).
    """
    n = len(lin.r)
    if n < 3:
        return [1.0 for _ in support]
    k = min(folds, n)

    def sse(cols: list[int]) -> float:
        total = 0.0
        for j in range(k):
            train = [i for i in range(n) if i % k != j]
            test = [i for i in range(n) if i % k == j]
            r, p, q = lin.rows(train)
            a = np.hstack([p, q[:, cols]])
            coef, *_ = np.linalg.lstsq(a, r, rcond=None)
            rt, pt, qt = lin.rows(test)
            e = rt - np.hstack([pt, qt[:, cols]]) @ coef
            total += float(e @ e)
        return total

    full = sse(list(support))
    return [sse([c for c in support if c != s]) / max(full, 1e-300) for s in support]


# ---- the period over position -----------------------------------------------------------


def position_period(ctx_trials: Sequence[TrialView], m_a: float) -> float | None:
    """The period over position of the residual force, from its Lomb-Scargle spectrum.

    The moving samples' residual force (m_a times the acceleration residual) against the
    simulated position; periods from 1/20 to 1/1.5 of the distance covered are searched.
    A peak that is not clearly above the spectrum's median gives None.

    Parameters
    ----------
    ctx_trials : sequence of TrialView
        The diagnosis's trials.
    m_a : float
        The fitted mass (kg).

    Returns
    -------
    float or None
        The period (m).
    """
    from scipy.signal import lombscargle

    zs, rs = [], []
    for tv in ctx_trials:
        moving = (tv.t > 0) & (np.abs(tv.v) > 1e-4)
        if moving.sum() < 20:
            continue
        r = m_a * tv.residual[moving]
        zm = np.asarray(tv.z[moving], dtype=float)
        trend = np.polynomial.Polynomial.fit(zm, r, 2)(zm) if np.ptp(zm) > 0 else np.mean(r)
        zs.append(zm)
        rs.append(r - trend)
    if not zs:
        return None
    z, r = np.concatenate(zs), np.concatenate(rs)
    span = float(np.ptp(z))
    if span <= 0 or z.size < 50:
        return None
    periods = np.geomspace(span / 20.0, span / 1.5, 200)
    # the shortest period searched spans hundreds of samples: every few is enough
    stride = max(1, z.size // PERIOD_SAMPLES)
    z, r = z[::stride], r[::stride]
    power = lombscargle(z, r - r.mean(), 2 * np.pi / periods)
    k = int(np.argmax(power))
    if not power[k] > 8.0 * float(np.median(power)):
        return None
    return float(periods[k])


# ---- the workflow -----------------------------------------------------------------------


def should_try(best: Explanation | None, noise_floor: float, tests_failed: bool) -> bool:
    """Whether to search for a term: a test failed and the arena's best leaves error.

    Parameters
    ----------
    best : Explanation or None
        The arena's best standing explanation.
    noise_floor : float
        Acceleration noise (m/s^2).
    tests_failed : bool
        Whether one of the adequacy tests failed for the current fit.

    Returns
    -------
    bool
        True when the best explanation changes a parameter (a missing force depending
        on the speed or the thrust looks like one), or when a test failed and there is
        no standing explanation or the best one leaves an error above the noise floor
        larger than :data:`LEFT_OVER` x the noise.
    """
    if best is not None and best.explainer.changes_parameter:
        return True
    if not tests_failed:
        return False
    if best is None:
        return True
    left = math.sqrt(max(best.rmse**2 - noise_floor**2, 0.0))
    return noise_floor <= 0 or left > LEFT_OVER * noise_floor


def challenges(best: Explanation | None, registry: Registry) -> bool:
    """Whether the arena's best is a library dry-friction law that the discovery's
    friction terms generalize, so that the search challenges it even at the noise floor.

    A constant friction level (Karnopp's) is the special case of Coulomb with Stribeck at
    ``F_s = 0``; where the friction falls with the speed, it reaches the noise floor with
    the viscosity bent to absorb the rest. The discovery must then beat it by
    :data:`CHALLENGE_BIC` (the ``margin`` of :func:`discover`).

    Parameters
    ----------
    best : Explanation or None
        The arena's best standing explanation.
    registry : Registry
        Where its effects are found.

    Returns
    -------
    bool
    """
    if best is None or best.key != "effect":
        return False
    return any(name in registry and "friction" in registry[name].hooks() for name in best.effects)


def discover(
    inp: ArenaInput,
    ctx: DiagnosisContext,
    *,
    rival: Explanation | None = None,
    command: str = "",
    terms: Sequence[Term] | None = None,
    extra_terms: Sequence[Term] = (),
    seed: int = 0,
    margin: float = 0.0,
) -> Discovery | None:
    """Search the missing force, refit the whole model with it, and score it.

    Parameters
    ----------
    inp : ArenaInput
        The current fit, its trials, the noise's AR(2) coefficients.
    ctx : DiagnosisContext
        The fit's trials with their simulated states.
    rival : Explanation, optional
        The arena's best explanation: the discovery must beat its BIC fall.
    command : str
        The command that writes the discovered effect (for the record).
    terms : sequence of Term, optional
        The candidate library; None: :func:`default_terms`.
    extra_terms : sequence of Term
        The user's own terms, added to the library.
    seed : int
        Seed of the bootstrap.
    margin : float
        BIC by which the discovery must beat ``rival`` (0: any fall beyond it).

    Returns
    -------
    Discovery or None
        None when no term pays in BIC and on held-out trials, or when the refit does not
        beat ``rival`` by ``margin``.
    """
    # the refits wander through bad regions (overflow, 0/0) before they settle: the
    # optimizer handles those steps, so their floating-point warnings are not news
    with warnings.catch_warnings(), np.errstate(all="ignore"):
        warnings.simplefilter("ignore", RuntimeWarning)
        return _search(inp, ctx, rival, command, terms, extra_terms, seed, margin)


def _search(
    inp: ArenaInput,
    ctx: DiagnosisContext,
    rival: Explanation | None,
    command: str,
    terms: Sequence[Term] | None,
    extra_terms: Sequence[Term],
    seed: int,
    margin: float,
) -> Discovery | None:
    """:func:`discover` without the floating-point warnings."""
    match = inp.match
    values = match.values()
    m_a = float(values.get("m_a", 1.0))
    views = list(ctx.trials)
    if terms is None:
        v_top = max((float(np.max(np.abs(tv.v))) for tv in views), default=0.0)
        if v_top <= 0:
            return None
        period = position_period(views, m_a)
        terms = default_terms(v_top, period)
        skip = set(PERIODIC) if period is None else set()
    else:
        skip = set()
    terms = [*terms, *extra_terms]
    # dry friction with a stick band, unless the model has a friction effect already
    stick = not any("friction" in e.hooks() for e in match.model.effects)
    lib = library_effect(terms, stick)
    registry = Registry(list(match.model.registry))
    if lib.name not in registry:
        registry.add(lib, origin="discovery")
    model = Model((*match.model.effects, lib), registry)
    shapes = {key: val for t in terms for key, val in t.shapes}
    q_names = [f"q{j}" for j in range(len(terms))]
    fixed = {**arena.held(match), **shapes}
    current = {**values, **dict.fromkeys(q_names, 0.0), **shapes}
    support: list[int] = []
    alternatives: list[dict[str, object]] = []
    inclusion = np.zeros(len(terms))
    refit: MatchResult | None = None
    d_best = 0.0
    for round_ in range(MAX_TERMS):
        rest = [j for j in range(len(terms)) if j not in support and terms[j].name not in skip]
        lin = _linearize(model, match.data, current, fixed, q_names, support, rest, inp.ar)
        if lin is None or not rest:
            break
        every = list(range(len(lin.r)))
        chosen = [rest[c] for c in select(lin, every, range(len(rest)))]
        if not chosen:
            break
        if round_ == 0:
            inclusion = _bootstrap(lin, rest, len(terms), seed)
        # the linear step ranks the terms; the few best are refitted whole (nonlinear) and
        # the one that lowers BIC most is taken (v|v| and v^3 look alike to the linear step)
        r, p, q = lin.rows(every)
        ranked = _ranked(r, p, q)
        top = ranked[0][1] if ranked else 0.0
        tries = [rest[c] for c, gain in ranked[:REFITTED] if gain > max(TERM_BIC, CLOSE * top)]
        tries = [j for j in tries if held_out_gain(lin, [rest.index(j)])[0] > 1.0]
        # a Stribeck term comes with its Coulomb level: the pair is tried too
        coulomb = next((k for k in rest if terms[k].name == COULOMB), None)
        groups: list[tuple[int, ...]] = [(j,) for j in tries]
        groups += [
            (coulomb, j)
            for j in tries
            if coulomb is not None and terms[j].name.startswith(STRIBECK) and coulomb != j
        ]
        best_try: tuple[float, tuple[int, ...], MatchResult] | None = None
        tried: list[tuple[float, tuple[int, ...], MatchResult]] = []
        for group in groups:
            cols = [rest.index(k) for k in group]
            step, *_ = np.linalg.lstsq(np.hstack([p, q[:, cols]]), r, rcond=None)
            start = {
                **current,
                **{q_names[k]: float(x) for k, x in zip(group, step[-len(group) :], strict=True)},
            }
            trial_support = [*support, *group]
            hold = {
                **fixed,
                **{q_names[k]: 0.0 for k in range(len(terms)) if k not in trial_support},
            }
            try:
                fitted = match_trials(
                    model, list(inp.trials), start=start, fixed=hold, max_nfev=200
                )
            except BalancerIdError:
                continue
            parts = [fitted.residual[sl] for sl in fitted.data.slices()]
            # a group is one law (a term, or Coulomb with Stribeck): it pays TERM_BIC once,
            # its second parameter counted in the BIC like any other
            gain, _ = arena.score(inp, parts, len(trial_support))
            tried.append((gain, group, fitted))
            if best_try is None or gain > best_try[0]:
                best_try = (gain, group, fitted)
        if best_try is None or best_try[0] - d_best <= TERM_BIC:
            break
        _, chosen_group, refit = best_try
        d_best = best_try[0]
        new = chosen_group[-1]
        # terms that fit about as well in this round: said with the discovery
        for d_alt, group, alt in tried:
            j = group[-1]
            if len(group) == 1 and j != new and d_alt >= best_try[0] - CLOSE_BIC:
                coef = alt.parameters[q_names[j]].value
                alternatives.append(
                    {
                        "instead_of": terms[new].concrete(),
                        "expression": terms[j].concrete(),
                        "coefficient": float(coef),
                        "bic_drop": float(d_alt),
                    }
                )
        support = [*support, *chosen_group]
        current = {**current, **refit.values()}
    if refit is None or not support:
        return None
    # a term taken while an earlier one's refit had not settled may not pay at the end:
    # each must still cost more than TERM_BIC when the whole model is refitted without it
    while len(support) > 1:
        trials = list(inp.trials)
        drops = []
        for j in support:
            keep = [k for k in support if k != j]
            hold = {**fixed, **{q_names[k]: 0.0 for k in range(len(terms)) if k not in keep}}
            try:
                fitted = match_trials(
                    model, trials, start={**current, q_names[j]: 0.0}, fixed=hold, max_nfev=200
                )
            except BalancerIdError:
                continue
            d, _ = arena.score(inp, [fitted.residual[sl] for sl in fitted.data.slices()], len(keep))
            drops.append((d_best - d - term_price(terms, support, j), j, fitted, d))
        if not drops:
            break
        excess, j, fitted, d = min(drops, key=lambda x: x[0])
        if excess > 0:
            break
        support = [k for k in support if k != j]
        refit, d_best = fitted, d
        current = {**current, **fitted.values()}
    hold = {**fixed, **{q_names[k]: 0.0 for k in range(len(terms)) if k not in support}}
    refit, hold, freed, support = _settle_friction(inp, model, refit, hold, terms, support)
    parts = [refit.residual[sl] for sl in refit.data.slices()]
    d_bic, rmse = arena.score(inp, parts, len(support) + len(freed))
    if d_bic <= TERM_BIC or (rival is not None and d_bic <= rival.delta_bic + margin):
        return None
    final = _final_inclusion(model, inp, refit, hold, freed, terms, support, seed)
    inclusion = final if final is not None else inclusion
    found = []
    for j in support:
        est = refit.parameters[q_names[j]]
        term = terms[j]
        if term.shapes and all(key in freed for key, _ in term.shapes):
            term = replace(term, shapes=tuple((key, freed[key]) for key, _ in term.shapes))
        found.append(DiscoveredTerm(term, float(est.value), est.stderr, float(inclusion[j])))
    return Discovery(
        terms=found,
        delta_bic=d_bic,
        rmse=rmse,
        command=command,
        refit=refit,
        rival={"label": rival.label, "delta_bic": rival.delta_bic} if rival is not None else None,
        fixed=hold,
        stick=stick and any(t.term.is_friction for t in found),
        alternatives=[a for a in alternatives if a["instead_of"] in {t.expression for t in found}],
        states=_states(refit, found),
    )


def term_price(terms: Sequence[Term], support: Sequence[int], j: int) -> float:
    """The BIC fall term ``j`` must bring beyond BIC's own penalty to stay in ``support``.

    A term pays :data:`TERM_BIC`; the Coulomb level beside a Stribeck term is a parameter
    of one law (Coulomb with Stribeck), counted in the BIC like any other: 0.

    Parameters
    ----------
    terms : sequence of Term
        The candidate library.
    support : sequence of int
        The terms in the model.
    j : int
        The term judged (in ``support``).

    Returns
    -------
    float
    """
    law = terms[j].name == COULOMB and any(
        terms[k].name.startswith(STRIBECK) for k in support if k != j
    )
    return 0.0 if law else TERM_BIC


def _settle_friction(
    inp: ArenaInput,
    model: Model,
    refit: MatchResult,
    hold: dict[str, float],
    terms: Sequence[Term],
    support: Sequence[int],
) -> tuple[MatchResult, dict[str, float], dict[str, float], list[int]]:
    """The chosen dry-friction terms settled: their Stribeck velocity fitted, the Coulomb
    level beside a Stribeck term.

    The grid of Stribeck velocities only starts the search: each chosen one is freed in a
    whole refit, and a Stribeck term chosen alone is tried with its Coulomb level too
    (Coulomb with Stribeck is the physical law). The chosen Stribeck term has paid
    :data:`TERM_BIC` as a term; its law's other parameters (the velocity, whose grid value
    is arbitrary, and the Coulomb level) are then fitted like any model's parameters: each
    is counted in the BIC, and the settled law is kept when its BIC is the lowest.

    Returns
    -------
    refit : MatchResult
    hold : dict
        What the refit held (the freed constants and the added level left out).
    freed : dict
        The fitted shape constants.
    support : list of int
        The terms kept (the Coulomb level added or not).
    """
    chosen = [terms[j] for j in support]
    keys = [key for t in chosen if t.is_friction for key, _ in t.shapes]
    if not keys:
        return refit, hold, {}, list(support)
    coulomb = next((j for j, t in enumerate(terms) if t.name == COULOMB), None)
    options: list[list[int]] = [list(support)]
    if coulomb is not None and coulomb not in support:
        options.append([*support, coulomb])
    best = (
        arena.score(inp, [refit.residual[sl] for sl in refit.data.slices()], len(support))[0],
        refit,
        hold,
        {},
        list(support),
    )
    for option in options:
        loose = {k: v for k, v in hold.items() if k not in keys}
        if coulomb is not None:
            loose.pop(f"q{coulomb}", None)
            if coulomb not in option:
                loose[f"q{coulomb}"] = 0.0
        try:
            fitted = match_trials(
                model, list(inp.trials), start=refit.values(), fixed=loose, max_nfev=200
            )
        except BalancerIdError:
            continue
        parts = [fitted.residual[sl] for sl in fitted.data.slices()]
        d, _ = arena.score(inp, parts, len(option) + len(keys))
        if d > best[0]:
            values = fitted.values()
            best = (d, fitted, loose, {k: float(values[k]) for k in keys}, option)
    _, refit, hold, freed, kept = best
    return refit, hold, freed, kept


def _linearize(
    model: Model,
    data: FitData,
    values: dict[str, float],
    fixed: dict[str, float],
    q_names: Sequence[str],
    support: Sequence[int],
    candidates: Sequence[int],
    ar: tuple[float, float],
) -> _Linear | None:
    """The output's sensitivities at ``values``: the model's free parameters and the
    terms already chosen as parameters, the ``candidates`` as columns; rows whitened."""
    names = model.param_names
    pvec = np.array([values.get(n, model.param(n).value) for n in names])
    chosen = {q_names[j] for j in support}
    free = [i for i, n in enumerate(names) if n not in fixed and (n not in q_names or n in chosen)]
    cand = [names.index(q_names[j]) for j in candidates]
    out, sens = data.packed.run_sens(model, pvec, [*free, *cand])
    if not (np.all(np.isfinite(out[:, 0])) and np.all(np.isfinite(sens))):
        return None
    resid = data.y - out[:, 0]
    k = len(free)
    lin = _Linear([], [], [], [names[i] for i in free])
    for sl in data.slices():
        lin.r.append(_whiten(resid[sl], ar))
        lin.p.append(_whiten(sens[sl, :k], ar))
        lin.q.append(_whiten(sens[sl, k:], ar))
    return lin


def _final_inclusion(
    model: Model,
    inp: ArenaInput,
    refit: MatchResult,
    hold: dict[str, float],
    freed: dict[str, float],
    terms: Sequence[Term],
    support: Sequence[int],
    seed: int,
) -> np.ndarray | None:
    """Inclusion probabilities of the final terms: over bootstrap resamples of the trials,
    how often each still pays (removing it from the model linearized at the refit raises
    BIC by more than its :func:`term_price`). The first round's selection speaks only of a term
    chosen then; a term chosen later, or one acting through the stick band of dry
    friction (which the linear step at zero cannot see), is judged where it was fitted."""
    q_names = [f"q{j}" for j in range(len(terms))]
    held = {**hold, **freed}
    lin = _linearize(model, inp.match.data, refit.values(), held, q_names, support, [], inp.ar)
    if lin is None or not lin.r:
        return None
    cols = {j: lin.free.index(q_names[j]) for j in support}
    values = refit.values()
    rng = np.random.default_rng(seed)
    counts = np.zeros(len(terms))
    n_trials = len(lin.r)
    for _ in range(BOOTSTRAP):
        g, n = lin.gram(list(rng.integers(0, n_trials, n_trials)))
        k = g.shape[0] - 1
        xx = g[:k, :k]
        every = list(range(k))
        full = _gram_rss(xx, g[:k, k], float(g[k, k]), every)
        for j, c in cols.items():
            # the residual with term j taken out of the model (its linear contribution
            # added back), refitted by every other column
            q = float(values[q_names[j]])
            gy = g[:k, k] + q * g[:k, c]
            yy = float(g[k, k] + 2.0 * q * g[c, k] + q * q * g[c, c])
            rest = [i for i in every if i != c]
            cost = n * np.log(_gram_rss(xx, gy, yy, rest) / full) - np.log(n)
            counts[j] += cost > term_price(terms, support, j)
    return counts / BOOTSTRAP


def _bootstrap(lin: _Linear, usable: Sequence[int], n_terms: int, seed: int) -> np.ndarray:
    """How often each term is selected over bootstrap resamples of the trials."""
    rng = np.random.default_rng(seed)
    counts = np.zeros(n_terms)
    n = len(lin.r)
    for _ in range(BOOTSTRAP):
        pick = rng.integers(0, n, n)
        chosen = select(lin, list(pick), list(range(len(usable))))
        for j in chosen:
            counts[usable[j]] += 1
    return counts / BOOTSTRAP


def _states(refit: MatchResult, found: Sequence[DiscoveredTerm]) -> dict[str, np.ndarray]:
    """The refit's states and the force the terms were fitted to (for the report's plot)."""
    values = refit.values()
    pvec = np.array([values[n] for n in refit.model.param_names])
    out = refit.data.packed.run(refit.model, pvec)
    f, v, z, h = out[:, 3], out[:, 1], out[:, 2], out[:, 4]
    force = np.zeros_like(v)
    for t in found:
        force += t.coefficient * t.term.evaluate(f, v, z, h)
    m_a = float(values.get("m_a", 1.0))
    t_rel = np.concatenate([td.time - td.t_step for td in refit.data.trials])
    return {
        "f": f,
        "v": v,
        "z": z,
        "h": h,
        "t": t_rel,
        "term_force": force,
        "residual_force": m_a * (refit.data.y - out[:, 0]) + force,
    }


def check_effects_out(
    path: str | Path, *, inputs: Sequence[str | Path] = (), overwrite: bool = False
) -> Path:
    """Refuse, before any work, an ``--effects-out`` that could destroy a file of the user's.

    Parameters
    ----------
    path : str or Path
        The ``.py`` file to write.
    inputs : sequence of str or Path
        Files the command reads (never written).
    overwrite : bool
        ``--overwrite``: a file an earlier ``--discover`` wrote may be replaced.

    Returns
    -------
    Path

    Raises
    ------
    UsageError
        Not a ``.py`` name, a missing folder, or one of the inputs.
    OutputExistsError
        The file exists and is the user's, or ``overwrite`` is not given.
    """
    from balancer_id.errors import UsageError
    from balancer_id.files import check_output

    path = Path(path)
    if path.suffix != ".py":
        raise UsageError(f"--effects-out '{path}': give a Python file name ending in .py")
    if path.exists():
        _check_ours(path, overwrite)
    return check_output(path, inputs=inputs, overwrite=True, option="--effects-out")


def _check_ours(path: Path, overwrite: bool) -> None:
    """Refuse an existing file unless an earlier ``--discover`` wrote it and ``overwrite``."""
    from balancer_id.errors import OutputExistsError

    first = ""
    try:
        with path.open(encoding="utf-8") as fh:
            first = fh.readline().strip()
    except (OSError, UnicodeDecodeError):
        pass
    if first != MARKER:
        raise OutputExistsError(
            f"--effects-out '{path}' exists and was not written by balancer-id: it is never "
            "replaced; give another name"
        )
    if not overwrite:
        raise OutputExistsError(
            f"--effects-out '{path}' exists already; add --overwrite to replace it, or "
            "give another name"
        )


def write_effect(
    discovery: Discovery, path: str | Path, *, evidence: str = "", overwrite: bool = False
) -> tuple[Path, str]:
    """Write the discovered effect to ``path`` and return its effect name.

    A file that exists is never replaced unless it was written by ``improve --discover``
    (its first line is :data:`MARKER`) and ``overwrite`` is given.

    Parameters
    ----------
    discovery : Discovery
    path : str or Path
        The ``.py`` file.
    evidence : str
        A line of evidence for the docstring.
    overwrite : bool
        Replace a file this command wrote before.

    Returns
    -------
    tuple
        The path and the effect's name.

    Raises
    ------
    OutputExistsError
        When the file exists and is the user's (or ``overwrite`` is not given).
    """
    path = Path(path)
    if path.exists():
        _check_ours(path, overwrite)
    name = effect_name(path)
    atomic_write_text(path, discovery.effect_source(name, evidence))
    return path, name


__all__ = [
    "DiscoveredTerm",
    "Discovery",
    "Term",
    "challenges",
    "check_effects_out",
    "default_terms",
    "discover",
    "library_effect",
    "should_try",
    "write_effect",
]
