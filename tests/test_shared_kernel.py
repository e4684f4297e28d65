"""The kernels the built-in effects share: the same responses and sensitivities as each
model's own kernel, one file per set of structural effects, compiled once."""

from __future__ import annotations

import numpy as np
import pytest

from balancer_id.model import parse_model
from balancer_id.simulation import kernel as K
from balancer_id.simulation import kernel_cache as KCache
from balancer_id.simulation import kernel_compile as KC
from balancer_id.simulation.engine import PackedTrials, TrialInput, initial_sensitivities
from balancer_id.simulation.inputs import Thrust

#: Models that together use every hook of every built-in effect, each structural effect
#: in a kernel of its own (their event codes do not meet in a model's own kernel, which
#: keeps its compile short): the shared kernels, with these switched on and the others
#: off, must be the models' own kernels.
MODELS = (
    "variable_viscosity+karnopp+dead_time+bias",
    "viscous+speed_limit+asymmetric_lag+servo",
)


@pytest.fixture
def fresh_choice(monkeypatch):
    """No kernel memoized or chosen in this process; what the choice was, restored after."""
    monkeypatch.setattr(K, "_KERNELS", {})
    monkeypatch.setattr(KCache, "_CHOSEN", {})


def _trials() -> PackedTrials:
    t = np.arange(0.0, 2.5, 0.005)
    z_ref = 0.05 * np.sin(2.0 * np.pi * 0.7 * t)
    v_ref = np.gradient(z_ref, t)
    return PackedTrials.pack(
        [
            TrialInput(t, Thrust(np.array([0.3, 1.4]), np.array([42.0, -35.0])), z_ref, v_ref),
            TrialInput(t, Thrust.step(0.2, -28.0), z_ref, v_ref, x0=(3.0, 0.05, 0.01)),
        ]
    )


def _values(model) -> np.ndarray:
    """Start values, varied so that no two parameters share a value."""
    return np.array([p.value * (1.0 + 0.07 * k) for k, p in enumerate(model.params)])


def _responses(model, policy: str, monkeypatch):
    monkeypatch.setenv("BALANCER_ID_KERNELS", policy)
    K._KERNELS.clear()
    KCache._CHOSEN.clear()
    packed = _trials()
    p = _values(model)
    cols = np.arange(p.size + 3)
    s_in = initial_sensitivities(packed.offsets.size - 1, p.size, cols)
    out = packed.run(model, p)
    out_s, sens, s_out = packed._simulate_sens(model, p, cols, 4, s_in)
    assert (K.get_kernel(model).shared is not None) == (policy == "shared")
    return out, out_s, sens, s_out


@pytest.mark.parametrize("spec", MODELS)
def test_the_shared_kernel_gives_each_model_its_own_kernels_response(
    spec, fresh_choice, monkeypatch
):
    _assert_same_responses(parse_model(spec), monkeypatch)


