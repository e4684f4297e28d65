"""Readable terminal tables (rich) for each command's result."""

from __future__ import annotations

import sys
from typing import Any

from rich.console import Console
from rich.markup import escape
from rich.table import Table

from balancer_id.diagnosis_fields import fact_lines
from balancer_id.metric_fields import FIT_METRICS, metric_line
from balancer_id.numbers import format_number
from balancer_id.param_fields import PARAM_FIELDS, parameter_cells
from balancer_id.verdicts import Verdict


def _stderr(console: Console) -> Console:
    """The console messages and warnings go to: stderr, at the same width and colours."""
    if console.stderr:
        return console
    if sys.stderr is not None and sys.stderr.isatty():
        return Console(stderr=True)  # the terminal's own width
    # piped or redirected: as wide as the tables (rich's default of 80 columns would
    # break the warnings mid-sentence while the tables beside them run wider)
    return Console(stderr=True, width=console.width)


def print_command(console: Console, command: str, indent: str = "    ") -> None:
    """Print a shell command on a line of its own, never wrapped (so it can be copied).

    Parameters
    ----------
    console : rich.console.Console
        Where to print.
    command : str
        The command line.
    indent : str
        Put before it.
    """
    console.print(indent + command, soft_wrap=True, markup=False, highlight=False)


def _fmt(x: Any, digits: int = 4) -> str:
    return format_number(x, digits) if isinstance(x, float) else ("-" if x is None else str(x))


def print_inspection(console: Console, info: dict[str, Any]) -> None:
    """Print what ``inspect`` read and the trials it found.

    Parameters
    ----------
    console : rich.console.Console
        Where to print (the CLI's stdout console).
    info : dict
        The CONTRACT.md ``inspect`` object, as
        :func:`~balancer_id.trials.describe_log` returns it.
    """
    console.print(
        f"[bold]{info['file']}[/bold]  format={info['format']}  "
        f"rate={_fmt(info['sample_rate_hz'])} Hz  samples={info['n_samples']}  "
        f"runs={len(info.get('runs', []))}  gaps={len(info['gaps'])}"
    )
    for run in info.get("runs", []):
        console.print(
            f"  run {run['name']!r}: {run['n_samples']} samples at "
            f"{_fmt(run['sample_rate_hz'])} Hz, "
            f"channels: {', '.join(run['channels'])}"
        )
        if run.get("vertical"):
            known = (
                "sign known"
                if run.get("vertical_sign_known", True)
                else ("sign is a guess: fix it with --vertical or --force-sign")
            )
            if not run.get("vertical_axis_known", True):  # the axis itself is assumed
                known = "the axis is a guess, and its sign: give it with --vertical"
                if run.get("vertical_sign_known", True):
                    known = "the axis is a guess (its sign fixed): give it with --vertical"
            console.print(f"    vertical (up): {run['vertical']} ({known})")
    print_inferences(console, info.get("inferences", []))
    for w in info.get("warnings", []):  # the trials' warnings are there, named
        _stderr(console).print(f"  [yellow]warning:[/yellow] {w}")
    table = Table(title=trials_title(info["trials"]))
    cols = ("#", "run", "t_step (s)", "window (s)", "thrust (N)", "change (N)", "direction")
    for col in (*cols, "ends by"):
        table.add_column(col)
    for t in info["trials"]:
        table.add_row(
            str(t["index"]),
            str(t.get("recording", "")),
            f"{t['t_step']:.3f}",
            f"{t['t_start']:.2f} - {t['t_end']:.2f}",
            f"{t['thrust_N']:+.3f}",
            f"{t.get('thrust_change_N', t['thrust_N']):+.3f}",
            t["direction"],
            str(t.get("end_reason", "")),
        )
    console.print(table)


def print_inferences(console: Console, inferences: list[dict[str, Any]]) -> None:
    """Print what the reader decided, with its evidence and the option that overrides it.

    Parameters
    ----------
    console : rich.console.Console
        Where to print.
    inferences : list of dict
        The ``inspect`` object's ``inferences`` (CONTRACT.md).
    """
    if not inferences:
        return
    console.print("  read as:")
    for item in inferences:
        run = f"[{item['run']}] " if item.get("run") else ""
        mark = "[yellow]?[/yellow] " if item.get("weak") else ""
        console.print(f"    {mark}{escape(run + item['text'])}", highlight=False)


_KIND_TITLES = {
    "step": ("step trial", "step trials"),
    "move": ("robot move", "robot moves"),
    "guided": ("guided move", "guided moves"),
    "window": ("given window", "given windows"),
}


