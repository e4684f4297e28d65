"""A newcomer's machine and a hostile one (issue 29): the set-up leaves nothing inside the
installed package, caches are private and keyed on what changes the answer, outputs
honour the umask and never replace links or devices, names cannot drive a terminal or a
spreadsheet, and every failure is one line with the contract's exit code."""

from __future__ import annotations

import io
import json
import os
import stat
import subprocess
import sys
from pathlib import Path

import pytest
from conftest import REPO, SAMPLE_LOGS

from balancer_id.errors import UsageError
from balancer_id.files import atomic_write_text, check_output, private_folder

POSIX_ROOT = hasattr(os, "geteuid") and os.geteuid() == 0


def _python(code: str, env: dict[str, str], cwd: Path | None = None) -> str:
    """Run ``code`` in a fresh interpreter importing this checkout; its stdout."""
    full = {k: v for k, v in os.environ.items() if k != "NUMBA_CACHE_DIR"}
    full.update(PYTHONPATH=str(REPO), **env)
    done = subprocess.run(
        [sys.executable, "-c", code], env=full, cwd=cwd, capture_output=True, text=True,
        timeout=120, check=True,
    )
    return done.stdout.strip()


# --- numba's cache: never inside the package, never in another user's folder ------------


def test_numba_caches_into_the_private_cache_folder_not_the_package(tmp_path):
    package = REPO / "balancer_id" / "simulation"
    before = set(package.rglob("*.nb[ic]"))
    shared = tmp_path / "shared"
    shared.mkdir()
    shared.chmod(0o777)  # a NUMBA_CACHE_DIR anyone could plant a pickle in
    out = _python(
        "import numpy as np\n"
        "from balancer_id.simulation.filters import first_order_lag\n"
        "print(round(float(first_order_lag(np.ones(50), 0.5)[-1]), 6))",
        {"BALANCER_ID_CACHE": str(tmp_path / "cache"), "NUMBA_CACHE_DIR": str(shared)},
    )
    assert float(out) == pytest.approx(1.0)  # the lag's step response after 49 samples
    cached = list((tmp_path / "cache" / "numba").rglob("*.nbi"))
    assert cached, "nothing was cached"
    assert stat.S_IMODE((tmp_path / "cache" / "numba").stat().st_mode) == 0o700
    assert set(package.rglob("*.nb[ic]")) == before  # nothing new beside the sources
    assert not list(shared.iterdir())  # the shared folder is neither read nor written


def test_kernels_cache_beside_themselves_and_other_code_follows_numba(tmp_path, monkeypatch):
    from balancer_id.simulation.jit import private_cache_path

    monkeypatch.setenv("BALANCER_ID_CACHE", str(tmp_path / "c"))
    kernel = tmp_path / "c" / "kernels" / "bid_kernel_x.py"
    assert private_cache_path(str(kernel)) == str(kernel.parent / "__pycache__")
    assert private_cache_path(str(tmp_path / "user_code.py")) is None


def test_the_cache_folder_must_be_private_real_and_ours(tmp_path, monkeypatch):
    root = tmp_path / "cache"
    monkeypatch.setenv("BALANCER_ID_CACHE", str(root))
    assert private_folder(root / "kernels") is None
    assert stat.S_IMODE(root.stat().st_mode) == 0o700
    root.chmod(0o775)
    assert "writable by others" in private_folder(root / "kernels")
    root.chmod(0o700)
    elsewhere = tmp_path / "elsewhere"
    elsewhere.mkdir(mode=0o700)
    (root / "results").symlink_to(elsewhere)  # results redirected through a link
    assert "symbolic link" in private_folder(root / "results")
    from balancer_id import cache

    assert cache._results_dir(create=True) is None
    if POSIX_ROOT:
        other = tmp_path / "other"
        other.mkdir(mode=0o700)
        os.chown(other, 65534, 65534)
        monkeypatch.setenv("BALANCER_ID_CACHE", str(other))
        assert "another user" in private_folder(other / "kernels")


