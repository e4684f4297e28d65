"""A robot servo of no stiffness (k_r = 0: not resolved, a bound) is no instability and
prints no internal error (issue 31 case run: 'internal error TypeError' on a late robot
whose servo the fit could not resolve)."""

from __future__ import annotations

import json

from balancer_id.identify.advice import advice_lines, advise
from balancer_id.identify.coupling import coupling

PAPER = {"m_a": 15.17, "T_a": 0.33, "D0": 6.0, "A": 0.41}


def test_no_servo_stiffness_leaves_the_load_where_it_is_not_unstable():
    free = coupling(15.17, 0.33, 6.0, 0.0, 25.0)
    assert free.stable and free.verdict == "well damped"
    assert coupling(15.17, 0.33, 6.0, 150.0, -60.0).stable is False  # a real instability


def test_advice_for_no_servo_stiffness_prints_its_margin_in_words():
    advice = advise({**PAPER, "k_r": 0.0, "c_r": 25.0}).to_dict()
    lines = advice_lines(json.loads(json.dumps(advice, default=str).replace("Infinity", "null")))
    assert "stability margin unbounded (no servo stiffness)" in lines[0]
