"""The fault suite: bad files, bad option values, output safety, special and hostile input.

Each case runs the installed command as a user would (``python -m balancer_id ...``) and
checks what CONTRACT.md promises: the exit code of the mistake, one line on stderr naming
it, never a traceback, with ``--json`` one JSON object on stdout, and no input changed.

    python benchmarks/faults.py            # every case, a table by class
    python benchmarks/faults.py --quick    # the cases CI runs (tests/test_fault_suite.py)

Files are generated in a temporary folder, never committed.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "sample_logs" / "paper_balancer.csv"


@dataclass
class Case:
    """One command run and what it must give."""

    kind: str
    name: str
    argv: list[str]
    code: int
    says: str = ""
    quick: bool = False
    json_out: bool = False
    make: Callable[[Path], None] | None = None
    keep: list[str] = field(default_factory=list)  # files that must be unchanged after
    absent: list[str] = field(default_factory=list)  # files that must not exist after
    env: dict[str, str] = field(default_factory=dict)  # set for the command


def _write(name: str, data: bytes | str) -> Callable[[Path], None]:
    def make(root: Path) -> None:
        path = root / name
        path.parent.mkdir(parents=True, exist_ok=True)
        if isinstance(data, bytes):
            path.write_bytes(data)
        else:
            path.write_text(data, encoding="utf-8")

    return make


def _copy(name: str) -> Callable[[Path], None]:
    return _write(name, SAMPLE.read_bytes())


def _both(*makers: Callable[[Path], None]) -> Callable[[Path], None]:
    def make(root: Path) -> None:
        for m in makers:
            m(root)

    return make


BAD_FILES: dict[str, tuple[bytes | str, int, str]] = {
    # name: (content, exit code, what the message says)
    "empty.csv": (b"", 3, "empty"),
    "binary.csv": (bytes(range(256)) * 8, 3, ""),
    "header_only.csv": ("Time (s),Force (N),Acceleration (m/s²)\n", 3, ""),
    "one_row.csv": ("Time (s),Force (N),Acceleration (m/s²)\n0,1,9.8\n", 3, "row"),
    "no_columns.csv": ("p,q\n1,2\n3,4\n", 3, "no time, force or acceleration column"),
    "text_cells.csv": ("Time (s),Force (N),Acceleration (m/s²)\n0,x,y\n0.005,x,y\n", 3, ""),
    "zip.csv": (b"PK\x03\x04" + b"\x00" * 64, 3, "zip"),
    "nan_cells.csv": (
        "Time (s),Force (N),Acceleration (m/s²)\n"
        + "".join(f"{k * 0.005},nan,nan\n" for k in range(400)),
        3,
        "",
    ),
    "flat.csv": (
        "Time (s),Force (N),Acceleration (m/s²)\n"
        + "".join(f"{k * 0.005},0.0,9.8\n" for k in range(2000)),
        4,
        "no step trial",
    ),
}


#: The bad files CI tries (``--quick``).
QUICK_FILES = ("empty.csv", "binary.csv", "no_columns.csv", "flat.csv")
#: The bad option values CI tries (by their first distinctive word).
QUICK_USAGE = ("m_a=30:20", "+", "runs:1-3,2-4", "1e308", "--nosuch", "-1")


def cases() -> list[Case]:
    """Every case of the suite."""
    out: list[Case] = []
    # -- bad files x commands ----------------------------------------------------------
    for name, (content, code, says) in BAD_FILES.items():
        for command in ("inspect", "fit", "diagnose", "report"):
            extra = ["--out", "r.html"] if command == "report" else ["--json"]
            code_here = code
            out.append(
                Case(
                    "bad file",
                    f"{command} {name}",
                    [command, name, *extra],
                    code_here,
                    says if code_here else "",
                    quick=command == "fit" and name in QUICK_FILES,
                    json_out=command != "report",
                    make=_write(name, content),
                    keep=[name],
                )
            )
    out.append(
        Case("bad file", "fit missing.csv", ["fit", "missing.csv"], 3, "file not found", quick=True)
    )
    out.append(
        Case(
            "bad file",
            "fit a folder",
            ["fit", "folder"],
            3,
            "folder",
            make=lambda root: (root / "folder").mkdir(),
        )
    )
    # -- bad option values: a usage error, exit 2 -------------------------------------
    usage = [
        (["fit", "log.csv", "--bounds", "m_a=30:20"], "give MIN < MAX"),
        (["fit", "log.csv", "--bounds", "m_a=nan:20"], "give MIN < MAX"),
        (["fit", "log.csv", "--bounds", "m_a=5"], "NAME=MIN:MAX"),
        (["fit", "log.csv", "--model", "+"], "empty effect name"),
        (["fit", "log.csv", "--model", "nosuch"], "nosuch"),
        (["fit", "log.csv", "--group-by", "runs:1-3,2-4"], "in two groups"),
        (["fit", "log.csv", "--group-by", ""], "--group-by"),
        (["fit", "log.csv", "--model", "viscous+servo"], "--trajectory"),
        (["fit", "log.csv", "--starts", "0"], "--starts"),
        (["fit", "log.csv", "--starts", "1e308"], "--starts"),
        (["fit", "log.csv", "--fix", "zz=1"], "zz"),
        (["fit", "log.csv", "--g", "-9.8"], "--g"),
        (["fit", "log.csv", "--nosuch"], "No such option"),

        (["simulate", "--thrust", "inf", "--out", "s.csv"], "--thrust"),
        (["simulate", "--thrust", "1e308", "--out", "s.csv"], "--thrust"),
        (["simulate", "--noise", "1e308", "--out", "s.csv"], "--noise"),
        (["simulate", "--rate", "1e308", "--out", "s.csv"], "--rate"),
        (["simulate", "--seed", "-1", "--out", "s.csv"], "--seed"),
        (["simulate", "--model", "viscous+servo", "--out", "s.csv"], "--trajectory"),
        (["batch", "log.csv", "--out", "o", "--jobs", "0"], "--jobs"),
    ]
    for argv, says in usage:
        out.append(
            Case(
                "bad option value",
                " ".join(argv[2:] if argv[0] != "simulate" else argv[1:]),
                [*argv, "--json"],
                2,
                says,
                quick=any(q in argv for q in QUICK_USAGE),
                json_out=True,
                make=_copy("log.csv"),
                keep=["log.csv"],
            )
        )
    out.append(
        Case(
            "bad option value",
            "--columns naming columns the file lacks (the log cannot be read so: 3)",
            ["fit", "log.csv", "--columns", "time=Nope,force=Nope2,a=Nope3"],
            3,
            "Nope",
            make=_copy("log.csv"),
        )
    )
    out.append(
        Case(
            "bad option value",
            "--params with NaN",
            ["fit", "log.csv", "--params", "p.json"],
            2,
            "p.json",
            make=_both(_copy("log.csv"), _write("p.json", '{"m_a": NaN}')),
        )
    )
    out.append(
        Case(
            "bad option value",
            "binary --params",
            ["fit", "log.csv", "--params", "p.json"],
            2,
            "p.json",
            make=_both(_copy("log.csv"), _write("p.json", b"\x00\xff\xfe")),
        )
    )
    out.append(
        Case(
            "bad option value",
            "binary trajectory",
            ["fit", "log.csv", "--model", "viscous+servo", "--trajectory", "m.csv"],
            3,
            "not a text file",
            make=_both(_copy("log.csv"), _write("m.csv", b"\x00\xff\xfe")),
        )
    )
    # -- output safety: nothing the user gave is overwritten ---------------------------
    safety = [
        (["inspect", "log.csv", "--plot", "log.csv"], "log.csv"),
        (["fit", "log.csv", "--report", "log.csv", "--overwrite"], "log.csv"),
        (["fit", "log.csv", "--save", "mine.json"], "--overwrite"),
        (["simulate", "--params", "mine.json", "--out", "mine.json", "--overwrite"], "mine.json"),
        (["batch", "log.csv", "--out", "o"], "log"),
    ]
    for argv, says in safety:
        out.append(
            Case(
                "output safety",
                " ".join(argv),
                argv,
                2,
                says,
                quick=argv[0] != "inspect",
                make=_both(
                    _copy("log.csv"),
                    _write("mine.json", '{"m_a": 15.0}'),
                    _write("o/log.json", '{"mine": true}'),
                ),
                keep=["log.csv", "mine.json", "o/log.json"],
            )
        )
    # -- hostile input ----------------------------------------------------------------
    escape = "\x1b]0;pwned\x07\x1b[2J"
    out.append(
        Case(
            "hostile input",
            "escape codes in a header",
            ["inspect", "h.csv"],
            3,
            "",
            make=_write("h.csv", f"a{escape},b\n1,2\n"),
        )
    )
    out.append(
        Case(
            "hostile input",
            "a 1 MB line",
            ["inspect", "long.csv"],
            3,
            "",
            make=_write("long.csv", "x" * 1_000_000 + "\n1\n"),
        )
    )
    out.append(
        Case(
            "hostile input",
            "symlink loop in a batch folder",
            ["batch", "loop", "--out", "o2"],
            2,
            "no log found",
            make=_symlink_loop,
        )
    )
    out += _hostile_machine_cases()
    # -- the sample works (the suite's control) ----------------------------------------
    out.append(
        Case(
            "control",
            "fit the sample",
            ["fit", "log.csv", "--json"],
            0,
            quick=True,
            json_out=True,
            make=_copy("log.csv"),
            keep=["log.csv"],
        )
    )
    return out


#: A module that leaves a file ``ran`` when imported: planted in the working folder.
_PLANTED = "open('ran', 'w').write('planted code ran')\n"


def _link(name: str, target: str) -> Callable[[Path], None]:
    def make(root: Path) -> None:
        os.symlink(target, root / name)

    return make


def _closed_port(root: Path) -> None:
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        (root / "port").write_text(str(sock.getsockname()[1]))


def _hostile_machine_cases() -> list[Case]:
    """Issue 29's attacker and newcomer list, one class each: what a hostile folder, name,
    environment or address does, and the contract's answer."""
    log = _copy("log.csv")
    move = _write("move.csv", "time,position\n0,0\n1,0.1\n2,0.2\n")
    weird = "x$\\frac$ \udcff.csv"
    return [
        Case("same output twice", "fit --report x --series x", ["fit", "log.csv", "--report",
             "x.html", "--series", "x.html"], 2, "same file", make=log, keep=["log.csv"],
             absent=["x.html"]),
        Case("output is an input", "inspect --plot move.csv --trajectory move.csv",
             ["inspect", "log.csv", "--plot", "move.csv", "--trajectory", "move.csv",
              "--overwrite"], 2, "one of the inputs", make=_both(log, move),
             keep=["move.csv"]),
        Case("output is a link", "fit --save link --overwrite", ["fit", "log.csv", "--save",
             "link.json", "--overwrite"], 2, "symbolic link",
             make=_both(log, _write("target.json", "{}"), _link("link.json", "target.json")),
             keep=["target.json"]),
        Case("output is a link loop", "fit --report loop.html", ["fit", "log.csv", "--report",
             "a.html"], 2, "symbolic link",
             make=_both(log, _link("a.html", "b.html"), _link("b.html", "a.html"))),
        Case("effects file is a link loop", "fit --effects-file loop.py", ["fit", "log.csv",
             "--effects-file", "a.py", "--json"], 3, "symbolic link", json_out=True,
             make=_both(log, _link("a.py", "b.py"), _link("b.py", "a.py"))),
        Case("trajectory not finite", "--trajectory distance=nan", ["inspect", "log.csv",
             "--trajectory", "trapezoid:distance=nan,speed=0.1,accel=0.5"], 2,
             "not a finite number", make=log),
        Case("scheduler unknown host", "batch --scheduler no-such-host.invalid",
             ["batch", "log.csv", "--out", "o", "--scheduler", "tcp://no-such-host.invalid:8786"],
             2, "is not known", make=log),
        Case("formula-looking and control names", "batch of =cmd.csv and cr\\r.csv",
             ["batch", "logs", "--out", "o", "--jobs", "1"], 0,
             make=_both(_copy("logs/=cmd.csv"), _copy("logs/cr\rname.csv"))),
        Case("mathtext and non-UTF-8 names", "fit x$\\frac$ \\xff.csv --report",
             ["fit", weird, "--report", "r.pdf"], 0, make=_copy(weird)),
        Case("ascii terminal", "PYTHONIOENCODING=ascii fit", ["fit", "log.csv"], 0, make=log,
             env={"PYTHONIOENCODING": "ascii"}),
        Case("planted module in the working folder", "batch with multiprocessing.py here",
             ["batch", "logs", "--out", "o", "--jobs", "2"], 0,
             make=_both(_copy("logs/a.csv"), _copy("logs/b.csv"),
                        _write("multiprocessing.py", _PLANTED)),
             absent=["ran"]),
        Case("shared numba cache", "NUMBA_CACHE_DIR writable by all", ["fit", "log.csv"], 0,
             make=_both(log, _shared_folder("shared")), env={"NUMBA_CACHE_DIR": "shared"},
             absent=["shared/x"]),
    ]