def test_helper_processes_never_import_from_the_working_folder(tmp_path):
    from balancer_id.batch.executors import _one_thread_env, run_in_processes
    from balancer_id.simulation.kernel_compile import helper_command

    marker = tmp_path / "ran"
    for name in ("json.py", "multiprocessing.py"):
        (tmp_path / name).write_text(f"open({str(marker)!r}, 'w').write('{name}')\n")
    subprocess.run(
        helper_command("import json, sys; print(json.dumps(sys.argv[1:]))", "x"),
        cwd=tmp_path, check=True, capture_output=True, timeout=60,
        env=dict(os.environ, PYTHONPATH=str(REPO)),
    )
    assert not marker.exists(), marker.read_text()
    import multiprocessing

    here = os.getcwd()
    os.chdir(tmp_path)
    try:
        got = {}
        with _one_thread_env():
            assert os.environ["PYTHONSAFEPATH"] == "1"
        run_in_processes(
            str, [(0, 12)], got.__setitem__, 1, context=multiprocessing.get_context("spawn")
        )
    finally:
        os.chdir(here)
    assert got == {0: "12"}
    assert not marker.exists(), marker.read_text()


# --- caches keyed on everything that changes the answer ---------------------------------


def test_a_kernel_depends_on_its_effect_modules_constants(tmp_path):
    from balancer_id.files import import_path
    from balancer_id.simulation.kernel import _effect_fingerprint

    source = (
        "from balancer_id.model import Effect, Param\n"
        "GAIN = {gain}\n"
        "class Pull(Effect):\n"
        "    name = 'pull_{tag}'\n"
        "    summary = 'a constant pull'\n"
        "    parameters = (Param('k_pull', 1.0, 0.0, 10.0, 'N', 'pull'),)\n"
        "    @staticmethod\n"
        "    def extra_force(z, v, f, h, k_pull):\n"
        "        return GAIN * k_pull\n"
    )
    prints = []
    for tag, gain in (("a", 1.0), ("b", 2.0)):
        path = tmp_path / f"pull_{tag}.py"
        path.write_text(source.format(gain=gain, tag=tag))
        module = import_path(f"bid_test_pull_{tag}", path)
        prints.append(_effect_fingerprint(module.Pull).replace(f"pull_{tag}", "pull"))
    assert prints[0] != prints[1]  # only GAIN differs, outside the class


