"""Grazing receivers, self-shadowing and tilted receivers against Cycles (issue 10, items 1 and 2), on the
built-in scenes made for them: `cube` (faces edge-on from the light centre, lit by the rest of the light),
`tilted` (a floor at 25° under a rectangle light), `slab` (a face 10° off edge-on to a 0.5 rad sun).
Cycles references are cached on disk."""
import numpy as np
import pytest

bpy = pytest.importorskip("bpy")

from penumbra.engine.blender.extract import extract  # noqa: E402
from penumbra.engine.core.settings import RenderSettings  # noqa: E402
from penumbra.engine.measure import metrics, reference, scenes  # noqa: E402
from penumbra.engine.render import pipeline  # noqa: E402

RES = (96, 96)
SPP = 256
SHADOW_MAP_TECHNIQUES = ["HARD", "PCF", "PCSS", "REFERENCE", "BACKPROJECTION"]


def _setup(name, resolution=RES):
    sc = scenes.build(name, resolution=resolution)
    return sc, extract(bpy.context.evaluated_depsgraph_get(), sc), reference.cycles_visibility(sc, samples=SPP)


def _visibility(snap, technique, **changes):
    r = pipeline.render(snap, RenderSettings(technique=technique).with_(**changes))
    return r.passes["Visibility"][..., 0]


@pytest.fixture(scope="module")
def cube():
    return _setup("cube")


@pytest.mark.parametrize("technique", SHADOW_MAP_TECHNIQUES)
def test_cube_faces_lit_by_part_of_the_light_are_not_shadowed(cube, technique):
    """The cube's side faces are behind its top as seen from the light centre, yet the light's outer strip
    lights them fully (Cycles: V ≈ 1). Every technique must leave the pixels Cycles sees fully lit lit:
    no face shadowed by its own cube, no acne stripes. Before the receiver's tangent plane bounded what can
    shadow it, HARD and PCF had the faces black and PCSS dark (mae_shadow 0.53, 0.52, 0.41)."""
    sc, snap, ref = cube
    v = _visibility(snap, technique)
    lit = ref.mask & (ref.visibility >= 0.99)
    assert lit.sum() > 2000
    dark = float(np.mean(v[lit] < 0.9))
    print(technique, "share of Cycles-lit pixels below 0.9:", dark)
    assert dark <= 0.01


@pytest.mark.parametrize("name", [
    "cube", "tilted", "slab",
    "room",
    # Cycles shadows a closed solid flattened to zero thickness through its coincident opposite faces (the
    # flat torus is black); tests/test_coincident_sheets.py. Before: mae_shadow 0.35, on the torus itself.
    "flattened"])
def test_reference_within_cycles_noise_on_grazing_scenes(name):
    """REFERENCE (256 samples) within Cycles' own noise floor at 256 spp plus 0.005 (the averaged maps'
    discretisation, as in test_against_cycles.py). On `slab` a sun sample below the face's horizon used to
    count as occluded (0.069 at 128²); it now carries weight 0 in the weighted mean. At 128², where the few
    silhouette pixels whose screen-space geometric normal straddles two surfaces weigh little."""
    sc, snap, ref = _setup(name, (128, 128))
    floor = reference.noise_floor(sc, SPP, width=128, height=128)
    v = _visibility(snap, "REFERENCE", averaged_light_samples=256)
    m = metrics.compare(v, ref.visibility, ref.mask)
    print(name, m, floor)
    assert m["n_shadow"] > 150            # the slab's shadow is a thin band; a dark face would add its pixels
    assert m["mae_shadow"] <= floor["mae_shadow"] + 0.005


