"""Readable terminal tables (rich) for each command's result."""

from __future__ import annotations

from typing import Any

from rich.console import Console
from rich.table import Table


def _fmt(x: Any, digits: int = 4) -> str:
    if x is None:
        return "-"
    if isinstance(x, float):
        return f"{x:.{digits}g}"
    return str(x)


def print_inspection(console: Console, info: dict[str, Any]) -> None:
    """Print what ``inspect`` read and the trials it found."""
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
    for w in info.get("warnings", []):
        console.print(f"  [yellow]warning:[/yellow] {w}")
    table = Table(title="step trials")
    for col in ("#", "run", "t_step (s)", "window (s)", "thrust (N)", "direction", "ends by"):
        table.add_column(col)
    for t in info["trials"]:
        table.add_row(
            str(t["index"]),
            str(t.get("recording", "")),
            f"{t['t_step']:.3f}",
            f"{t['t_start']:.2f} - {t['t_end']:.2f}",
            f"{t['thrust_N']:+.3f}",
            t["direction"],
            str(t.get("end_reason", "")),
        )
    console.print(table)


def print_fit(console: Console, result: dict[str, Any]) -> None:
    """Print a fit result: parameters with uncertainties, the paper's method, errors."""
    table = Table(title=f"model {result['model']}: simulation matching over all trials")
    for col in ("parameter", "value", "std. error", "95% interval", "unit", "note"):
        table.add_column(col)
    for name, p in result["parameters"].items():
        ci = p.get("ci95")
        note = "held" if not p["vary"] else (f"at {p['at_bound']} bound" if p["at_bound"] else "")
        table.add_row(
            name,
            _fmt(p["value"]),
            _fmt(p["stderr"], 2),
            f"{ci[0]:.4g} .. {ci[1]:.4g}" if ci else "-",
            p.get("unit", ""),
            note,
        )
    console.print(table)
    c = result["classic"]
    console.print(
        f"paper's method: m_a = {_fmt(c['m_a'])} kg (± {_fmt(c.get('m_a_stderr'), 2)}), "
        f"T_a = {_fmt(c['T_a'])} s, free-line intercept = {_fmt(c.get('intercept_N'), 3)} N"
    )
    m = result["metrics"]
    console.print(
        f"errors: RMSE = {_fmt(m['rmse'])} m/s^2, fit = {_fmt(m['nrmse_fit_percent'], 4)} %, "
        f"AIC = {m['aic']:.1f}, BIC = {m['bic']:.1f}, samples = {m['n_samples']}"
    )
    trials = Table(title="per trial")
    for col in ("#", "thrust (N)", "direction", "RMSE (m/s^2)"):
        trials.add_column(col)
    for t in result["trials"]:
        trials.add_row(str(t["index"]), f"{t['thrust_N']:+.3f}", t["direction"], _fmt(t["rmse"]))
    console.print(trials)
    if "coupling" in result:
        cp = result["coupling"]
        console.print(
            f"robot coupling: oscillation {_fmt(cp['oscillation_hz'])} Hz, damping ratio "
            f"{_fmt(cp['damping_ratio'], 3)}, stability margin {_fmt(cp['stability_margin'], 3)}"
        )
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
    for w in result.get("warnings", []):
        console.print(f"[yellow]warning:[/yellow] {w}")


def print_effects(console: Console, effects: list[dict[str, Any]]) -> None:
    """Print the effect library."""
    table = Table(title="effects (join with '+' in --model; the base is always present)")
    for col in ("effect", "parameters", "meaning", "origin"):
        table.add_column(col)
    for e in effects:
        params = ", ".join(
            f"{p['name']} [{p['min']:g}..{p['max']:g}] {p['unit']}" for p in e["parameters"]
        )
        table.add_row(e["name"], params, e["summary"], e.get("origin", ""))
    console.print(table)