def test_an_installed_plugin_changes_the_result_cache_key(tmp_path, monkeypatch):
    import importlib.metadata

    from balancer_id import cache

    plugin = tmp_path / "bid_plugin_x.py"
    plugin.write_text("LEVEL = 1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    point = importlib.metadata.EntryPoint("x", "bid_plugin_x:X", "balancer_id.effects")
    monkeypatch.setattr(importlib.metadata, "entry_points", lambda group=None: [point])
    assert cache._plugin_sources() == [plugin]
    cache._package_fingerprint.cache_clear()
    first = cache._package_fingerprint()
    plugin.write_text("LEVEL = 2\n")
    cache._package_fingerprint.cache_clear()
    try:
        assert cache._package_fingerprint() != first
    finally:
        cache._package_fingerprint.cache_clear()


# --- outputs ------------------------------------------------------------------------------


@pytest.mark.parametrize(("mask", "mode"), [(0o077, 0o600), (0o022, 0o644), (0o002, 0o664)])
def test_outputs_honour_the_umask(tmp_path, mask, mode):
    old = os.umask(mask)
    try:
        written = atomic_write_text(tmp_path / "out.json", "{}")
    finally:
        os.umask(old)
    assert stat.S_IMODE(written.stat().st_mode) == mode


def test_links_and_special_files_are_never_replaced(tmp_path):
    target = tmp_path / "target.json"
    target.write_text("keep")
    link = tmp_path / "link.json"
    link.symlink_to(target)
    loop = tmp_path / "loop.json"
    loop.symlink_to(tmp_path / "loop2.json")
    (tmp_path / "loop2.json").symlink_to(loop)
    for path in (link, loop):
        with pytest.raises(UsageError, match="symbolic link"):
            check_output(path, overwrite=True, option="--save")
        with pytest.raises(UsageError, match="symbolic link"):
            atomic_write_text(path, "new")
    with pytest.raises(UsageError, match="not a regular file"):
        check_output(os.devnull, overwrite=True, option="--save")
    assert target.read_text() == "keep" and link.is_symlink()


def test_one_path_for_two_outputs_is_refused(cli, tmp_path):
    same = tmp_path / "x.html"
    code, _, err = cli("fit", SAMPLE_LOGS / "paper_balancer.csv", "--report", same,
                       "--series", same)
    assert code == 2 and "same file" in err, err
    assert not same.exists()


# --- names ---------------------------------------------------------------------------------


def test_summary_cells_cannot_become_formulas_or_break_rows():
    from balancer_id.batch.rows import spreadsheet_cell

    assert spreadsheet_cell("=HYPERLINK(1)") == "'=HYPERLINK(1)"
    assert spreadsheet_cell("@sum") == "'@sum" and spreadsheet_cell("+1") == "'+1"
    assert spreadsheet_cell("a\rb\x1b[31m.csv") == "a\\rb\\x1b[31m.csv"
    assert spreadsheet_cell(-0.5) == -0.5 and spreadsheet_cell(None) == ""


def test_shown_names_cannot_drive_a_terminal_or_fail_to_encode():
    from balancer_id.text import shown

    raw = os.fsdecode(b"n\xff\x1b[2J.csv")
    assert shown(raw) == "n\\xff\\x1b[2J.csv"
    shown(raw).encode("utf-8")  # never a UnicodeEncodeError
    assert shown("plain name.csv") == "plain name.csv"


def test_any_file_name_can_be_drawn():
    from matplotlib.figure import Figure

    from balancer_id.text import make_figure_text_safe

    fig = Figure()
    ax = fig.add_subplot()
    ax.set_title(os.fsdecode(b"x$\\frac$ \xff.csv"))
    ax.set_xlabel("$m_a$ (kg)")  # a formula of ours stays a formula
    make_figure_text_safe(fig).savefig(io.BytesIO(), format="png")
    assert ax.get_title() == "x\\$\\frac\\$ \\xff.csv"
    assert ax.get_xlabel() == "$m_a$ (kg)"


def test_batch_names_results_safely_whatever_the_log_is_called(cli, tmp_path):
    logs = tmp_path / "logs"
    logs.mkdir()
    long_name = "L" * 248 + ".csv"  # 252 bytes: its result name would not fit
    for name in (long_name, "cr\rname.csv", "=cmd.csv"):
        (logs / name).write_bytes((SAMPLE_LOGS / "quantized_sensor.csv").read_bytes())
    code, _, err = cli("batch", logs, "--out", tmp_path / "out", "--jobs", "1")
    assert code == 0, err
    names = sorted(p.name for p in (tmp_path / "out").glob("*.json"))
    assert len(names) == 3 and all(len(os.fsencode(n)) < 200 for n in names), names
    assert "cr_name.json" in names
    rows = (tmp_path / "out" / "summary.csv").read_text().split("\n")
    assert len([r for r in rows if r]) == 4  # the header and one row per log, unbroken
    assert any(r.startswith("'logs/=cmd.csv") or "'=" in r or "/=cmd" in r for r in rows)


# --- failures: one line, the contract's exit code ------------------------------------------


def test_a_bad_trajectory_number_is_a_usage_error(cli):
    code, _, err = cli(
        "fit", SAMPLE_LOGS / "robot" / "robot_assist.csv", "--model",
        "variable_viscosity+servo", "--trajectory", "trapezoid:distance=nan,speed=0.1,accel=0.5",
    )
    assert code == 2 and "not a finite number" in err and "Traceback" not in err


def _command(*args: str, **kwargs) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONPATH=str(REPO), **kwargs.pop("env", {}))
    kwargs.setdefault("stdout", subprocess.PIPE)
    return subprocess.run(
        [sys.executable, "-m", "balancer_id", *args], env=env, stderr=subprocess.PIPE,
        timeout=120, **kwargs,
    )


def test_json_on_a_closed_or_full_stdout_is_one_line_exit_3():
    done = _command("effects", "--json", stdout=subprocess.DEVNULL)
    assert done.returncode == 0
    closed = subprocess.run(
        f"{sys.executable} -m balancer_id effects --json >&-", shell=True, capture_output=True,
        env=dict(os.environ, PYTHONPATH=str(REPO)), timeout=120,
    )
    assert closed.returncode == 3, closed.stderr
    assert closed.stderr.decode().strip().count("\n") == 0
    assert b"stdout is closed" in closed.stderr
    if Path("/dev/full").exists():
        with open("/dev/full", "w") as full:
            done = _command("effects", "--json", stdout=full)
        assert done.returncode == 3 and b"No space left" in done.stderr
        assert b"Traceback" not in done.stderr


def test_a_terminal_that_cannot_show_a_character_gets_it_escaped():
    done = _command("effects", env={"PYTHONIOENCODING": "ascii"})
    assert done.returncode == 0, done.stderr
    assert b"Traceback" not in done.stderr


def test_the_api_lists_itself():
    import balancer_id as bid

    listed = dir(bid)
    assert {"fit", "diagnose", "improve", "compare", "load_trials"} <= set(listed)
    assert not {"importlib", "os", "sys", "Any"} & set(listed)
    assert json.loads(json.dumps(listed)) == listed
