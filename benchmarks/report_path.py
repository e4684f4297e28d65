"""The full report's data path (issue 30): the modules a fit's report passes through.

Fits a log (outside the trace), then traces ``write_fit_report(result, FILE)`` (what
``balancer-id fit LOG --report FILE`` runs after the fit) with :func:`sys.setprofile`:
every change of the package module that runs is a *stay*; it prints the stays, the
modules visited, the modules entered again after being left, and the *returns up the
layers* (control coming back from a module of a lower import layer to one of a higher
layer, pyproject.toml's ``[tool.importlinter]`` order; the package's top-level modules
are the ground floor).

Usage: ``python benchmarks/report_path.py [LOG] [--model SPEC] [--list]`` (no
randomness: the log is read as it is; default ``sample_logs/paper_balancer.csv``).
"""

from __future__ import annotations

import argparse
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ["cli", "batch", "workflows", "report", "diagnostics", "identify", "trials",
          "simulation", "model", "segment", "read"]


def floor(module: str) -> int:
    """The import layer of a ``balancer_id`` module (0: a top-level helper module)."""
    parts = module.split(".")
    if len(parts) > 1 and parts[1] in LAYERS:
        return len(LAYERS) - LAYERS.index(parts[1])
    return 0


def trace(fn, *args, **kwargs) -> list[tuple[str, str]]:
    """Run ``fn`` and return its stays: (module, event that entered it)."""
    stays: list[tuple[str, str]] = []

    def profile(frame, event, arg):  # sys.setprofile calls it so
        if event == "call":
            module = frame.f_globals.get("__name__", "")
        elif event == "return" and frame.f_back is not None:
            module = frame.f_back.f_globals.get("__name__", "")
        else:
            return
        if not module.startswith("balancer_id"):
            return
        if not stays or stays[-1][0] != module:
            stays.append((module, event))

    sys.setprofile(profile)
    try:
        fn(*args, **kwargs)
    finally:
        sys.setprofile(None)
    return stays


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("log", nargs="?", default=str(ROOT / "sample_logs/paper_balancer.csv"))
    parser.add_argument("--model", default=None)
    parser.add_argument("--list", action="store_true", help="print every stay")
    args = parser.parse_args()

    from balancer_id.identify import fit
    from balancer_id.report.document import write_fit_report

    result = fit(args.log, model=args.model)
    with tempfile.TemporaryDirectory() as tmp:
        write_fit_report(result, Path(tmp) / "warm.html")  # imports and fonts, untraced
        stays = trace(write_fit_report, result, Path(tmp) / "r.html")
    seen: set[str] = set()
    again = 0
    up = 0
    for k, (module, event) in enumerate(stays):
        if module in seen:
            again += 1
        seen.add(module)
        if k and event == "return" and floor(module) > floor(stays[k - 1][0]):
            up += 1
        if args.list:
            print(f"{k + 1:4d}. floor {floor(module):2d} {event:6s} {module}")
    print(f"report data path of {Path(args.log).name} ({result.model}):")
    print(f"  stays: {len(stays)}; modules: {len(seen)}; entered again: {again}; "
          f"returns up the layers: {up}")


if __name__ == "__main__":
    main()