def _assert_same_responses(model, monkeypatch):
    """The model's shared kernel gives its own kernel's responses and sensitivities."""
    own = _responses(model, "own", monkeypatch)
    shared = _responses(model, "shared", monkeypatch)
    out, out_s, sens, s_out = own
    # the same arithmetic in the same order, up to the sum of the forces (1e-13 m/s^2)
    assert np.abs(out).max() > 0.1 and np.abs(sens).max() > 1e-3
    np.testing.assert_allclose(shared[0], out, rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(shared[1], out_s, rtol=1e-9, atol=1e-9)
    # forward differences of the right-hand side inside the kernel: a step of 1.5e-8
    # relative, so sensitivities agree to about 1e-6 of their scale (a column that stays
    # near 0, such as the initial position's without a spring, on the largest one's)
    scale = np.maximum(np.abs(sens).max(axis=0), 1e-4 * np.abs(sens).max())
    assert np.max(np.abs(shared[2] - sens) / scale) < 1e-5
    np.testing.assert_allclose(shared[3], s_out, rtol=1e-5, atol=1e-6 * np.abs(s_out).max())


def test_a_model_outside_the_built_in_effects_gets_its_own_kernel(fresh_choice, monkeypatch):
    from balancer_id.model.effect import Effect, Param
    from balancer_id.model.spec import Model

    class Spring(Effect):
        """A spring to the rest position."""

        name = "test_spring_shared"
        parameters = (Param("k_s", 10.0, 0.0, 1e4, "N/m", "stiffness"),)

        @staticmethod
        def force(f: float, v: float, z: float, h: float, k_s: float) -> float:
            return -k_s * z

    viscous = parse_model("viscous")
    model = Model((*viscous.effects, Spring), viscous.registry)
    monkeypatch.setenv("BALANCER_ID_KERNELS", "shared")
    assert K.shared_places(model) is None
    assert K._shared_choice(model) is None
    assert K.shared_places(parse_model("viscous+bias")) is not None


def test_models_share_a_kernel_file_when_their_structural_effects_are_the_same(
    fresh_choice, monkeypatch
):
    monkeypatch.setenv("BALANCER_ID_KERNELS", "shared")

    def path(spec):
        return K._kernel_path(parse_model(spec))[0]

    plain = {path(s) for s in ("base", "viscous", "variable_viscosity+bias+dead_time")}
    friction = {path(s) for s in ("viscous+karnopp", "variable_viscosity+bias+karnopp")}
    assert len(plain) == 1 and len(friction) == 1 and plain != friction
    assert path("viscous+speed_limit") not in plain | friction
    monkeypatch.setenv("BALANCER_ID_KERNELS", "own")
    KCache._CHOSEN.clear()
    assert path("viscous") != path("variable_viscosity") != next(iter(plain))


def test_the_shared_kernel_is_named_once_when_several_models_need_it(
    fresh_choice, tmp_path, monkeypatch, capfd
):
    monkeypatch.setenv("BALANCER_ID_CACHE", str(tmp_path / "cache"))
    monkeypatch.setenv("BALANCER_ID_KERNELS", "shared")
    monkeypatch.setattr(KC, "_compile_shared", lambda models, sens: seen.extend(models))
    seen: list = []
    specs = ("viscous", "viscous+bias", "variable_viscosity", "viscous+karnopp")
    KC.compile_models([parse_model(s) for s in specs])
    err = capfd.readouterr().err
    assert len(seen) == 2
    assert err.count("compiling the simulation kernel") == 2
    assert "the built-in effects (shared by their models) (1/2; once)" in err
    assert "the built-in effects with karnopp (shared by their models) (2/2; once)" in err


HOSE = '''
from balancer_id.model.effect import Effect, Param


class Hose(Effect):
    """A hose pulling back towards the rest position."""

    name = "hose_shared_test"
    parameters = (Param("k_h", 8.0, 0.0, 1e4, "N/m", "stiffness of the hose"),)

    @staticmethod
    def force(f: float, v: float, z: float, h: float, k_h: float) -> float:
        return -k_h * z
'''


def test_a_user_effect_shares_a_kernel_with_the_switched_built_ins(
    fresh_choice, tmp_path, monkeypatch
):
    from balancer_id.model.registry import default_registry

    path = tmp_path / "hose.py"
    path.write_text(HOSE)
    registry = default_registry([path])
    monkeypatch.setenv("BALANCER_ID_KERNELS", "shared")

    def kernel_file(spec):
        return K._kernel_path(parse_model(spec, registry))[0]

    plain = kernel_file("variable_viscosity+hose_shared_test")
    assert kernel_file("viscous+hose_shared_test+bias+dead_time") == plain
    assert kernel_file("variable_viscosity+hose_shared_test+karnopp") != plain
    assert kernel_file("variable_viscosity") != plain
    _assert_same_responses(
        parse_model("variable_viscosity+hose_shared_test+bias", registry), monkeypatch
    )