def trials_title(trials: list[dict[str, Any]]) -> str:
    """The title of ``inspect``'s table: what it found (step trials, a robot or guided move).

    Parameters
    ----------
    trials : list of dict
        The ``inspect`` trial records (their ``kind``; a record without one is a step trial).

    Returns
    -------
    str
        E.g. ``"step trials"``, ``"robot move"``, ``"1 guided move, 4 step trials"``.
    """
    counts: dict[str, int] = {}
    for t in trials:
        kind = str(t.get("kind", "step"))
        counts[kind] = counts.get(kind, 0) + 1
    if not counts:
        return "step trials (none found)"
    if len(counts) == 1:
        kind, n = next(iter(counts.items()))
        one, many = _KIND_TITLES.get(kind, (kind, f"{kind} windows"))
        return one if n == 1 and kind != "step" else many
    parts = []
    for kind, n in counts.items():
        one, many = _KIND_TITLES.get(kind, (kind, f"{kind} windows"))
        parts.append(f"{n} {one if n == 1 else many}")
    return ", ".join(parts)


def print_fit(console: Console, result: dict[str, Any]) -> None:
    """Print a fit result: parameters with uncertainties, the paper's method, errors.

    Parameters
    ----------
    console : rich.console.Console
        Where to print (the CLI's stdout console).
    result : dict
        The CONTRACT.md ``fit`` object (:meth:`FitResult.to_dict`); the per-trial table
        and the robot coupling are printed when it holds them.
    """
    if result.get("trusted") is False:  # lead with it: the user must not act on the values
        for why in result.get("untrusted_because", []):
            _stderr(console).print(f"[bold red]NOT TRUSTED:[/bold red] {why}")
    post = result.get("posterior") or {}
    console.print(_parameter_table(result, post))
    if post:  # issue 34.2: how well the chain mixed
        console.print(
            f"posterior: {post['n_walkers']} walkers x {post['n_steps']} steps, "
            f"acceptance {post['acceptance']:.2f}, "
            f"autocorrelation {max((q['tau_steps'] or 0) for q in post['parameters'].values()):.0f}"
            f" steps: {'converged' if post['converged'] else 'NOT converged (rough intervals)'}"
        )
    c = result["classic"]
    console.print(
        f"paper's method: m_a = {_fmt(c['m_a'])} kg (± {_fmt(c.get('m_a_stderr'), 2)}), "
        f"T_a = {_fmt(c['T_a'])} s, free-line intercept = {_fmt(c.get('intercept_N'), 3)} N"
    )
    console.print(f"errors: {metric_line(result['metrics'])}")
    trials = Table(title="per trial")
    for col in ("#", "thrust (N)", "direction", "RMSE (m/s²)"):
        trials.add_column(col)
    for t in result["trials"]:
        trials.add_row(str(t["index"]), f"{t['thrust_N']:+.3f}", t["direction"], _fmt(t["rmse"]))
    console.print(trials)
    _print_fit_extras(console, result)
    _print_fit_notes(console, result)


def _parameter_table(result: dict[str, Any], post: dict[str, Any]) -> Table:
    """The fit's parameters (:data:`~balancer_id.param_fields.PARAM_FIELDS`), with the
    credible interval after the 95 % one when the posterior was sampled."""
    table = Table(title=f"model {result['model']}: simulation matching over all trials")
    credible = {n: q.get("credible95") for n, q in post.get("parameters", {}).items()}
    headings = [f.heading for f in PARAM_FIELDS]
    if post:
        headings.insert(3, "95 % credible")
    for col in ("parameter", *headings):
        table.add_column(col)
    for name, p in result["parameters"].items():
        cells = list(parameter_cells(p).values())
        if post:
            cr = credible.get(name)
            cells.insert(3, f"{cr[0]:.4g} .. {cr[1]:.4g}" if cr else "-")
        table.add_row(name, *cells)
    return table


