"""Every command the README shows, run as written, in the README's order, with its claims.

The commands are read from README.md itself (the fenced first lines and every
```balancer-id ...``` span), so a command edited there is the command tested here. Only
templates (placeholders in capitals, ``batch DIR --out OUT``; options in brackets), a
command named in prose without its logs, and
``--install-completion`` (it edits the user's shell start-up file) are left out.
"""

from __future__ import annotations

import json
import math
import re
import shlex
import shutil
from pathlib import Path

import pytest
from conftest import REPO

#: The commands build on each other and take minutes: one worker runs them all (their
#: module-scoped work folder groups them, conftest.py), started first.
pytestmark = pytest.mark.slow

README = (REPO / "README.md").read_text(encoding="utf-8")
LOG_COMMANDS = {"inspect", "fit", "compare", "diagnose", "improve", "batch", "report"}



def readme_commands() -> list[str]:
    """The runnable ``balancer-id`` command lines of the README, in order of appearance."""
    found: list[tuple[int, str]] = []
    for block in re.finditer(r"```bash\n(.*?)```", README, re.S):
        for line in block.group(1).splitlines():
            for part in line.split("&&"):
                if part.strip().startswith("balancer-id "):
                    found.append((block.start(), part.strip()))
    for span in re.finditer(r"`(balancer-id [^`]+)`", README):
        found.append((span.start(), " ".join(span.group(1).split())))
    runnable = []
    for _, command in sorted(found):
        words = shlex.split(command)
        if "--install-completion" in words:
            continue
        if any(re.fullmatch(r"[A-Z][A-Z_.]+", w) or w.startswith("[") for w in words):
            continue  # a template: batch DIR --out OUT, effects [--json]
        if words[1] in LOG_COMMANDS and not any(w.endswith((".csv", "/")) for w in words):
            continue  # a command named in prose ("`balancer-id fit` run a second time")
        runnable.append(command)
    return runnable


COMMANDS = readme_commands()


def test_the_readme_commands_are_found():
    # the walk-through, the robot section and the main line are all there
    assert any(c.startswith("balancer-id batch sample_logs/*.csv") for c in COMMANDS)
    assert sum("hose_walkthrough" in c for c in COMMANDS) >= 3
    assert any("--model variable_viscosity+servo" in c for c in COMMANDS)
    assert len(COMMANDS) >= 8


#: The commands run so far in each work folder (by this worker).
RAN: dict[str, list[str]] = {}


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    """A fresh folder holding the README's inputs: sample_logs/, examples/ and logs/."""
    root = tmp_path_factory.mktemp("readme")
    shutil.copytree(REPO / "sample_logs", root / "sample_logs")
    shutil.copytree(REPO / "examples", root / "examples")
    (root / "logs").mkdir()  # "batch logs/": a plant's folder of logs
    for log in (REPO / "sample_logs").glob("*.csv"):
        shutil.copy(log, root / "logs" / log.name)
    return root


def run_readme_command(cli, root: Path, command: str) -> tuple[int, str, str]:
    """Run one README line in ``root``: globs expanded, ``> FILE`` written, as a shell."""
    words = shlex.split(command)[1:]
    target = None
    if ">" in words:
        at = words.index(">")
        words, target = words[:at], words[at + 1]
    args: list[str] = []
    for w in words:
        matches = sorted(str(p.relative_to(root)) for p in root.glob(w)) if "*" in w else []
        args.extend(matches or [w])
    code, out, err = cli(*args)
    if target is not None:
        (root / target).write_text(out, encoding="utf-8")
    return code, out, err


@pytest.mark.parametrize("command", COMMANDS, ids=[c[12:60] for c in COMMANDS])
def test_a_readme_command_runs_and_says_what_the_readme_says(cli, workdir, monkeypatch, command):
    monkeypatch.chdir(workdir)
    # the commands build on each other (a batch writes results/, a fit saves a model):
    # under xdist this worker may not have run the earlier ones; it runs them first
    ran = RAN.setdefault(str(workdir), [])
    for earlier in COMMANDS[: COMMANDS.index(command)]:
        if earlier not in ran:
            run_readme_command(cli, workdir, earlier)
            ran.append(earlier)
    code, out, err = run_readme_command(cli, workdir, command)
    ran.append(command)
    assert code == 0, f"{command}\n{err}"
    assert "Traceback" not in err
    words = shlex.split(command)
    for flag in ("--report", "--vibration-plot"):
        if flag in words:
            written = workdir / words[words.index(flag) + 1]
            assert written.stat().st_size > 1000, written
            assert f"wrote {words[words.index(flag) + 1]}" in err
    if words[1] == "batch":
        out_dir = workdir / words[words.index("--out") + 1]
        rows = (out_dir / "summary.csv").read_text(encoding="utf-8").splitlines()
        logs = [w for w in words[2:] if w.endswith(".csv") or w.endswith("/")]
        assert len(rows) - 1 >= len(logs) and all(",ok," in r for r in rows[1:]), rows
        if "--diagnose" in words:
            # every sample log diagnosed without failing (the hose walk-through's is not
            # diagnosed again in test_diagnose_never_fails_on_a_sample_log)
            docs = [json.loads(p.read_text(encoding="utf-8")) for p in out_dir.glob("*.json")]
            assert len(docs) == len(rows) - 1
            for doc in docs:
                assert doc["diagnosis"]["verdict"] in ("adequate", "effect missing"), doc
                assert math.isfinite(doc["metrics"]["rmse"]), doc
    if words[1] == "diagnose" and "--effects-file" not in words:
        # walk-through step 1: a missing effect that no built-in explains; the position;
        # the force discovered with the hose's stiffness (truth 4 N/m)
        assert "effect missing" in out and "position" in out
        k = float(re.search(r"F = (-[0-9.]+)\*z", out).group(1))
        assert k == pytest.approx(-4.0, rel=0.03), out
    if words[1] == "diagnose" and "--effects-file" in words:
        # step 3: the user's effect is ranked first, with the command that fits it
        first = re.search(r"^\s*1\. (\S+):$", out, re.M)
        assert first is not None and first.group(1) == "+hose_spring", out
    if words[1] == "improve":
        # step 2: the discovered force is written, added, and the error falls to the noise
        # floor (0.03)
        name = Path(words[words.index("--effects-out") + 1])
        assert (workdir / name).read_text().startswith("# Written by balancer-id")
        last = next(line for line in out.splitlines() if f"│ {name.stem}" in line)
        rmse = float(last.split("│")[4])
        assert 0.025 < rmse < 0.035, out
        assert "consistent with noise" in " ".join(out.split())
    if "--json" in words:
        assert json.loads((workdir / words[-1]).read_text())["model"] == "variable_viscosity"
    if "--model" in words and "variable_viscosity+servo" in words and words[1] == "fit":
        # robot step 2: the servo of the simulated robot (truth 150 N/m, 100 N s/m)
        k_r = float(re.search(r"k_r\W+([0-9.]+)", out).group(1))
        c_r = float(re.search(r"c_r\W+([0-9.]+)", out).group(1))
        assert k_r == pytest.approx(150, rel=0.03) and c_r == pytest.approx(100, rel=0.03)
        _assert_readme_robot_numbers(out)


