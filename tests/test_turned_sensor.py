"""A sensor turned during the recording, and an up axis that is a guess (issue 19.3).

A phone rests flat (gravity on +z), is turned onto its side (+y), a step trial follows,
it is turned onto its edge (+x), another trial follows. The reader warns
(``read.turned_sensor``, naming the orientations); each trial's vertical is that of its
part; the turns themselves (the acceleration swinging through 90 degrees) are no onsets.
Seeded, at two rates and tilts. An up axis guessed (a linear acceleration's principal
direction, a one-axis motion sensor) is said to be a guess in ``inspect`` with or without
trials; a log's real PHIRElab recording, turned five times, is warned too.
"""

from __future__ import annotations

import json

import numpy as np
import pytest
from scipy.spatial.transform import Rotation, Slerp
from simlib.sessions import write_recordings
from test_real_logs_public import REAL_LOGS
from test_segment_synth import make_log, synth_run

from balancer_id.constants import G_DEFAULT
from balancer_id.notes import has_code
from balancer_id.read import read_log
from balancer_id.read.recording import Recording
from balancer_id.segment import find_trials
from balancer_id.trials import describe_log

#: (time the turn starts, sensor orientation after it): flat, on its side, on its edge.
TURNS = [(8.0, Rotation.from_euler("x", 90, degrees=True)),
         (24.0, Rotation.from_euler("y", -90, degrees=True))]  # fmt: skip
ONSETS = (14.0, 30.0)
THRUST_ACCEL = (0.35, -0.3)


def turned_phone(seed: int, rate: float) -> Recording:
    """The with-g recording of a phone turned twice, with a step trial after each turn."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, 38.0, 1.0 / rate)
    a_up = np.zeros(t.size)
    for t0, amp in zip(ONSETS, THRUST_ACCEL, strict=True):
        tau = t - t0
        move = (tau >= 0) & (tau < 3.0)
        a_up[move] += amp * (1 - np.exp(-tau[move] / 0.3))
        catch = (tau >= 3.0) & (tau < 3.4)
        v = amp * (3.0 - 0.3 * (1 - np.exp(-10.0)))
        a_up[catch] -= v * np.pi / 0.8 * np.sin(np.pi * (tau[catch] - 3.0) / 0.4)
    tilt = Rotation.from_rotvec(rng.normal(0, np.radians(4), 3))
    keys = [0.0]
    rots = [tilt]
    for t_turn, rot in TURNS:  # each turn takes 1.2 s
        keys += [t_turn, t_turn + 1.2]
        rots += [rots[-1], rot * tilt]
    keys.append(t[-1] + 1)
    rots.append(rots[-1])
    orient = Slerp(keys, Rotation.concatenate(rots))(t)
    world = np.column_stack([np.zeros(t.size), np.zeros(t.size), a_up + G_DEFAULT])
    accel = orient.inv().apply(world) + rng.normal(0, 0.03, (t.size, 3))
    return Recording(
        name="Run 1",
        time=t,
        accel=accel,
        accel_includes_gravity=True,
        sample_rate_hz=rate,
    )


@pytest.mark.parametrize(("seed", "rate"), [(1, 100.0), (2, 200.0), (3, 100.0)])
def test_a_turned_sensor_is_warned_and_each_part_has_its_vertical(tmp_path, seed, rate):
    path = tmp_path / "turned.csv"
    write_recordings(path, [turned_phone(seed, rate)])
    log = read_log(path)
    (note,) = [n for n in log.notes if n.code == "read.turned_sensor"]
    assert "+z" in note.text and "+y" in note.text and "+x" in note.text
    trials = find_trials(log, thrusts=[3.5, 3.0])  # the turns are no onsets
    assert [round(tr.t_step) for tr in trials] == [14, 30]
    assert [tr.direction for tr in trials] == ["up", "down"]
    assert trials[0].vertical.startswith("+y") and trials[1].vertical.startswith("+x")
    # the vertical acceleration of each trial is its own, not a projection on another axis
    for tr, amp in zip(trials, THRUST_ACCEL, strict=True):
        steady = (tr.time > tr.t_step + 1.5) & (tr.time < tr.t_step + 2.8)
        assert np.median(tr.accel[steady]) == pytest.approx(amp, abs=0.05)


def test_an_unturned_sensor_is_not_warned(tmp_path):
    rec, _ = synth_run(5, [[4.9], [-3.0]], tilt_deg=25.0, has_force=False)
    path = tmp_path / "still.csv"
    write_recordings(path, [rec])
    assert not has_code(read_log(path).notes, "read.turned_sensor")


def test_a_guessed_up_axis_is_called_a_guess_with_or_without_trials():
    # linear acceleration, automatic axis: the axis is the motion's principal direction
    rec, _ = synth_run(46, [[4.9], [-3.0]], with_g=False, tilt_deg=0.0, has_force=False)
    log = make_log(rec)
    with pytest.raises(Exception, match="no step trial found"):
        find_trials(log)  # without thrusts: no trial, the vertical is still reported
    (run,) = describe_log(log, [])["runs"]
    assert run["vertical"].startswith("+z")
    assert run["vertical_axis_known"] is False and run["vertical_sign_known"] is False
    assert has_code(log.notes, "read.vertical_guess", "Run 1")
    # a one-axis sensor without gravity: the axis is assumed, and so is its sign
    one = Recording("Run 1", rec.time, None, rec.accel[:, 2:], False, ("z",), rec.sample_rate_hz)
    log1 = make_log(one)
    with pytest.raises(Exception, match="no step trial found"):
        find_trials(log1)
    (run1,) = describe_log(log1, [])["runs"]
    assert run1["vertical_axis_known"] is False and run1["vertical_sign_known"] is False
    # with gravity the axis is known
    withg, _ = synth_run(47, [[4.9]], has_force=False)
    log2 = make_log(withg)
    find_trials(log2, thrusts=[4.9])
    (run2,) = describe_log(log2, [])["runs"]
    assert run2["vertical_axis_known"] is True and run2["vertical_sign_known"] is True


def test_inspect_names_the_up_axis_without_trials(cli, tmp_path):
    rec, _ = synth_run(48, [[4.9]], with_g=False, tilt_deg=0.0, has_force=False)
    path = tmp_path / "linear.csv"
    write_recordings(path, [rec])
    code, out, _ = cli("inspect", path, "--json")
    assert code == 4  # no thrusts: no trial, but what was read is shown
    (run,) = json.loads(out)["runs"]
    assert run["vertical_axis_known"] is False and "vertical" in run
    code, out, _ = cli("inspect", path)
    assert "the axis is a guess" in " ".join(out.split())


def test_the_real_turned_phone_is_warned():
    path = REAL_LOGS / "public" / "phyphox_withg_long6min_PHIRElab_ExampleAccML.csv"
    if not path.is_file():
        pytest.skip("real_logs folder not present")
    (note,) = [n for n in read_log(path).notes if n.code == "read.turned_sensor"]
    assert all(axis in note.text for axis in ("+z", "-x", "-y"))