def _print_fit_extras(console: Console, result: dict[str, Any]) -> None:
    """The robot coupling, the tracked parameters and the per-trial fits, when present."""
    if "coupling" in result:
        cp = result["coupling"]
        console.print(
            f"robot coupling: oscillation {_fmt(cp['oscillation_hz'])} Hz, damping ratio "
            f"{_fmt(cp['damping_ratio'], 3)}, stability margin {_fmt(cp['stability_margin'], 3)}"
        )
        _print_robot(console, result)
    if result.get("tracking"):
        from balancer_id.identify.tracking import tracking_lines

        for line in tracking_lines(result["tracking"]):
            console.print(line, markup=False, soft_wrap=True)
    if result.get("per_trial"):
        per = Table(title="each trial alone (--per-trial)")
        names = list(result["parameters"])
        for col in ("#", "thrust (N)", "dir", *names, "RMSE"):
            per.add_column(col)
        for row in result["per_trial"]:
            per.add_row(
                str(row["index"]),
                f"{row['thrust_N']:+.3f}",
                row["direction"],
                *[_fmt(row["parameters"][n]["value"]) for n in names],
                _fmt(row["rmse"]),
            )
        console.print(per)


def _print_fit_notes(console: Console, result: dict[str, Any]) -> None:
    """The notes not already warnings (stdout), then the warnings (stderr)."""
    shown = set(result.get("warnings", []))
    for note in result.get("notes", []):
        text = note["text"] if isinstance(note, dict) else str(note)
        if text not in shown:
            console.print(f"note: {text}")
    err = _stderr(console)
    for w in result.get("warnings", []):
        if result.get("trusted") is False and w in result.get("untrusted_because", []):
            continue  # printed first
        err.print(f"[yellow]warning:[/yellow] {w}")


def _coupling_word(coupling: dict[str, Any]) -> str:
    """``UNSTABLE``, ``stable but lightly damped: vibrates`` or ``stable``."""
    if not coupling.get("stable"):
        return "UNSTABLE"
    if coupling.get("verdict") == "lightly damped":
        return f"stable but lightly damped: vibrates, damping {coupling['damping_ratio']:.2g}"
    return "stable"


def print_effects(console: Console, effects: list[dict[str, Any]]) -> None:
    """Print the effect library.

    Parameters
    ----------
    console : rich.console.Console
        Where to print (the CLI's stdout console).
    effects : list of dict
        One :meth:`Effect.describe` dict per effect, each with an added ``origin``.
    """
    table = Table(title="effects (join with '+' in --model; the base is always present)")
    for col in ("effect", "parameters", "meaning", "origin"):
        table.add_column(col)
    for e in effects:
        params = ", ".join(
            f"{p['name']} [{p['min']:g}..{p['max']:g}] {p['unit']}" for p in e["parameters"]
        )
        table.add_row(e["name"], params, e["summary"], e.get("origin", ""))
    console.print(table)


def print_compare(console: Console, result: dict[str, Any]) -> None:
    """Print the models side by side, overall and per trial, with their worst windows.

    Parameters
    ----------
    console : rich.console.Console
        Where to print (the CLI's stdout console).
    result : dict
        The CONTRACT.md ``compare`` object: ``{"models": [...]}``, one
        :meth:`ModelComparison.to_dict` per model, all on the same trials.
    """
    models = result["models"]
    if result.get("vibration"):  # issue 9: human against robot
        from balancer_id.diagnostics.vibration import vibration_lines

        for line in vibration_lines(result["vibration"]):
            console.print(line)
    # the same trials: one count of samples, in the title
    first = models[0]["metrics"] if models else {}
    samples = f" ({first['n_samples']} samples)" if "n_samples" in first else ""
    table = Table(title=f"models compared on the same trials{samples}")
    fields = [f for f in FIT_METRICS if f.key in first and f.key != "n_samples"]
    for col in ("model", *(f.heading for f in fields), "worst window"):
        table.add_column(col)
    for m in models:
        table.add_row(
            m["model"], *(f.format(m["metrics"].get(f.key)) for f in fields), _worst(m["worst"])
        )
    console.print(table)
    per = Table(title="RMSE per trial (m/s²)")
    per.add_column("#")
    per.add_column("thrust (N)")
    for m in models:
        per.add_column(m["model"])
    for k, row in enumerate(models[0]["trials"]):
        per.add_row(
            str(row["index"]),
            f"{row['thrust_N']:+.3f}",
            *[_fmt(m["trials"][k]["rmse"]) for m in models],
        )
    console.print(per)
    validation = result.get("validation")
    if validation:  # compare --params: does the identified model hold on these logs?
        _print_validation(console, validation)


def _worst(worst: list[dict[str, Any]]) -> str:
    """A model's worst window, in words."""
    w = worst[0] if worst else None
    return f"trial {w['trial']} {w['t_start']:.2f}-{w['t_end']:.2f} s" if w else "-"