def _shared_folder(name: str) -> Callable[[Path], None]:
    def make(root: Path) -> None:
        folder = root / name
        folder.mkdir()
        folder.chmod(0o777)

    return make


def _symlink_loop(root: Path) -> None:
    folder = root / "loop"
    folder.mkdir()
    os.symlink("b", folder / "a")
    os.symlink("a", folder / "b")


def _digest(path: Path) -> str | None:
    return hashlib.sha256(path.read_bytes()).hexdigest() if path.is_file() else None


def run_case(case: Case, root: Path, timeout: float = 120.0) -> tuple[bool, str]:
    """Run one case in ``root``; (passed, why not)."""
    if case.make is not None:
        case.make(root)
    before = {k: _digest(root / k) for k in case.keep}
    env = {**os.environ, "BALANCER_ID_NO_CACHE": "1", **case.env}
    try:
        res = subprocess.run(
            [sys.executable, "-m", "balancer_id", *case.argv],
            cwd=root,
            capture_output=True,
            text=True,
            timeout=timeout,
            env=env,
        )
    except subprocess.TimeoutExpired:
        return False, f"hung (> {timeout:.0f} s)"
    problems = []
    if res.returncode != case.code:
        problems.append(f"exit {res.returncode}, expected {case.code}")
    if "Traceback" in res.stderr:
        problems.append("traceback")
    if case.code != 0:
        errors = [ln for ln in res.stderr.splitlines() if ln.startswith("balancer-id: error:")]
        if len(errors) != 1:
            problems.append(f"{len(errors)} error lines")
        elif case.says and case.says.lower() not in errors[0].lower():
            problems.append(f"message lacks {case.says!r}: {errors[0][:160]}")
        if any(ord(ch) < 32 and ch not in "\n\t" for ch in res.stderr):
            problems.append("control characters on stderr")
    if case.json_out:
        try:
            data = json.loads(res.stdout)
            if case.code != 0 and data.get("error", {}).get("exit_code") != case.code:
                problems.append("JSON error object lacks the exit code")
        except ValueError:
            problems.append("stdout is not one JSON object")
    for name, digest in before.items():
        if digest is not None and _digest(root / name) != digest:
            problems.append(f"{name} was changed")
    for name in case.absent:
        found = root / name
        if name.endswith("/x"):  # a folder that must stay empty
            if any(found.parent.iterdir()):
                problems.append(f"{found.parent.name}/ was written into")
        elif found.exists():
            problems.append(f"{name} exists ({found.read_text(errors='replace')[:60]!r})")
    return not problems, "; ".join(problems)


def main(argv: list[str] | None = None) -> int:
    """Run the suite; print one line per failure and a table by class."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true", help="only the cases CI runs")
    args = parser.parse_args(argv)
    chosen = [c for c in cases() if c.quick or not args.quick]
    passed: Counter[str] = Counter()
    total: Counter[str] = Counter()
    started = time.perf_counter()
    for case in chosen:
        with tempfile.TemporaryDirectory() as tmp:
            ok, why = run_case(case, Path(tmp))
        total[case.kind] += 1
        passed[case.kind] += ok
        if not ok:
            print(f"FAIL [{case.kind}] {case.name}: {why}", flush=True)
    print(f"\n{'class':<20} {'cases':>6} {'as promised':>12}")
    for kind in total:
        print(f"{kind:<20} {total[kind]:>6} {passed[kind]:>12}")
    print(
        f"{'all':<20} {sum(total.values()):>6} {sum(passed.values()):>12}"
        f"   ({time.perf_counter() - started:.0f} s)"
    )
    return 0 if passed == total else 1


if __name__ == "__main__":
    raise SystemExit(main())
