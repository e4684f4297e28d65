"""The shared parameters' covariance widened to the groups' sandwich (``fit --track``'s band):
groups that disagree beyond the noise widen it, groups that agree leave it alone."""

from __future__ import annotations

import numpy as np

from balancer_id.identify.grouped import _covariances, _robust_shared


def _groups(rng, n_groups: int, spread: float, sigma: float = 1.0, n: int = 200):
    """Linear groups y = s + o_g + x_g t + noise: one shared slope-free level ``s`` and a
    per-group slope; ``spread`` adds a per-group level shift the model does not have."""
    parts = []
    for _ in range(n_groups):
        t = np.linspace(-1, 1, n)
        a = np.ones((n, 1))  # shared: the level
        b = t[:, None]  # own: the group's slope
        shift = rng.normal(0, spread)
        r = shift + rng.normal(0, sigma, n)  # residual at the fitted values (level 0)
        r = r - b @ np.linalg.lstsq(b, r, rcond=None)[0]  # each group's own fitted
        parts.append((np.hstack([a, b]), r))
    mean = np.mean(np.concatenate([r for _, r in parts]))  # the shared level fitted
    return [(j, r - mean) for j, r in parts]


def test_groups_that_agree_keep_the_model_covariance():
    rng = np.random.default_rng(1)
    parts = _groups(rng, 40, spread=0.0)
    model_s, _ = _covariances(parts, 1, 1)
    robust_s, _ = _covariances(parts, 1, 1, robust_sigma2=1.0)
    assert robust_s[0, 0] >= model_s[0, 0]  # never narrower
    assert robust_s[0, 0] < 1.6 * model_s[0, 0]  # the sandwich is noisy over 40 groups


def test_groups_that_disagree_widen_the_shared_and_common_parts():
    # each group's level off by 0.5 (the noise is 1 over 200 samples: 0.07 a group): the
    # shared level's error is the groups' scatter over sqrt(40), not the noise's
    rng = np.random.default_rng(2)
    parts = _groups(rng, 40, spread=0.5)
    model_s, model_o = _covariances(parts, 1, 1)
    robust_s, robust_o = _covariances(parts, 1, 1, robust_sigma2=1.0)
    expected = 0.5**2 / 40 + 1.0 / (40 * 200)
    assert robust_s[0, 0] == np.clip(robust_s[0, 0], 0.5 * expected, 2.0 * expected)
    assert robust_s[0, 0] > 10 * model_s[0, 0]
    # a group's own part given the shared ones stays; its common part follows the shared
    for (cond_m, _), (cond_r, common_r) in zip(model_o, robust_o, strict=True):
        assert np.allclose(cond_m, cond_r)
        assert common_r.shape == (1, 1)


def test_robust_shared_is_the_larger_in_every_direction():
    cov = np.array([[2.0, 0.5], [0.5, 1.0]])
    rng = np.random.default_rng(3)
    scores = rng.normal(size=(30, 2)) * [3.0, 0.1]  # much more than the model in one axis
    out = _robust_shared(cov, scores, 1.0)
    assert np.all(np.linalg.eigvalsh(out - cov) >= -1e-12)  # never narrower
    few = _robust_shared(cov, scores[:3], 1.0)  # 3 groups for 2 parameters: kept
    assert np.array_equal(few, cov)