def _readme_number(pattern: str) -> float:
    """A number the README quotes, found by ``pattern`` (one group) in its text."""
    found = re.search(pattern, " ".join(README.split()))
    assert found is not None, pattern
    return float(found.group(1))


#: The simulated check of the advised viscosity: its frequency and damping.
D0_CHECK = r"D0 .*?simulated: ([0-9.]+) Hz, damping ([0-9.]+)"


def _assert_readme_robot_numbers(out: str) -> None:
    """Every number the README quotes for the robot step is what the command prints (to the
    README's rounding): the mode's damping, the stability condition's two sides, the
    advised settings and their simulated check."""
    flat = " ".join(out.split())
    printed = {
        "damping": float(re.search(r"damping ratio ([0-9.]+), stability margin", flat).group(1)),
        "left": float(re.search(r"k_r: ([0-9.]+) vs ([0-9.]+)", flat).group(1)),
        "right": float(re.search(r"k_r: ([0-9.]+) vs ([0-9.]+)", flat).group(2)),
        "k_r_to": float(re.search(r"k_r \(N/m\): [0-9.]+ -> ([0-9.]+)", flat).group(1)),
        "d0_to": float(re.search(r"D0 \(kg/s\): [0-9.]+ -> ([0-9.]+)", flat).group(1)),
        "d0_from": float(re.search(r"D0 \(kg/s\): ([0-9.]+) ->", flat).group(1)),
        "d0_hz": float(re.search(D0_CHECK, flat).group(1)),
        "d0_damping": float(re.search(D0_CHECK, flat).group(2)),
    }
    quoted = {
        "damping": _readme_number(r"0\.66 Hz with damping ratio ([0-9.]+)"),
        "left": _readme_number(r"stability condition \(([0-9.]+) vs"),
        "right": _readme_number(r"stability condition \([0-9.]+ vs ([0-9.]+)\)"),
        "k_r_to": _readme_number(r"k_r from [0-9.]+ to ([0-9.]+) N/m"),
        "d0_to": _readme_number(r"[0-9]+-fold \(to ([0-9.]+) kg/s\)"),
        "d0_fold": _readme_number(r"would have to grow ([0-9.]+)-fold"),
        "d0_hz": _readme_number(r"moving to ([0-9.]+) Hz with damping"),
        "d0_damping": _readme_number(r"Hz with damping ([0-9.]+): the check"),
    }
    assert printed["damping"] == pytest.approx(quoted["damping"], abs=0.006)
    # the README rounds to units; a change of the balancer's fit in its last digits moves
    # the sides by a unit or two
    assert printed["left"] == pytest.approx(quoted["left"], abs=2.0)
    assert printed["right"] == pytest.approx(quoted["right"], abs=2.0)
    assert printed["k_r_to"] == pytest.approx(quoted["k_r_to"], abs=0.6)
    assert printed["d0_to"] == pytest.approx(quoted["d0_to"], abs=0.6)
    assert printed["d0_to"] / printed["d0_from"] == pytest.approx(quoted["d0_fold"], abs=0.5)
    assert printed["d0_hz"] == pytest.approx(quoted["d0_hz"], abs=0.006)
    assert printed["d0_damping"] == pytest.approx(quoted["d0_damping"], abs=0.006)
    # step 5: the robot's servo acts at once: "none found", at most a few ms
    late = re.search(r"servo delay: none found .*?at most ([0-9.]+) ms", flat)
    quoted_late = _readme_number(r'"none found", at most ([0-9.]+) ms')
    assert late is not None and float(late.group(1)) == pytest.approx(quoted_late, abs=1.0)
