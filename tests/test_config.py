"""Config loading: YAML, overrides, strict keys, strict booleans."""

from dataclasses import dataclass, field

import pytest

from emogesture.config import load_config, parse_bool, to_dict
from emogesture.errors import ConfigError, InputFileError


@dataclass
class Inner:
    width: int = 4
    rate: float = 0.5
    flag: bool = True


@dataclass
class Outer:
    name: str = "tiny"
    joints: tuple[int, ...] = (1, 2)
    inner: Inner = field(default_factory=Inner)
    path: str | None = None


def test_defaults_yaml_and_overrides(tmp_path):
    p = tmp_path / "c.yaml"
    p.write_text("name: paper\ninner:\n  width: 8\n")
    cfg = load_config(Outer, p, ["inner.rate=0.25", "inner.flag=False", "joints=[3,4,5]"])
    assert cfg == Outer(name="paper", joints=(3, 4, 5), inner=Inner(width=8, rate=0.25, flag=False))
    assert to_dict(cfg)["joints"] == [3, 4, 5]


@pytest.mark.parametrize("text,value", [("False", False), ("false", False), ("0", False), ("no", False),
                                        ("True", True), ("1", True), ("yes", True)])
def test_booleans_are_parsed_not_truthy(text, value):
    assert parse_bool(text) is value
    assert load_config(Outer, None, [f"inner.flag={text}"]).inner.flag is value


def test_errors():
    with pytest.raises(ConfigError, match="unknown key"):
        load_config(Outer, None, ["inner.depth=3"])
    with pytest.raises(ConfigError, match="not a boolean"):
        load_config(Outer, None, ["inner.flag=maybe"])
    with pytest.raises(ConfigError, match="not a valid int"):
        load_config(Outer, None, ["inner.width=wide"])
    with pytest.raises(ConfigError, match="key=value"):
        load_config(Outer, None, ["inner.width"])
    with pytest.raises(InputFileError, match="nope.yaml"):
        load_config(Outer, "nope.yaml")
    assert load_config(Outer, None, ["path=none"]).path is None
