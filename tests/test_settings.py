"""Technique options: declared once on the technique, reachable from RenderSettings, the CLI and Blender."""
import pytest

from penumbra.engine import techniques
from penumbra.engine.core.settings import RenderSettings
from penumbra.engine.techniques.base import Option, Technique


class _Demo(Technique):
    identifier = "DEMO"
    options = (Option("demo_level", 3, "Level", min=1, max=8),
               Option("demo_mode", "A", "Mode", items=(("A", "A", ""), ("B", "B", ""))))


@pytest.fixture()
def demo(monkeypatch):
    monkeypatch.setitem(techniques.TECHNIQUES, "DEMO", _Demo())


def test_options_route_to_extras_and_default(demo):
    s = RenderSettings(technique="DEMO")
    assert s.option("demo_level") == 3
    t = s.with_(demo_level=5, shadow_map_size=512)
    assert t.option("demo_level") == 5 and t.shadow_map_size == 512 and s.option("demo_level") == 3
    t.validate()


def test_bad_options_name_the_setting(demo):
    with pytest.raises(ValueError, match="demo_level"):
        RenderSettings(technique="DEMO").with_(demo_level=99).validate()
    with pytest.raises(ValueError, match="demo_mode"):
        RenderSettings(technique="DEMO").with_(demo_mode="C").validate()
    with pytest.raises(ValueError, match="Unknown setting 'nope'"):
        RenderSettings().with_(nope=1).validate()


def test_cli_set_accepts_options(demo):
    from penumbra.engine.cli import parse_overrides
    assert parse_overrides(["demo_level=4", "bias=0.5"]) == {"demo_level": 4, "bias": 0.5}
    with pytest.raises(SystemExit, match="NAME one of"):
        parse_overrides(["bogus=1"])
