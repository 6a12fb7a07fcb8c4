"""frozen.py: the value keys every memo of derived values uses."""

from dataclasses import dataclass

import numpy as np

from guaca_py.frozen import field_key, freeze


def test_equal_values_give_equal_hashable_keys_whatever_their_container():
    a = {"color": [1.0, 0.5, 0.25], "m": np.eye(2), "name": "x", "n": None, "flags": (True, 2)}
    b = {"n": None, "name": "x", "m": [[1.0, 0.0], [0.0, 1.0]], "color": (1.0, 0.5, 0.25), "flags": [True, 2]}
    assert freeze(a) == freeze(b) and hash(freeze(a)) == hash(freeze(b))
    assert freeze(np.float32(0.5)) == 0.5 and type(freeze(np.float32(0.5))) is float


def test_a_value_edited_in_place_gives_another_key():
    color = [1.0, 0.5, 0.25]
    before = freeze({"color": color})
    color[1] = 0.75
    assert freeze({"color": color}) != before


def test_field_keys_tell_types_apart():
    @dataclass
    class Light:
        intensity: object
        color: object

    assert field_key(Light(1.0, [1, 1, 1])) == field_key(Light(1.0, [1, 1, 1]))  # other lists, equal values
    assert field_key(Light(True, [1, 1, 1])) != field_key(Light(1.0, [1, 1, 1]))  # True == 1.0, but not its type
