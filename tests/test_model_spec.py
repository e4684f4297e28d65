"""Model specs: parsing, refusals with reasons, composition, lmfit parameters."""

from __future__ import annotations

import pytest

from balancer_id.errors import ModelSpecError
from balancer_id.model import Effect, Param, Registry, parse_model
from balancer_id.model.effects import BUILTIN_EFFECTS


def test_default_is_the_papers_model():
    model = parse_model()
    assert model.spec == "variable_viscosity"
    assert model.param_names == ("m_a", "T_a", "D0", "A")


def test_every_effect_of_model_md_is_built_in():
    expected = {
        "viscous",
        "variable_viscosity",
        "karnopp",
        "speed_limit",
        "dead_time",
        "bias",
        "asymmetric_lag",
        "servo",
    }
    assert set(BUILTIN_EFFECTS) == expected


def test_unknown_effect_lists_the_known_ones():
    with pytest.raises(ModelSpecError) as err:
        parse_model("variable_viscosity+frobnicate")
    msg = str(err.value)
    assert "unknown effect 'frobnicate'" in msg
    assert "karnopp" in msg and "speed_limit" in msg


def test_exclusive_effects_are_refused_with_the_reason():
    with pytest.raises(ModelSpecError, match="exclude each other"):
        parse_model("viscous+variable_viscosity")


def test_repeated_effect_is_refused():
    with pytest.raises(ModelSpecError, match="given twice"):
        parse_model("karnopp+karnopp")


def test_asymmetric_lag_replaces_T_a():
    model = parse_model("variable_viscosity+asymmetric_lag")
    assert "T_a" not in model.param_names
    assert {"T_up", "T_down"} <= set(model.param_names)


def test_composition_with_plus():
    model = parse_model("variable_viscosity") + "karnopp"
    assert model.spec == "variable_viscosity+karnopp"
    assert model.param_names[-1] == "f_s"


def test_clashing_parameter_names_are_refused():
    class Clash(Effect):
        name = "clash"
        summary = "test"
        parameters = (Param("m_a", 1.0, 0.0, 2.0, "kg", "clashes with the base"),)

        @staticmethod
        def force(f, v, z, h, m_a):
            return 0.0

    registry = Registry()
    registry.add(Clash)
    with pytest.raises(ModelSpecError, match="clashes"):
        parse_model("clash", registry)


def test_bad_settings_are_refused():
    model = parse_model("variable_viscosity+karnopp")
    with pytest.raises(ModelSpecError, match="outside its range"):
        model.resolve({"f_s": -1.0})
    with pytest.raises(ModelSpecError, match="no parameter 'k_r'"):
        model.resolve({"k_r": 1.0})


def test_lmfit_parameters_carry_bounds_and_fixed():
    params = parse_model("variable_viscosity").lmfit_parameters({"m_a": 12.0}, fixed=("A",))
    assert params["m_a"].value == 12.0
    assert params["D0"].min == 0.0
    assert params["A"].vary is False


def test_malformed_user_effect_is_refused():
    class NoHook(Effect):
        name = "nohook"
        summary = "x"

    with pytest.raises(ModelSpecError, match="implement at least one hook"):
        Registry().add(NoHook)


@pytest.mark.parametrize(
    ("body", "words"),
    [
        ("    @staticmethod\n    def force(f, v, z, k_h):\n        return -k_h * z\n",
         "force(f, v, z, k_h) takes 4 argument(s)"),
        ("    def force(self, f, v, z, h, k_h):\n        return -k_h * z\n",
         "must be a staticmethod"),
        ("    @staticmethod\n    def friction(v, k_h):\n        return 0.0\n",
         "friction(v, F, k_h)"),
    ],
)
def test_a_hook_with_a_wrong_signature_is_refused_by_name(tmp_path, body, words):
    from balancer_id.model.registry import default_registry

    path = tmp_path / "bad_effect.py"
    path.write_text(
        "from balancer_id import Effect, Param\n\n\nclass Bad(Effect):\n"
        '    name = "bad_hose"\n    summary = "x"\n'
        '    parameters = (Param("k_h", 2.0, 0.0, 200.0, "N/m", "stiffness"),)\n\n' + body
    )
    with pytest.raises(ModelSpecError, match="bad_hose") as info:
        default_registry([path])
    assert words in str(info.value)


def test_an_effects_file_python_cannot_import_is_refused_by_its_spec(tmp_path):
    # decided on importlib's spec, not on an ImportError's wording (issue 20)
    from balancer_id.errors import EffectError
    from balancer_id.model.registry import default_registry

    bad = tmp_path / "effects.txt"
    bad.write_text("x = 1\n")
    with pytest.raises(EffectError, match="cannot be imported as a Python module"):
        default_registry([bad])