def _print_validation(console: Console, validation: dict[str, Any]) -> None:
    """A saved model's verdict on new logs, and each test."""
    colour = "green" if validation["holds"] else "red"
    console.print(
        f"[bold {colour}]model {validation['model']} {validation['verdict']}[/bold "
        f"{colour}] on these logs (fit {validation['fit_percent']:.1f} %, nothing refitted)"
    )
    for test in validation["tests"]:
        mark = "ok  " if test["passed"] else "FAIL"
        console.print(f"  {mark} {test['name']}: {test['text']}", highlight=False)


def print_diagnosis(console: Console, result: dict[str, Any]) -> None:
    """Print the verdict, the residual tests and the ranked suggestions.

    Parameters
    ----------
    console : rich.console.Console
        Where to print (the CLI's stdout console).
    result : dict
        The CONTRACT.md ``diagnose`` object (:meth:`Diagnosis.to_dict`).
    """
    colour = "green" if result["verdict"] == Verdict.ADEQUATE else "red"
    m = result["metrics"]
    console.print(
        f"model [bold]{result['model']}[/bold]: [{colour}]{result['verdict']}[/{colour}]  "
        f"(RMSE {_fmt(m['rmse'])}, noise floor {_fmt(m['noise_floor'])}, "
        f"above the floor {_fmt(m['excess_rmse'])} m/s²)"
    )
    console.print(result["summary"])
    for line in fact_lines(result):
        console.print(line, markup=False, highlight=False)
    tests = result["residual_tests"]
    groups = tests.get("parameter_groups")
    if groups:
        console.print(_groups_table(groups))
    w = tests["whiteness"]
    if w.get("ljung_box_p") is not None:
        console.print(
            f"whiteness: {w['outside_band']} of {len(w['acf'])} autocorrelation lags outside "
            f"±{w['band']:.4f}; Ljung-Box Q = {w['ljung_box_q']:.1f}, p = {w['ljung_box_p']:.2g}"
        )
    xc = tests["input_cross_correlation"]
    console.print(
        f"residual against the thrust: peak {xc['peak_value']:+.4f} m/s² at "
        f"{xc['peak_lag_s']:.2f} s after the onset "
        f"({'significant' if xc['significant'] else 'within noise'})"
    )
    peaks = tests["spectrum"]["peaks"]
    if peaks:
        console.print(
            "spectrum peaks: "
            + ", ".join(f"{p['frequency_hz']:.2f} Hz ({p['ratio_to_median']:.0f}x)" for p in peaks)
        )
    reg = Table(title="residual by regime")
    for col in ("group", "label", "samples", "mean", "RMS", "RMS / noise"):
        reg.add_column(col)
    for r in tests["regimes"]:
        reg.add_row(
            r["group"],
            r["label"],
            str(r["n"]),
            f"{r['mean']:+.4f}",
            _fmt(r["rms"]),
            f"{r['rms_over_noise']:.2f}",
        )
    console.print(reg)
    sug = Table(title="suggestions (best first; score = BIC improvement of a quick refit)")
    for col in ("#", "change", "score", "error drop", "evidence"):
        sug.add_column(col, overflow="fold")
    for k, s in enumerate(result["suggestions"], 1):
        sug.add_row(
            str(k),
            s["change"],
            f"{s['score']:.1f}",
            f"{s['excess_error_drop']:.0%}",
            s["evidence"],
        )
    if result["suggestions"]:
        console.print(sug)
    elif not groups:  # an empty table says nothing: say why there is no suggestion
        why = "the model is adequate" if result.get("verdict") == "adequate" else (
            "no effect tried improves the fit enough"
        )
        console.print(f"suggestions: none ({why})")
    if result["suggestions"]:
        console.print("to try a suggestion, run its command:")
    for k, s in enumerate(result["suggestions"], 1):
        console.print(f"  {k}. {s['change']}:", markup=False, highlight=False)
        print_command(console, s["command"])
    if result.get("discovery"):
        _print_discovery(console, result["discovery"])
    for f in result.get("failed_candidates", []):
        _stderr(console).print(f"[yellow]candidate failed:[/yellow] {f}")


def _groups_table(groups: dict[str, Any]) -> Table:
    """A parameter's value run by run (the split test's groups)."""
    title = f"{groups['parameter']} per run (split test p = {groups['p_value']:.1e})"
    runs = Table(title=title)
    for col in ("#", "run", "value", "stderr", "|thrust| (N)"):
        runs.add_column(col)
    for k, r in enumerate(groups["runs"], start=1):
        runs.add_row(
            str(k), r["run"], f"{r['value']:.4g}", f"{r['stderr']:.2g}", f"{r['thrust_N']:.3g}"
        )
    return runs