# REFERENCE's default became 256 samples (its mae_shadow within Cycles-64's on the class scenes): twice its error
# is now a tighter target than the 64 samples' that these tests were first measured against (96², 256 spp).
@pytest.fixture(scope="module")
def near_contact():
    """(BACKPROJECTION's, REFERENCE's and Cycles-16's mae_shadow) per scene, rendered once for both tests."""
    out = {}

    def scores(name):
        if name not in out:
            sc, snap, ref = _setup(name)
            ours = metrics.compare(_visibility(snap, "BACKPROJECTION"), ref.visibility, ref.mask)["mae_shadow"]
            best = metrics.compare(_visibility(snap, "REFERENCE"), ref.visibility, ref.mask)["mae_shadow"]
            c16 = reference.cycles_visibility(sc, samples=16, seed=3)
            cycles16 = metrics.compare(c16.visibility, ref.visibility, ref.mask)["mae_shadow"]
            print(name, "BACKPROJECTION", ours, "Cycles-16", cycles16, "REFERENCE", best)
            out[name] = ours, best, cycles16
        return out[name]
    return scores


@pytest.mark.heavy
@pytest.mark.parametrize("name", ["tilted", "slab", "contact"])
def test_backprojection_next_to_contacts_within_cycles_16(near_contact, name):
    """Receivers next to their casters: a ball on a tilted floor, a wall's foot lit nearly edge-on, a ball and
    a wall on the ground. There BACKPROJECTION's coarse micro-occluders sit close to the
    receiver, where 1/(d − z) magnifies their approximation (one depth, one box) into the penumbra. With the
    plane refit, the centre clip and the near-field split (the defaults) it must stay at or below Cycles at
    16 spp (issue 11). At 96², before (MEAN refit, no split) → after:
    tilted 0.043 → 0.026 (Cycles-16 0.031), slab 0.062 → 0.022 (0.031), contact 0.024 → 0.019 (0.030); with
    the split at 0.15 and the coverage shrink towards the occluding parts: 0.020, 0.018, 0.015."""
    ours, _, cycles16 = near_contact(name)
    assert ours <= cycles16


@pytest.mark.heavy
@pytest.mark.parametrize("name", ["tilted", "slab", "contact"])
def test_backprojection_next_to_contacts_within_twice_reference(near_contact, name):
    """The same scenes within twice REFERENCE's mae_shadow (issue 10). (Suzanne: 0.025, not within twice
    REFERENCE's 0.012 at 64 samples either.) slab: 0.0138 against REFERENCE's 0.0066 (2.1×) until the tilted
    plates were held to their parts' depths (0.0122; 0.0115 with the split's coarse parts
    left unfilled)."""
    ours, best, _ = near_contact(name)
    assert ours <= 2.0 * best


@pytest.mark.parametrize("name", ["tilted", "suzanne"])
def test_pcss_has_no_isolated_outliers(name):
    """Salt-and-pepper across the penumbra is the bug. Over the penumbra (Cycles 0.05 < V < 0.95) where the
    Cycles image is itself locally smooth (within 0.02 of its 3×3 median, so true edges do not count), PCSS
    may differ from its own 3×3 median by more than 0.02 at no more than 5 % of the pixels. Measured at 128²:
    per-pixel rotated sample patterns 23 % (tilted) and 20 % (suzanne); the fixed pattern 1.3 % and 3.8 %."""
    sc = scenes.build(name, resolution=(128, 128))
    snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
    ref = reference.cycles_visibility(sc, samples=SPP)
    v = _visibility(snap, "PCSS")
    smooth = np.abs(ref.visibility - metrics.median3x3(ref.visibility, ref.mask)) < 0.02
    penumbra = ref.mask & (ref.visibility > 0.05) & (ref.visibility < 0.95) & smooth
    assert penumbra.sum() > 500
    outliers = np.abs(v - metrics.median3x3(v, ref.mask))[penumbra]
    share = float(np.mean(outliers > 0.02))
    print(name, "share > 0.02:", share, "p99", float(np.percentile(outliers, 99)))
    assert share <= 0.05


@pytest.fixture(scope="module")
def grazing():
    return _setup("grazing")


