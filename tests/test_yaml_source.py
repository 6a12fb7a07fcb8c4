"""YAML syntax errors: one wording (file, line, column, what to check) for scenes, pipelines and values."""

from __future__ import annotations

import pytest

from guaca_py.errors import ConfigError
from guaca_py.scene.loader import load_scene_text
from guaca_py.yaml_source import load_yaml_text, yaml_value


@pytest.mark.parametrize(
    "text, line, column, fragment",
    [
        ("background: [0.1, 0.1, 0.1\nnodes: []\n", 2, 6, "flow sequence (started on line 1)"),
        ("nodes:\n  - name: a\n    transform: translation: [1, 2]\n", 3, 27, "mapping values are not allowed"),
        ("nodes:\n  - name: a\0b\n", 2, 12, "character #x0000 is not allowed"),
    ],
    ids=["unclosed", "colon", "control-character"],
)
def test_scene_and_yaml_files_word_a_syntax_error_alike(text, line, column, fragment):
    said = []
    for read in (load_scene_text, load_yaml_text, yaml_value):
        with pytest.raises(ConfigError) as err:
            read(text, "f.yaml")
        e = err.value
        assert (e.file, e.line) == ("f.yaml", line), read
        assert e.reason.startswith(f"invalid YAML at column {column}: ") and fragment in e.reason, e.reason
        assert e.hint and "\n" not in str(e)
        said.append(str(e))
    assert said[0] == said[1] == said[2]
    assert said[0].startswith(f"f.yaml:{line}: invalid YAML")