def _print_discovery(console: Console, d: dict[str, Any]) -> None:
    """The discovered force: its terms, coefficients and inclusion, and the command."""
    table = Table(title=f"discovered term: {d['formula']} (N)")
    for col in ("term", "coefficient", "stderr", "unit", "inclusion"):
        table.add_column(col, overflow="fold")
    for t in d["terms"]:
        se = t["stderr"]
        table.add_row(
            t["expression"],
            f"{t['coefficient']:.4g}",
            "-" if se is None else f"{se:.2g}",
            t["unit"],
            f"{t['inclusion']:.0%}",
        )
    console.print(table)
    console.print(
        f"BIC falls by {d['bic_drop']:.0f}; RMSE after {_fmt(d['rmse_after'])} m/s². "
        "Write it as an effect and refit:"
    )
    print_command(console, d["command"])


def print_improve(console: Console, result: dict[str, Any]) -> None:
    """Print the ladder of models and the final verdict.

    Parameters
    ----------
    console : rich.console.Console
        Where to print (the CLI's stdout console).
    result : dict
        The CONTRACT.md ``improve`` object (:meth:`ImproveResult.to_dict`).
    """
    table = Table(title="improve: effects added while BIC and held-out trials improve")
    for col in ("step", "model", "added", "RMSE", "held-out RMSE", "BIC"):
        table.add_column(col, overflow="fold")  # a model is named whole, never cut
    for k, s in enumerate(result["steps"]):
        table.add_row(
            str(k),
            s["model"].replace("+", " + "),  # wraps at the effects in a narrow terminal
            s["added"] or "-",
            _fmt(s["rmse"]),
            _fmt(s["cv_rmse"]),
            f"{s['bic']:.1f}",
        )
    console.print(table)
    for r in result.get("rejected", []):
        console.print(f"[yellow]not taken:[/yellow] {r}")
    note = result.get("discovery_note")
    if note and note.get("code") != "improve.discovered":  # "wrote FILE" is said on stderr
        console.print(f"discovery: {note['text']}", markup=False)
    if result["steps"]:
        console.print("the final model's fit:")
        print_command(console, result["steps"][-1]["command"])
    console.print(f"final model: [bold]{result['final_model']}[/bold] — {result['final_summary']}")


def _print_robot(console: Console, result: dict[str, Any]) -> None:
    """The stability condition, its dominant terms and the advice (robot logs, issue 9)."""
    from balancer_id.identify.advice import advice_lines

    cond = result["coupling"].get("condition")
    if cond:
        console.print(
            f"stability: {cond['text']}: {cond['lhs']:.4g} vs {cond['rhs']:.4g} "
            f"({_coupling_word(result['coupling'])}); "
            f"dominated by {result['coupling'].get('dominant', '')}"
        )
    late = result.get("servo_delay")
    for line in late.get("lines", []) if late else []:
        console.print(line, markup=False)
    for line in advice_lines(result["advice"]) if result.get("advice") else []:
        console.print(line)


def print_groups(console: Console, result: dict[str, Any]) -> None:
    """Print one fit per group (``fit --group-by``), each under its group's label.

    Parameters
    ----------
    console : rich.console.Console
        Where to print.
    result : dict
        The ``fit --group-by`` JSON object (:meth:`GroupFits.to_dict`).
    """
    for item in result["groups"]:
        console.print(f"[bold]group {item['group']}[/bold]")
        print_fit(console, item)


def print_per_log(console: Console, result: dict[str, Any]) -> None:
    """Print a fit with per-log parameters (``fit --per-log``): the shared values, each
    log's own, the sharings compared and the verdict.

    Parameters
    ----------
    console : rich.console.Console
        Where to print.
    result : dict
        The ``fit --per-log`` JSON object (:meth:`PerLogFit.to_dict`).
    """
    from balancer_id.identify.per_log import per_log_lines

    for line in per_log_lines(result):
        console.print(line, markup=False, soft_wrap=True)


def print_plan(console: Console, result: dict[str, Any]) -> None:
    """Print a plan: the trials to record next and the intervals predicted after each.

    Parameters
    ----------
    console : rich.console.Console
        Where to print.
    result : dict
        The CONTRACT.md ``plan`` object (:meth:`~balancer_id.workflows.plan.Plan.to_dict`).
    """
    lines = result.get("text") or []
    if lines:
        console.print(f"[bold]{lines[0]}[/bold]", highlight=False)
    for line in lines[1:]:
        console.print(line, highlight=False)
