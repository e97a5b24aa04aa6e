"""Hard shadows of lights without extent (a point or spot light of radius 0) from REFERENCE, against Cycles.

Cycles' visibility of a delta light is 0 or 1 in each pixel (point-like pixel filter), so the only error
left is where a shadow edge crosses a pixel centre on the wrong side: how far the map puts the edge from
where it lies. REFERENCE has one map for such a light instead of N, and spends up to N maps' texels on it
(averaged.delta_map_size). The class: a light low over a wide floor, whose receivers far from it lie at
grazing angles, where a texel's bias and normal offset move an edge most (fuzz 1027)."""
import math

import pytest

from penumbra.engine.techniques.averaged import DELTA_MAP_MAX, delta_map_size

EDGE_PIXELS = 2         # wrong pixels allowed: an edge within a hair of a pixel centre


def test_delta_map_size_grows_by_the_samples_texels_up_to_its_cap():
    assert delta_map_size(1024, 64) == 4096
    assert delta_map_size(1024, 8) == 2048
    assert delta_map_size(1024, 1) == 1024
    assert delta_map_size(512, 4096) == 2048                  # 16× the texels at most
    assert delta_map_size(3000, 64) == DELTA_MAP_MAX
    assert delta_map_size(8192, 64) == 8192                   # never below the setting


def _low_light_over_wide_floor(kind: str) -> dict:
    light = dict(name="Lamp", type=kind, location=[0.0, 0.0, 0.9], target=[0.3, 0.2, 0.0], scale=[1, 1, 1],
                 scale_kind="one", radius=0.0, soft_falloff=True, energy=300.0)
    if kind == "SPOT":
        light.update(spot_size=math.radians(160.0), spot_blend=0.1)
    objects = [
        dict(name="Ring", primitive="TORUS", transform="plain", location=[0.9, 0.3, 0.35], rotation=[0.6, 0.3, 0.0],
             scale=[0.3] * 3, smooth=True),
        dict(name="Head", primitive="MONKEY", transform="plain", location=[-0.7, 0.8, 0.3],
             rotation=[0.3, 0.0, 2.0], scale=[0.3] * 3, smooth=False),
        dict(name="Box", primitive="CUBE", transform="nonuniform", location=[0.2, -1.0, 0.25],
             rotation=[0.0, 0.0, 0.5], scale=[0.1, 0.4, 0.25], smooth=False)]
    return {"seed": 0, "objects": objects, "floor": dict(half_size=10.0, rotation=[0.0, 0.0, 0.0], z=0.0),
            "lights": [light],
            "camera": dict(ortho=True, location=[4.0, 1.0, 7.0], target=[0.0, 0.0, 0.3], lens=35.0,
                           ortho_scale=9.0, inside=None)}


@pytest.mark.parametrize("kind", ["POINT", "SPOT"])
def test_hard_edges_of_a_low_delta_light_land_on_cycles_pixels(kind):
    """Measured at 64², 256 spp (wrong pixels of ~185 in shadow): a 1024² map (the samples setting at 1)
    POINT 5, SPOT 6; the 4096² map 1 and 1."""
    pytest.importorskip("bpy")
    from penumbra.engine.measure import fuzz
    m, _ = fuzz.shadow_score(_low_light_over_wide_floor(kind), "REFERENCE")
    wrong = m["mae_shadow"] * m["n_shadow"]
    assert wrong <= EDGE_PIXELS, (kind, m["mae_shadow"], m["n_shadow"])