@pytest.mark.parametrize("technique", ["PCSS", "BACKPROJECTION", "SSM", "REFERENCE"])
def test_ground_lit_at_85_degrees_is_not_its_own_caster(grazing, technique):
    """`grazing`: a 2.5 m area light 5° above the horizon, 20 m away. Its rectangle stays above the ground
    (it reaches 1.25 m down from a centre 1.74 m up), so the ground cannot shadow itself and must stay out of
    the light's casters; when the light's half diagonal (1.77 m) stood for its reach, the ground was kept and
    shadowed itself: mae_shadow 0.75 (BACKPROJECTION), 0.36 (PCSS, SSM) at 128². Measured after at 96²:
    BACKPROJECTION 0.058, PCSS 0.051, SSM 0.039, REFERENCE 0.016; the bound is the soft techniques' spread on
    the other built-in scenes."""
    sc, snap, ref = grazing
    m = metrics.compare(_visibility(snap, technique), ref.visibility, ref.mask)
    print(technique, m)
    assert m["mae_shadow"] <= 0.1


def _crumpled_sheet(resolution=RES):
    """A flat-shaded 5×5 grid whose vertices are jittered up and down by up to 0.4 m (bent quads), under a
    1 cm point light 0.9 m above it and 3.5 m to the side: the light grazes many faces, and on a bent quad
    the face normal and its triangles' normals disagree about which side of the light they face."""
    import math
    bpy.ops.wm.read_factory_settings(use_empty=True)
    sc = bpy.context.scene
    sc.render.resolution_x, sc.render.resolution_y = resolution
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=5, y_subdivisions=5, size=4)
    sheet = bpy.context.object
    rng = np.random.default_rng(7)
    for v in sheet.data.vertices:
        v.co.z += float(rng.uniform(-0.4, 0.4))
    sheet.data.shade_flat()
    light = bpy.data.lights.new("Key", "POINT")
    light.shadow_soft_size, light.energy = 0.01, 2000.0
    key = bpy.data.objects.new("Key", light)
    key.location = (3.5, 0.3, 0.9)
    cam = bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    cam.location, cam.rotation_euler = (0.0, -5.0, 5.0), (math.radians(45.0), 0.0, 0.0)
    for ob in (key, cam):
        sc.collection.objects.link(ob)
    sc.camera = cam
    bpy.context.view_layer.update()
    return sc


def test_flat_shaded_bent_faces_are_lit_as_cycles_lights_them():
    """Unshadowed light on flat-shaded bent quads (fuzz seed 3013's class: a flat monkey under a 2 mm light,
    REFERENCE mae_shadow 0.093 against a bound of 0.033, 0.012 after). While shading took the face normal,
    the median pixel's unshadowed light was 17 % off Cycles' and a quarter of the pixels over 48 %; with
    each triangle's own normal the median is 2e-5 and the 75th percentile 6e-5. What remains (about one
    pixel in ten) sits on the triangles' edges, where a pixel holds two faces."""
    sc = _crumpled_sheet()
    ref = reference.cycles_visibility(sc, samples=SPP)
    snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
    r = pipeline.render(snap, RenderSettings(technique="REFERENCE", debug_passes=True))
    ours = metrics.luminance(r.passes["Irradiance"] / np.pi)
    cycles = metrics.luminance(ref.unshadowed)
    lit = ref.mask & (cycles > 1e-3 * np.percentile(cycles[ref.mask], 99))
    rel = np.abs(ours[lit] - cycles[lit]) / cycles[lit]
    print("relative unshadowed error, 50/75/90th percentiles:", np.percentile(rel, [50, 75, 90]))
    assert lit.sum() > 2000
    assert np.percentile(rel, 75) <= 0.01


