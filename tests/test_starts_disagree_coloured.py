"""Two optima told apart by a coloured residual count its independent samples only
(issue 31: wrong basins trusted).

A coloured 50 Hz log (a phone's filtered accelerometer) ended in the mirror basin (lag
and viscous time swapped: m_a 3.8 kg against 9.5, T_a 0.68 s against 0.28), trusted,
because its truth-like rival's cost was 10.7 noise variances behind, past the 10 that
"about as good" allows; on a residual correlated over 8.7 samples that is 1.2 variances
of independent evidence (``bench_universe`` world 271828019). The rival is now weighed
as the standard errors are, by the residual's correlation time.
"""

from __future__ import annotations

from types import SimpleNamespace

import numpy as np

from balancer_id.identify.matching import _Outcome, _starts_disagree


def _result(tau: float, n: int) -> SimpleNamespace:
    params = {"m_a": SimpleNamespace(stderr=0.28), "T_a": SimpleNamespace(stderr=0.026)}
    return SimpleNamespace(y=np.zeros(n), metrics={"residual_tau": tau}, parameters=params)


def _end(x: list[float], chisqr: float, n: int) -> _Outcome:
    r = np.full(n, np.sqrt(chisqr / n))
    return _Outcome(np.array(x), r, np.eye(2), True, "converged", 10)


def test_a_rival_behind_by_less_than_its_correlated_evidence_disagrees():
    n = 1200
    best = _end([3.78, 0.683], 1.0, n)
    s2 = 1.0 / (n - 2)
    rival = _end([9.49, 0.272], 1.0 + 10.7 * s2, n)
    note = _starts_disagree(_result(8.7, n), best, [best, rival], ["m_a", "T_a"])
    assert note is not None and note.code == "fit.starts_disagree" and note.severity == "error"
    # on a white residual the same costs do tell them apart
    assert _starts_disagree(_result(1.0, n), best, [best, rival], ["m_a", "T_a"]) is None
