"""Every real export in ``../shared/real_logs`` is read as its manifest says, or refused clearly.

The expected readings are in ``tests/golden/real_logs_public.json`` (taken from
``public/MANIFEST.tsv``'s ``correct_reading`` column, judged by opening each file). A
file is judged the way a new user meets it: read as it is; when the tool refuses and asks
for ``--columns``, read again with the column map the expectation gives. The outcome is
one of

* ``right``: read, and every stated fact holds (runs, rate, samples, axes, gravity, rest
  magnitude, notes, the onsets of the acceleration: none in steady travel);
* ``clear``: refused in one line holding the words the expectation names (the real cause
  and its fix);
* ``unhelpful``: refused where a reading was expected, or refused without naming the cause;
* ``misread``: read where a refusal was expected, or read with a stated fact wrong.

``benchmarks/bench_real_logs.py`` prints the counts. Skipped where the shared folder is
absent (CI clones the repository without it).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from balancer_id.constants import G_DEFAULT
from balancer_id.errors import BalancerIdError
from balancer_id.notes import has_code

#: ``../shared/real_logs`` next to the checkout (as tests/test_read_real_logs.py finds it), or
#: one folder up for a worktree in ``wt/NAME``.
REAL_LOGS = next(
    (
        p / "shared" / "real_logs"
        for p in Path(__file__).resolve().parents[2:4]
        if (p / "shared" / "real_logs").is_dir()
    ),
    Path(__file__).resolve().parents[2] / "shared" / "real_logs",
)
EXPECTED = Path(__file__).resolve().parent / "golden" / "real_logs_public.json"
OUTCOMES = ("right", "clear", "unhelpful", "misread")


def expectations() -> dict[str, dict[str, Any]]:
    """The expected reading of each file, by its path under ``real_logs``."""
    return json.loads(EXPECTED.read_text(encoding="utf-8"))["files"]


def _facts(log: Any, exp: dict[str, Any]) -> list[str]:
    """What in ``log`` contradicts ``exp`` (empty when the reading is right)."""
    wrong: list[str] = []
    recs = log.recordings
    if "runs" in exp and len(recs) != exp["runs"]:
        wrong.append(f"{len(recs)} runs, expected {exp['runs']}")
    if not recs:
        return wrong or ["no recording"]
    main = max(recs, key=lambda r: r.n_samples)
    tol = exp.get("rate_tol", 0.01)
    if "rate_hz" in exp and not np.isclose(main.sample_rate_hz, exp["rate_hz"], rtol=tol):
        wrong.append(f"rate {main.sample_rate_hz:.4g} Hz, expected {exp['rate_hz']}")
    if "rates_hz" in exp:
        rates = [r.sample_rate_hz for r in recs]
        if len(rates) != len(exp["rates_hz"]) or not np.allclose(rates, exp["rates_hz"], rtol=tol):
            wrong.append(f"rates {rates}, expected {exp['rates_hz']}")
    if "n" in exp and main.n_samples != exp["n"]:
        wrong.append(f"{main.n_samples} samples, expected {exp['n']}")
    if "duration_s" in exp:
        span = float(main.time[-1] - main.time[0])
        if not np.isclose(span, exp["duration_s"], rtol=0.02):
            wrong.append(f"{span:.4g} s long, expected {exp['duration_s']}")
    if exp.get("force") and main.force is None:
        wrong.append("no force")
    axes = 0 if main.accel is None else main.accel.shape[1]
    if "axes" in exp and axes != exp["axes"]:
        wrong.append(f"{axes} acceleration axes, expected {exp['axes']}")
    if axes and "gravity" in exp and main.accel_includes_gravity != exp["gravity"]:
        wrong.append(f"includes gravity {main.accel_includes_gravity}, expected {exp['gravity']}")
    if axes and "rest_g" in exp:
        level = float(np.median(np.linalg.norm(main.accel, axis=1))) / G_DEFAULT
        low, high = exp["rest_g"]
        if not low <= level <= high:
            wrong.append(f"rest magnitude {level:.3g} g, expected {low}-{high} g")
    if "gaps" in exp and len(main.gaps) != exp["gaps"]:
        wrong.append(f"{len(main.gaps)} gaps, expected {exp['gaps']}")
    if "onsets" in exp:
        try:
            from balancer_id.segment.find import find_onsets
        except ImportError:  # an older checkout (bench --code): no onset check
            find_onsets = None
        if find_onsets is not None:
            found = find_onsets(log).get(main.name, [])
            want = exp["onsets"]
            if len(found) != len(want) or not np.allclose(found, want, atol=0.5):
                wrong.append(f"onsets {np.round(found, 2).tolist()}, expected {want}")
    for code in exp.get("notes", []):
        if not has_code(getattr(log, "notes", log.warnings), code):  # older Log: no notes
            wrong.append(f"no note {code}")
    return wrong


def judge(path: Path, exp: dict[str, Any]) -> tuple[str, str]:
    """Read ``path`` as a user would and judge the outcome against ``exp``.

    Parameters
    ----------
    path : pathlib.Path
        The file.
    exp : dict
        Its expectation (see the module docstring).

    Returns
    -------
    outcome : str
        One of :data:`OUTCOMES`.
    detail : str
        What was read or the refusal, and what is wrong.
    """
    from balancer_id.read import read_log

    try:
        try:
            log = read_log(path)
        except BalancerIdError as exc:
            if "columns" not in exp or "--columns" not in str(exc):
                raise
            log = read_log(path, columns=exp["columns"])
            if exp.get("native"):
                return "unhelpful", f"read only with --columns: {exc}"
    except BalancerIdError as exc:
        message = str(exc)
        said = message.replace(str(path), "<file>").lower()  # the file name is no cause
        if exp["expect"] == "refuse":
            missing = [w for w in exp["mention"] if w.lower() not in said]
            if missing:
                return "unhelpful", f"refusal lacks {missing}: {message}"
            return "clear", message
        accepted = exp.get("accept_refusal")
        if accepted and all(w.lower() in said for w in accepted):
            return "clear", message
        return "unhelpful", message
    if exp["expect"] == "refuse":
        return "misread", f"read ({log.format}, {len(log.recordings)} runs), expected a refusal"
    wrong = _facts(log, exp)
    if wrong:
        return "misread", "; ".join(wrong)
    return "right", f"{log.format}, {len(log.recordings)} run(s)"


pytestmark = pytest.mark.skipif(not REAL_LOGS.is_dir(), reason="real_logs folder not present")


@pytest.mark.parametrize("name", sorted(expectations()))
def test_real_log_reads_as_its_manifest_says(name: str) -> None:
    path = REAL_LOGS / name
    if not path.is_file():
        pytest.skip(f"{name} not present")
    exp = expectations()[name]
    outcome, detail = judge(path, exp)
    wanted = "clear" if exp["expect"] == "refuse" else "right"
    if exp.get("accept_refusal") and outcome == "clear":
        wanted = "clear"
    assert outcome == wanted, detail


def test_every_manifest_file_has_an_expectation() -> None:
    """The golden table covers the manifest: a new file there needs its expected reading."""
    manifest = REAL_LOGS / "public" / "MANIFEST.tsv"
    if not manifest.is_file():
        pytest.skip("no manifest")
    lines = manifest.read_text(encoding="utf-8").splitlines()[1:]
    listed = {"public/" + line.split("\t")[0] for line in lines if line.strip()}
    assert listed <= set(expectations())


#: The column map that reads the known-mass rig with its stated calibration
#: (known_mass/MANIFEST.tsv: force_N = (counts * 0.000321464 + 30.6694) / 1000 * 9.81,
#: acc = counts * 2 * 0.061e-3 g).
KNOWN_MASS_COLUMNS = {
    "time": "Time",
    "force": "Force:3.15356e-6N+0.300862",
    "ax": "accX:1.22e-4g",
    "ay": "accY:1.22e-4g",
    "az": "accZ:1.22e-4g",
}


def test_known_mass_rig_reads_with_its_calibration() -> None:
    from balancer_id.read import read_log

    path = REAL_LOGS / "known_mass" / "kierancoz__LoadCellIMU_500g_static.csv"
    if not path.is_file():
        pytest.skip("known_mass log not present")
    (rec,) = read_log(path, columns=KNOWN_MASS_COLUMNS, g=9.81).recordings
    assert rec.n_samples == 1000 and rec.sample_rate_hz == pytest.approx(100.0, rel=1e-3)
    assert rec.force is not None and rec.accel is not None and rec.accel_includes_gravity
    # hanging at rest before the first pull: the cell holds the weight (~0.52-0.55 kg)
    rest = rec.time < 0.8
    assert np.median(rec.force[rest]) / 9.81 == pytest.approx(0.545, abs=0.02)
    # +z points down: the accelerometer reads -g on z at rest (1.1 % low, as stated)
    assert np.median(rec.accel[rest, 2]) == pytest.approx(-9.70, abs=0.05)
