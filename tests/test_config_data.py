"""trumans.config_data.config_from_dict: the one dict -> config reader (sampler, refine, training)."""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Literal

import pytest

from trumans.config_data import config_from_dict


@dataclass(frozen=True)
class Inner:
    frames: int = 8
    span: tuple[int, int] = (5, 20)
    extent: tuple[float, float, float] = (1.2, 1.2, 1.2)


@dataclass(frozen=True)
class Outer:
    name: str = "x"
    share: float | None = None
    mode: Literal["a", "b"] = "a"
    kinds: tuple[str, ...] = ("walk",)
    inner: Inner = field(default_factory=Inner)


@dataclass(frozen=True)
class Required:
    width: int
    depth: int = 2


def test_values_keep_their_types_and_defaults() -> None:
    c = config_from_dict(Outer, {"share": 0.25, "mode": "b", "kinds": ["sit", "lie"], "inner": {"span": [3, 9]}})
    assert c == Outer(share=0.25, mode="b", kinds=("sit", "lie"), inner=Inner(span=(3, 9)))
    assert all(type(v) is int for v in c.inner.span)  # integer pairs stay integers
    assert config_from_dict(Outer, {"share": None}).share is None
    assert config_from_dict(Outer, {"inner": {"extent": [1, 2, 3]}}).inner.extent == (1.0, 2.0, 3.0)
    base = Outer(name="base", inner=Inner(frames=4))
    assert config_from_dict(Outer, {"inner": {"span": [1, 2]}}, base=base) == Outer(name="base", inner=Inner(4, (1, 2)))
    assert config_from_dict(Required, {"width": 3}) == Required(3)


@pytest.mark.parametrize("data, msg", [
    ({"inner": {"span": [5.5, 20]}}, r"config\.inner\.span must be a whole number, got 5\.5"),
    ({"inner": {"span": [5]}}, r"config\.inner\.span must be a list of 2 whole numbers"),
    ({"inner": {"extent": [1, 2, float("nan")]}}, r"config\.inner\.extent must be a finite number"),
    ({"share": "half"}, r"config\.share must be a finite number"),
    ({"mode": "c"}, r"config\.mode must be one of \['a', 'b'\]"),
    ({"kinds": "walk"}, r"config\.kinds must be a list of names"),
    ({"inner": {"frame": 3}}, r"config\.inner: unknown key\(s\) \['frame'\]"),
    ({"inner": 3}, r"config\.inner must be a mapping"),
])
def test_bad_values_name_their_path(data, msg) -> None:
    with pytest.raises(ValueError, match=msg):
        config_from_dict(Outer, data)


def test_derived_keys_and_missing_required_fields() -> None:
    with pytest.raises(ValueError, match=r"config\.inner\.frames is set by data\.episode_frames, not in a config"):
        config_from_dict(Outer, {"inner": {"frames": 3}}, derived={"inner": {"frames": "data.episode_frames"}})
    with pytest.raises(ValueError, match=r"config\.name is set by the dataset"):
        config_from_dict(Outer, {"name": "y"}, derived={"name": "the dataset"})
    with pytest.raises(ValueError, match=r"config: .*width"):
        config_from_dict(Required, {"depth": 3})
