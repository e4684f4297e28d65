"""Parameters known from an earlier fit: ``fit --params FILE.json`` holds them.

The usual robot workflow identifies the balancer from step trials first, then the
robot's servo from a robot-assist log with the balancer held at those values.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from pathlib import Path

from balancer_id.errors import UsageError
from balancer_id.model.spec import Model, resolve_model


def read_params_file(path: str | Path) -> dict[str, float]:
    """The parameter values of an earlier ``fit --json`` (or a plain ``{NAME: value}``).

    Parameters
    ----------
    path : str or Path
        A JSON file: the object ``balancer-id fit --json`` prints (its ``parameters``
        ``{NAME: {"value": ...}}``), or a flat object ``{NAME: number}``.

    Returns
    -------
    dict of str to float
        Parameter name -> value.

    Raises
    ------
    UsageError
        When the file cannot be read, is not JSON, or holds no parameter values.
    """
    path = Path(path)
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except OSError as exc:
        raise UsageError(f"--params {path}: cannot read it ({exc.strerror})") from None
    except UnicodeDecodeError:
        raise UsageError(
            f"--params {path}: not a text file; give the output of 'balancer-id fit --json'"
        ) from None
    except json.JSONDecodeError as exc:
        raise UsageError(
            f"--params {path}: line {exc.lineno} column {exc.colno}: not JSON ({exc.msg}); "
            "give the output of 'balancer-id fit --json'"
        ) from None
    table = data.get("parameters", data) if isinstance(data, dict) else None
    out: dict[str, float] = {}
    for name, item in (table or {}).items():
        value = item.get("value") if isinstance(item, dict) else item
        if isinstance(value, int | float) and not isinstance(value, bool):
            if not math.isfinite(value):  # NaN or Infinity: never used as a value
                raise UsageError(
                    f"--params {path}: {name} is {value}; give a finite value (or leave {name} out)"
                )
            out[str(name)] = float(value)
    if not out:
        raise UsageError(
            f"--params {path}: no parameter values found; give the output of "
            "'balancer-id fit --json' or an object of NAME: value"
        )
    return out


def held_for_model(
    path: str | Path,
    model: str | Model | None,
    effects_files: Sequence[str | Path] = (),
) -> dict[str, float]:
    """The values of ``path`` (:func:`read_params_file`) that are parameters of ``model``.

    Parameters
    ----------
    path : str or Path
        The JSON of an earlier fit.
    model : str, Model or None
        The model of this fit, or its spec (None: the default).
    effects_files : sequence of str or Path
        User effect files the spec may name.

    Returns
    -------
    dict of str to float
        Parameter name -> value, only for the model's parameters.

    Raises
    ------
    UsageError
        When the file holds none of the model's parameters.
    """
    names = set(resolve_model(model, effects_files).param_names)
    values = read_params_file(path)
    held = {k: v for k, v in values.items() if k in names}
    if not held:
        raise UsageError(
            f"--params {path}: none of its parameters ({', '.join(sorted(values))}) is a "
            f"parameter of the model"
        )
    return held


def params_model(path: str | Path, model: str | None) -> str | None:
    """The model of ``--params FILE`` (its ``model`` key) unless ``model`` names one.

    Parameters
    ----------
    path : str or Path
        The JSON of an earlier fit.
    model : str or None
        The model the user named (it wins).

    Returns
    -------
    str or None
        None when neither says (the default model); a file that cannot be read is left
        to :func:`read_params_file` to explain.
    """
    if model is not None:
        return model
    try:
        data = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError):
        return None
    spec = data.get("model") if isinstance(data, dict) else None
    return spec if isinstance(spec, str) else None
