"""One range check and one YAML number hint for settings, material uniforms, scene values and options."""

import math

from guaca_py.numeric import NON_NEGATIVE, POSITIVE, Range, number_hint, yaml_number_hint
from guaca_py.pipeline.settings import NUMBER, Setting, positive, unit_interval


def test_range_bounds_and_their_text():
    unit = Range(0, 1, lo_open=True)
    assert not unit.contains(0) and unit.contains(1e-9) and unit.contains(1) and not unit.contains(1.0001)
    assert str(unit) == "(0, 1]" and unit.requirement() == "in (0, 1]"
    assert str(NON_NEGATIVE) == "[0, inf]" and NON_NEGATIVE.requirement() == ">= 0" and NON_NEGATIVE.contains(0)
    assert POSITIVE.requirement() == "> 0" and not POSITIVE.contains(0)
    assert Range(hi=2.5, hi_open=True).requirement() == "< 2.5" and not Range(hi=2.5, hi_open=True).contains(2.5)
    assert str(Range()) == "[-inf, inf]" and Range().contains(-1e300)
    assert not any(r.contains(math.nan) for r in (POSITIVE, NON_NEGATIVE, unit))  # NaN is within no bound


def test_settings_checks_speak_through_the_range():
    assert positive(3) is None and positive(0) == "must be > 0, got 0"
    assert unit_interval(5) == "must be in (0, 1], got 5"
    assert Range(1).problem(-5) == "must be >= 1, got -5"  # --width, --frames ...


def test_yaml_number_hint_only_for_finite_number_text():
    assert (
        yaml_number_hint("1e9") == "YAML reads '1e9' as text: write it with a dot and a signed exponent, e.g. 1.0e+09"
    )
    assert yaml_number_hint("5e-1").endswith("e.g. 5.0e-01")
    for not_a_mistake in ("auto", "nan", "inf", "1e999", 1e9, None):
        assert yaml_number_hint(not_a_mistake) is None, not_a_mistake
    assert number_hint("abc") == "write a plain number like 1.5"


def test_setting_refuses_number_text_even_where_text_is_accepted():
    budget = Setting((str, int, float), "auto", check=lambda v: None if v == "auto" or v > 0 else "bad")
    assert budget.validate("auto") is None
    assert "YAML reads '1e3' as text" in budget.validate("1e3")
    assert Setting(NUMBER, 1.0).validate("2e1").startswith("expected int/float, got '2e1' (YAML reads")
    assert Setting((str,), "x").validate("1e3") is None  # a text setting keeps text that looks like a number
    assert Setting(NUMBER, 1.0).validate(True) == "expected int/float, got True"


def test_gpu_numbers_finite_and_within_32_bits():
    from guaca_py.numeric import gpu_number_problem

    assert gpu_number_problem(2**31 - 1, integer=True) is None and gpu_number_problem(-(2**31), integer=True) is None
    assert "beyond the 32-bit integer range" in gpu_number_problem(2**31, integer=True)
    assert gpu_number_problem(10**5000, integer=True).startswith("1e4999 (an integer) is beyond")  # no str() of it
    assert gpu_number_problem(math.inf, integer=True) == "must be a finite integer, got inf"
    assert gpu_number_problem(3.4e38) is None and "beyond the 32-bit float range" in gpu_number_problem(3.5e38)
    assert gpu_number_problem(math.nan) == "must be a finite number, got nan"
    assert "beyond the 32-bit float range" in gpu_number_problem(-(10**400))  # float() of it overflows


def test_settings_take_numpy_numbers_and_refuse_what_the_gpu_cannot_hold():
    import numpy as np

    from guaca_py.pipeline.settings import resolve_settings

    schema = {"n": Setting((int,), 1, check=positive), "x": Setting(NUMBER, 1.0)}
    out = resolve_settings(schema, {"n": np.int64(4), "x": np.float32(0.5)}, lambda k, r, h: ValueError(k, r))
    assert out == {"n": 4, "x": 0.5} and type(out["n"]) is int
    assert Setting((int,), 1).validate(10**11).endswith("beyond the 32-bit integer range [-2147483648, 2147483647]")
    assert Setting(NUMBER, 1.0).validate(math.inf) == "must be a finite number, got inf"
    assert Setting(NUMBER, 1.0).validate(10**11) is None  # a number setting may be a large int


def test_quoted_numbers_are_told_to_lose_their_quotes():
    assert yaml_number_hint("2.2") == "'2.2' is quoted, so it is text: write it without quotes"
    assert yaml_number_hint("-12") == "'-12' is quoted, so it is text: write it without quotes"
    assert yaml_number_hint("0808") == "write a plain number like 808"  # not octal, not a YAML number either
    assert yaml_number_hint("1.5E3").startswith("YAML reads '1.5E3' as text")  # no signed exponent
