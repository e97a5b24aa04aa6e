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


# ---------------------------------------------------------------------------------------------------------
# One mechanism: the PCF, PCSS and averaged-maps settings are Options of their techniques


def test_technique_settings_are_options_of_their_technique():
    from penumbra.engine.core.settings import SHARED
    declared = {t.identifier: {o.name for o in t.options} for t in techniques.TECHNIQUES.values()}
    assert declared["PCF"] == {"pcf_radius", "pcf_taps"}
    assert declared["PCSS"] == {"pcss_blocker_samples", "pcss_filter_samples", "pcss_max_radius",
                                "pcss_filter_max_radius", "pcss_midpoint"}
    assert declared["REFERENCE"] == {"averaged_light_samples", "averaged_weighted", "averaged_facets"}
    # RenderSettings keeps only what every technique shares.
    shared = {o.name for o in SHARED}
    assert set(RenderSettings.field_names()) == shared | {"technique", "collect_stats", "extras"}
    s = RenderSettings()
    assert (s.option("pcf_radius"), s.option("pcf_taps")) == (2.0, 5)
    assert (s.option("pcss_blocker_samples"), s.option("pcss_filter_samples"), s.option("pcss_max_radius"),
            s.option("pcss_filter_max_radius"), s.option("pcss_midpoint")) == (64, 512, 0.1, 0.2, True)
    assert (s.option("averaged_light_samples"), s.option("averaged_weighted"), s.option("averaged_facets")) == \
        (256, True, False)
    assert (s.shadow_map_size, s.bias, s.normal_offset, s.seed, s.debug_passes) == (1024, 1.0, 0.25, 0, False)


@pytest.mark.parametrize("name, bad, allowed", [
    ("pcf_taps", 0, "1 … 33"), ("pcf_radius", 300.0, "0 … 256"), ("pcss_blocker_samples", 0, "1 … 1024"),
    ("pcss_filter_samples", 5000, "1 … 4096"), ("pcss_max_radius", 2.0, "0.001 … 1"),
    ("averaged_light_samples", 0, "1 … 4096"), ("shadow_map_size", 8, "16 … 16384"), ("bias", -1.0, "0 … 100"),
    ("normal_offset", 101.0, "0 … 100"), ("seed", -1, "≥ 0")])
def test_ranges_come_from_the_options(name, bad, allowed):
    with pytest.raises(ValueError, match=f"Setting '{name}' = .* out of range \\({allowed}\\)"):
        RenderSettings().with_(**{name: bad}).validate()


def test_old_names_are_refused_with_their_new_name():
    with pytest.raises(ValueError, match="reference_samples.*averaged_light_samples"):
        RenderSettings().with_(reference_samples=8).validate()


def test_effective_settings_fill_in_the_techniques_defaults():
    explicit = RenderSettings(technique="PCF").with_(pcf_radius=2.0)
    assert explicit.effective() == RenderSettings(technique="PCF").effective()
    assert RenderSettings(technique="PCF").with_(pcf_radius=4.0).effective()["pcf_radius"] == 4.0
    assert "pcss_filter_samples" not in RenderSettings(technique="PCF").effective()


# ---------------------------------------------------------------------------------------------------------
# Blender: passes follow the settings that change them; files saved with old names load with their values


def _registered_bpy():
    bpy = pytest.importorskip("bpy")
    import penumbra
    if not hasattr(bpy.types.Scene, "penumbra"):
        penumbra.register()
    return bpy


def test_changing_technique_or_debug_passes_refreshes_blenders_passes():
    bpy = _registered_bpy()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.engine = "PENUMBRA"
    tree = bpy.data.node_groups.new("Passes", "CompositorNodeTree")
    sc.compositing_node_group = tree
    layers = tree.nodes.new("CompositorNodeRLayers")

    def shown():
        return {o.name for o in layers.outputs if o.enabled}

    assert "Irradiance" not in shown()
    sc.penumbra.debug_passes = True
    assert "Irradiance" in shown()
    sc.penumbra.technique = "BACKPROJECTION"
    assert {"BP Class", "BP Level"} <= shown()
    sc.penumbra.debug_passes = False
    assert not shown() & {"Irradiance", "BP Class", "BP Level"}


def test_a_file_saved_with_old_setting_names_loads_with_their_values(tmp_path):
    bpy = _registered_bpy()
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    props = sc.penumbra
    # What an older Penumbra stored: values under names that have been renamed since.
    store = props.bl_system_properties_get() if hasattr(props, "bl_system_properties_get") else props
    store["reference_samples"] = 200
    store["reference_weighted"] = 0
    path = tmp_path / "old.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(path))
    bpy.ops.wm.read_factory_settings(use_empty=True)
    bpy.ops.wm.open_mainfile(filepath=str(path))
    props = bpy.context.scene.penumbra
    assert props.averaged_light_samples == 200 and props.averaged_weighted is False
    store = props.bl_system_properties_get() if hasattr(props, "bl_system_properties_get") else props
    assert "reference_samples" not in store.keys() and "reference_weighted" not in store.keys()
    from penumbra.engine.blender.settings_bridge import settings_from_scene
    assert settings_from_scene(bpy.context.scene).option("averaged_light_samples") == 200


class _Layout:
    """Records what a panel draws (layout.prop names), standing in for Blender's UILayout."""

    def __init__(self, drawn):
        self.drawn, self.use_property_split = drawn, False

    def prop(self, data, name, **_):
        assert name in data.bl_rna.properties, name      # every drawn name is a real property
        self.drawn.append(name)

    def prop_search(self, data, name, *_, **__):    # a text property with a datablock search (images)
        self.prop(data, name)

    def column(self, **_):
        return self

    row = column

    def operator(self, *_, **__):
        pass

    def label(self, **_):
        pass


def test_the_panel_draws_each_techniques_options_from_its_option_list():
    bpy = _registered_bpy()
    from penumbra.ui.panels import RENDER_PT_penumbra
    sc = bpy.context.scene
    for technique in techniques.TECHNIQUES.values():
        sc.penumbra.technique = technique.identifier
        drawn = []
        panel = type("Panel", (), {"layout": _Layout(drawn)})()
        RENDER_PT_penumbra.draw(panel, type("Context", (), {"scene": sc})())
        own = [o.name for o in technique.options] + list(technique.reads_shared)
        assert [n for n in drawn if n in own] == own, technique.identifier
        others = {o.name for t in techniques.TECHNIQUES.values() if t is not technique for o in t.options}
        assert not others & set(drawn), technique.identifier
    assert techniques.TECHNIQUES["REFERENCE"].reads_shared == ("seed", "early_skip")  # drawn beside its options