# Issue 10's target for the grazing and tilted classes: the soft techniques within twice REFERENCE's mae_shadow.
# Where a technique misses it the xfail names the cause and the measured figures (96², Cycles 256 spp). Against
# REFERENCE at its default 256 samples; the 64 samples it had when most of these were measured erred about
# twice as much (0.011-0.014), and within twice that PCSS and BACKPROJECTION held on grazing and tilted.
TWICE_REFERENCE_XFAIL = {
    ("cube", "PCSS"): "the penumbra is wider than the blocker search's reach (pcss_max_radius, 0.1 of the map): "
                      "blockers beyond it go unseen and the mean blocker depth comes out wrong. 0.046 against "
                      "REFERENCE's 0.0035; with both caps raised to 0.2 or 0.5, 0.035 (one mean blocker depth for "
                      "the whole light is what is left; raising the caps makes suzanne, contact, tilted and slab "
                      "worse, and fuzz 8369's stacked casters 0.057 -> 0.369)",
    ("slab", "PCSS"): "the ground at the foot of the slab's lit face: seen from the sun almost edge-on, the face fills "
                      "the filter there with texels nearer than the ground's plane, which the one-depth filter counts "
                      "as blocking rays that pass in front of the face, so the contact line comes out dark: 0.063 "
                      "against REFERENCE's 0.0066 (0.087 against 0.013 before REFERENCE's 256 samples; 0.062 with the "
                      "search weighted towards the receiver's own map position, midpoint blocker depths and the "
                      "filter's own cap)",
    ("slab", "SSM"): "the outer penumbra falls outside the light's map and is taken as lit: a sun's view is fitted with "
                     "no room for its disk of directions (lightview.fit). 0.028 against REFERENCE's 0.0066; with the "
                     "window widened by each lit point's reach 0.015, but on random scenes with suns the coarser "
                     "maps cost more than the tail gains (fuzz 15012 0.071 -> 0.092, 15031 0.019 -> 0.033, and "
                     "every soft technique worse summed over seven such seeds), so it did not land",
}


@pytest.fixture(scope="module")
def class_scenes():
    return {}


@pytest.mark.heavy
@pytest.mark.parametrize("name,technique", [
    pytest.param(n, t, marks=[pytest.mark.xfail(strict=True, reason=TWICE_REFERENCE_XFAIL[(n, t)])]
                 if (n, t) in TWICE_REFERENCE_XFAIL else [])
    for n in ("grazing", "cube", "tilted", "slab") for t in ("PCSS", "SSM", "BACKPROJECTION")])
def test_soft_techniques_within_twice_reference_on_grazing_and_tilted_scenes(class_scenes, name, technique):
    """PCSS with an even vote over its taps → irradiance-weighted taps, 128² against Cycles 1024 spp (bench):
    grazing 0.050 → 0.030, cube 0.097 → 0.089, tilted 0.041 → 0.035. SSM's flat micro-patches → sloped facets
    (ssm_facets): tilted 0.051 → 0.008, cube 0.020 → 0.005 (96² here: tilted 0.053 → 0.011); SSM's irradiance
    weighting with the receiver's own normal in place of one facing the light: grazing 0.038 → 0.009. PCSS's
    filter at 128 → 512 taps (96², REFERENCE at 256 samples): grazing 0.0187 → 0.0115 (REFERENCE 0.0063),
    tilted 0.0191 → 0.0158 (0.0082). BACKPROJECTION's tilted plates held to their parts' depths: slab 0.0138 →
    0.0122 (0.0066); the split's coarse parts left unfilled: 0.0115."""
    if name not in class_scenes:
        sc, snap, ref = _setup(name)
        best = metrics.compare(_visibility(snap, "REFERENCE"), ref.visibility, ref.mask)["mae_shadow"]
        class_scenes[name] = (snap, ref, best)
    snap, ref, best = class_scenes[name]
    ours = metrics.compare(_visibility(snap, technique), ref.visibility, ref.mask)["mae_shadow"]
    print(name, technique, ours, "REFERENCE", best)
    assert ours <= 2.0 * best
