"""engine/core/irradiance.py against Cycles: unoccluded direct diffuse light, one light per case.

Each case builds a scene from code (factory settings, empty): a large ground plane plus a plane tilted
by 45° whose plane passes through the light position (so the light straddles the receivers' horizon
there), both white Diffuse BSDF, no shadows (`visible_shadow = False`), one light that the camera
does not see. Cycles renders direct light only (max_bounces 0) to a multilayer EXR; each pixel's
world position and normal are found analytically (camera ray ∩ planes) and the prediction is
albedo/π · E, averaged over a 2×2 grid inside the pixel (Cycles' box filter of width 1 px integrates
over the whole pixel). EXR rows: row 0 is the TOP of the image.

Measured mean relative errors (noise + model) at 256 spp, silhouette pixels excluded: 0.01–0.14 %
for area/point/sun, 0.5 % for the spot with a radius (cone averaged over 64 emitter cells). The 2 %
bound is therefore far above the noise floor yet catches every convention error seen while measuring
(4/π area factor 27 %, sun cos²β 33 %, soft-falloff vs sphere 6 %, spot cone at the light centre
only 10 %, spot scale divided vs multiplied > 25 %).
"""
from __future__ import annotations

import math
import os
import tempfile

import numpy as np
import pytest

from penumbra.engine.render import pipeline
from penumbra.engine.blender.extract import extract, make_light
from penumbra.engine.core.settings import RenderSettings

bpy = pytest.importorskip("bpy")
OpenEXR = pytest.importorskip("OpenEXR")

from penumbra.engine.core.irradiance import cycles_radius_share, irradiance  # noqa: E402
from penumbra.engine.core.snapshot import Light  # noqa: E402

W = H = 96
SAMPLES = 256
SUPERSAMPLE = 2
LIGHT_POS = (0.0, 0.0, 1.2)


def _white_material():
    """Pure Lambertian white: a Diffuse BSDF with roughness 0. (A Principled BSDF with base colour
    white and `Specular IOR Level` = 0 renders identically in Cycles 5.0.)"""
    mat = bpy.data.materials.new("white")
    nt = mat.node_tree
    nt.nodes.clear()
    out = nt.nodes.new("ShaderNodeOutputMaterial")
    bsdf = nt.nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.0
    nt.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


def _plane(name, size, location, rotation, mat):
    mesh = bpy.data.meshes.new(name)
    h = 0.5 * size
    mesh.from_pydata([(-h, -h, 0), (h, -h, 0), (h, h, 0), (-h, h, 0)], [], [(0, 1, 2, 3)])
    ob = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(ob)
    ob.location = location
    ob.rotation_euler = rotation
    ob.data.materials.append(mat)
    ob.visible_shadow = False
    return ob, h


def _build_scene(light_kind, light_props, obj_props, samples=SAMPLES):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device = "CPU"
    c.samples = samples
    c.use_adaptive_sampling = False
    c.use_denoising = False
    c.max_bounces = 0
    c.light_sampling_threshold = 0.0
    c.pixel_filter_type = "BOX"
    c.filter_width = 1.0
    c.seed = 0
    scene.render.resolution_x, scene.render.resolution_y = W, H
    scene.render.resolution_percentage = 100

    mat = _white_material()
    # The tilted plane satisfies x + z = 1.2: it contains LIGHT_POS.
    planes = [_plane("ground", 30.0, (0, 0, 0), (0, 0, 0), mat),
              _plane("tilted", 1.0, (0.75, 0.0, 0.45), (0, math.radians(45), 0), mat)]

    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    cam.data.lens = 28
    scene.collection.objects.link(cam)
    cam.location = (0.3, -4.5, 4.0)
    from mathutils import Vector
    cam.rotation_euler = (Vector((0.3, 0.0, 0.3)) - cam.location).to_track_quat("-Z", "Y").to_euler()
    scene.camera = cam

    data = bpy.data.lights.new("light", light_kind)
    for k, v in light_props.items():
        setattr(data, k, v)
    lob = bpy.data.objects.new("light", data)
    scene.collection.objects.link(lob)
    lob.location = obj_props.get("location", LIGHT_POS)
    lob.rotation_euler = obj_props.get("rotation", (0, 0, 0))
    lob.scale = obj_props.get("scale", (1, 1, 1))
    lob.visible_camera = False
    if "parent_scale" in obj_props:
        # Under a non-uniformly scaled parent the light's rotation skews its world axes.
        parent = bpy.data.objects.new("light_parent", None)
        scene.collection.objects.link(parent)
        parent.location, parent.scale = lob.location, obj_props["parent_scale"]
        lob.location, lob.parent = (0.0, 0.0, 0.0), parent
    bpy.context.view_layer.update()
    return scene, cam, planes, lob


def _render_combined(scene) -> np.ndarray:
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "out.exr")
        settings = scene.render.image_settings
        settings.media_type = "MULTI_LAYER_IMAGE"
        settings.file_format = "OPEN_EXR_MULTILAYER"
        settings.color_depth = "32"
        scene.render.filepath = path
        bpy.ops.render.render(write_still=True)
        for part in OpenEXR.File(path).parts:  # one part per pass, e.g. "ViewLayer.Combined"
            for name, ch in part.channels.items():
                if name.endswith("Combined"):
                    return ch.pixels[..., :3].astype(np.float64)  # (H, W, 3), row 0 = top
    raise AssertionError("no Combined pass in the EXR")


def _pixel_geometry(cam, planes, w, h):
    """World position, camera-facing normal and plane index (-1: none) per sample, row 0 = top;
    position/normal NaN where no plane is hit."""
    dg = bpy.context.evaluated_depsgraph_get()
    proj = np.array(cam.calc_matrix_camera(dg, x=W, y=H))
    cam_to_world = np.array(cam.matrix_world)
    ii, jj = np.meshgrid(np.arange(w), np.arange(h))
    ndc = np.stack([(ii + 0.5) / w * 2 - 1, 1 - (jj + 0.5) / h * 2,
                    -np.ones((h, w)), np.ones((h, w))], -1).reshape(-1, 4)
    pc = ndc @ np.linalg.inv(proj).T
    d = (pc[:, :3] / pc[:, 3:4]) @ cam_to_world[:3, :3].T
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    o = cam_to_world[:3, 3]
    best = np.full(d.shape[0], np.inf)
    pos = np.full(d.shape, np.nan)
    nrm = np.full(d.shape, np.nan)
    ids = np.full(d.shape[0], -1)
    for k, (ob, half) in enumerate(planes):
        m = np.array(ob.matrix_world)
        c, ax, ay = m[:3, 3], m[:3, 0], m[:3, 1]
        n = np.cross(ax, ay)
        n /= np.linalg.norm(n)
        denom = d @ n
        t = ((c - o) @ n) / np.where(np.abs(denom) > 1e-12, denom, 1e-12)
        x = o + t[:, None] * d
        lx, ly = (x - c) @ ax / (ax @ ax), (x - c) @ ay / (ay @ ay)
        ok = (t > 0) & (np.abs(lx) <= half) & (np.abs(ly) <= half) & (t < best)
        best[ok] = t[ok]
        ids[ok] = k
        pos[ok] = x[ok]
        nrm[ok] = np.where((d[ok] @ n < 0)[:, None], n, -n)  # Cycles shades the side it sees
    return pos, nrm, ids


def _light_from_object(ob) -> Light:
    """The light as extraction reads it (engine/scene.make_light: area size scales with the object, point/spot
    radius does not, power = energy · 2^exposure, Normalize off folded into the power)."""
    return make_light(ob.name, ob.data, np.array(ob.matrix_world), lambda text: None)


CASES = {
    "area_square": ("AREA", dict(shape="SQUARE", size=1.0, energy=100.0), {}),
    "area_rectangle_scaled": ("AREA", dict(shape="RECTANGLE", size=1.0, size_y=0.5, energy=80.0,
                                           color=(1.0, 0.5, 0.25)),
                              dict(rotation=(0.3, 0.0, 0.4), scale=(1.4, 0.8, 1.0))),
    "area_disk_not_normalized": ("AREA", dict(shape="DISK", size=0.8, energy=60.0, normalize=False), {}),
    "area_ellipse_scaled": ("AREA", dict(shape="ELLIPSE", size=1.0, size_y=0.5, energy=100.0),
                            dict(rotation=(-0.3, 0.2, 0.0), scale=(1.5, 0.8, 1.0))),
    "point_radius_soft": ("POINT", dict(shadow_soft_size=0.3, energy=100.0), {}),
    "point_radius_sphere_exposure": ("POINT", dict(shadow_soft_size=0.3, energy=50.0, exposure=1.0,
                                                   use_soft_falloff=False), {}),
    "point_radius0": ("POINT", dict(shadow_soft_size=0.0, energy=100.0), {}),
    "spot_radius_blend_scaled": ("SPOT", dict(shadow_soft_size=0.15, energy=150.0,
                                              spot_size=math.radians(80), spot_blend=0.5),
                                 dict(rotation=(0.2, 0.0, 0.0), scale=(1.4, 1.0, 1.0))),
    "sun_angle": ("SUN", dict(angle=math.radians(40), energy=3.0), dict(rotation=(0.5, 0.2, 0.0))),
    # Issue 10 item 5: extreme lights.
    "area_ellipse_tiny_nonuniform": ("AREA", dict(shape="ELLIPSE", size=1e-3, size_y=2e-3, energy=100.0),
                                     dict(rotation=(0.3, 0.0, 0.2), scale=(0.7, 0.5, 1.3))),
    "point_tiny_radius": ("POINT", dict(shadow_soft_size=1e-4, energy=100.0), {}),
    "sun_3rad": ("SUN", dict(angle=3.0, energy=3.0), dict(rotation=(0.5, 0.2, 0.0))),
    "sun_180": ("SUN", dict(angle=math.pi, energy=3.0), dict(rotation=(0.9, 0.2, 0.0))),
    "point_zero_scale": ("POINT", dict(shadow_soft_size=0.2, energy=100.0), dict(scale=(0.0, 0.0, 0.0))),
    "spot_nonuniform_scale": ("SPOT", dict(shadow_soft_size=0.05, energy=150.0, spot_size=math.radians(100),
                                           spot_blend=0.3),
                              dict(rotation=(0.3, -0.2, 0.0), scale=(2.0, 0.5, 0.7))),
    # Spots with a zero scale axis (extract._singular_spot: Cycles' 1e-8 tweak of the singular inverse): a
    # zero Z lights the half-space below the light's tilted X/Y plane, whatever the cone.
    "spot_zero_z_scale_tilted": ("SPOT", dict(shadow_soft_size=0.05, energy=150.0, spot_size=math.radians(50),
                                              spot_blend=0.2),
                                 dict(rotation=(0.8, 0.0, 0.3), scale=(0.8, 1.6, 0.0))),
    # Object scales Cycles ignores or that only turn the light (issue 10 item 5): a point light's any scale,
    # mirrored axes (a spot's or an area light's negative Z turns its emission), a sun's non-uniform scale.
    "point_nonuniform_scale": ("POINT", dict(shadow_soft_size=0.3, energy=100.0),
                               dict(rotation=(0.3, 0.2, 0.1), scale=(1.0, 0.3, 2.0))),
    "point_sphere_mirrored": ("POINT", dict(shadow_soft_size=0.3, energy=100.0, use_soft_falloff=False),
                              dict(rotation=(0.3, 0.2, 0.1), scale=(-1.0, 0.3, 2.0))),
    "spot_mirrored_z": ("SPOT", dict(shadow_soft_size=0.05, energy=150.0, spot_size=math.radians(100),
                                     spot_blend=0.3), dict(rotation=(math.pi - 0.3, 0.0, 0.0), scale=(1.5, 0.6, -1.0))),
    "spot_mirrored_x": ("SPOT", dict(shadow_soft_size=0.05, energy=150.0, spot_size=math.radians(100),
                                     spot_blend=0.3), dict(rotation=(0.3, -0.2, 0.0), scale=(-2.0, 0.5, 0.7))),
    "area_mirrored_x": ("AREA", dict(shape="RECTANGLE", size=1.0, size_y=0.5, energy=80.0),
                        dict(rotation=(0.3, 0.0, 0.4), scale=(-1.4, 0.8, 1.0))),
    "area_mirrored_z": ("AREA", dict(shape="RECTANGLE", size=1.0, size_y=0.5, energy=80.0),
                        dict(rotation=(math.pi - 0.3, 0.0, 0.4), scale=(1.4, 0.8, -1.0))),
    "area_disk_z_scale": ("AREA", dict(shape="DISK", size=1.0, energy=80.0),
                          dict(rotation=(0.3, 0.0, 0.4), scale=(1.0, 0.6, 3.0))),
    "sun_nonuniform_mirrored": ("SUN", dict(angle=0.6, energy=3.0),
                                dict(rotation=(math.pi - 0.5, 0.2, 0.0), scale=(2.0, 0.3, -1.0))),
    # A sun's zero X scale changes nothing in Cycles (its direction is the Z axis, its angle unscaled).
    "sun_zero_x_scale": ("SUN", dict(angle=1.2, energy=3.0), dict(rotation=(0.5, 0.2, 0.0), scale=(0.0, 0.6, 3.0))),
    # A spot whose true sphere holds the receivers near it: no cone inside, one-sided for BSDF rays.
    "spot_inside_sphere": ("SPOT", dict(shadow_soft_size=2.0, energy=400.0, use_soft_falloff=False,
                                        spot_size=math.radians(40), spot_blend=0.2), {}),
    # A narrow cone from a disk wider than its height: only a small off-centre part of the disk reaches
    # each receiver inside the cone (the footprint quadrature).
    "spot_wide_disk_narrow_cone": ("SPOT", dict(shadow_soft_size=4.0, energy=400.0, spot_size=math.radians(30),
                                                spot_blend=0.4), dict(rotation=(0.35, 0.0, 0.0))),
}


# Cases whose Cycles image is noisy at SAMPLES (measured: two seeds differ by 10 % per pixel for the wide
# disk, whose uniform emitter samples rarely fall inside the cone).
CASE_SAMPLES = {"spot_wide_disk_narrow_cone": 2048}


# Strict: the day the model matches, the xfail must go.
XFAIL = {"spot_inside_sphere": "inside a spot's true sphere Cycles gives 4–9 % less near the sphere's surface than "
                               "the one-sided MIS model E = πL(3 + cosθ)/4 (exact on fuzz seed 52 at d = 0.4 r); "
                               "measured here: mean relative error 4.2 %, Cycles/model 0.969; not understood"}


@pytest.mark.heavy
@pytest.mark.parametrize("case", [pytest.param(c, marks=pytest.mark.xfail(strict=True, reason=XFAIL[c]))
                                  if c in XFAIL else c for c in CASES])
def test_irradiance_matches_cycles(case):
    kind, light_props, obj_props = CASES[case]
    scene, cam, planes, lob = _build_scene(kind, light_props, obj_props, CASE_SAMPLES.get(case, SAMPLES))
    img = _render_combined(scene)

    s = SUPERSAMPLE
    pos, nrm, ids = _pixel_geometry(cam, planes, W * s, H * s)
    hit = ~np.isnan(pos[:, 0])
    e = np.zeros(pos.shape)
    e[hit] = irradiance(_light_from_object(lob), pos[hit], nrm[hit])
    assert np.all(np.isfinite(e))
    pred = (e / np.pi).reshape(H, s, W, s, 3).mean(axis=(1, 3))  # albedo 1: L_o = E/π

    # Pixels that straddle a silhouette (their area covers two planes, or a neighbour's does) mix
    # surfaces in Cycles' box filter; leave them out.
    ids = ids.reshape(H, s, W, s)
    mixed = ids.min(axis=(1, 3)) != ids.max(axis=(1, 3))
    padded = np.pad(mixed, 1)
    edge = np.zeros_like(mixed)
    for dj in range(3):
        for di in range(3):
            edge |= padded[dj:dj + H, di:di + W]

    lum_pred, lum_img = pred.mean(-1), img.mean(-1)
    lit = (lum_pred > 0.05 * lum_pred.max()) & ~edge
    assert lit.sum() > 150, f"{case}: only {lit.sum()} lit pixels"
    rel = np.abs(lum_img[lit] - lum_pred[lit]) / lum_pred[lit]
    ratio = lum_img[lit].sum() / lum_pred[lit].sum()
    # per-channel ratio checks the colour is carried through
    chan = img[lit].sum(axis=0) / pred[lit].sum(axis=0)
    print(f"{case}: mean rel err {rel.mean():.4f}, total ratio {ratio:.4f}, lit px {lit.sum()}")
    if case in CASE_SAMPLES:
        # Still noise-limited per pixel at 2048 spp (measured: mean relative error 4.4 %, Cycles/prediction
        # 0.984; before the footprint quadrature 25 % and 0.79): the total is what is checked.
        assert abs(ratio - 1.0) < 0.02, f"{case}: Cycles/prediction {ratio:.4f}"
    else:
        assert rel.mean() < 0.02, f"{case}: mean relative error {rel.mean():.4f}"
        assert abs(ratio - 1.0) < 0.01, f"{case}: Cycles/prediction {ratio:.4f}"
    assert np.all(np.abs(chan - 1.0) < 0.02), f"{case}: per-channel ratios {chan}"
    # nothing lit where we predict darkness (beyond the noise of the lit neighbourhood)
    assert np.all(lum_img[(lum_pred == 0) & ~edge] < 0.02 * lum_pred.max())

    # End to end: the same scene through extraction and the GPU pipeline; its Unshadowed pass (albedo 1)
    # against the Cycles render on the same pixels.
    snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
    gpu = np.flipud(pipeline.render(snap, RenderSettings(technique="HARD")).passes["Unshadowed"])
    # (a case still noisy in Cycles is checked against the numpy prediction, which is checked above)
    expect = lum_pred if case in CASE_SAMPLES else lum_img
    rel_gpu = np.abs(expect[lit] - gpu.mean(-1)[lit]) / expect[lit]
    print(f"{case}: GPU Unshadowed mean rel err {rel_gpu.mean():.4f}")
    assert rel_gpu.mean() < 0.02, f"{case}: GPU Unshadowed mean relative error {rel_gpu.mean():.4f}"


def test_skewed_spot():
    """A spot under a rotated, non-uniformly scaled parent has skewed axes; Cycles' cone is the image of its
    round cone under the inverse object map (Light.spot_linear). Inside the cone its light tree bounds the spot
    by (atan(tan(spot_size/2)·max|X|,|Y| / |Z|) plus the emitter's angular radius, around its Z axis) the model
    must match as every other light; past that bound Cycles only lights receivers through BSDF rays that hit
    the 5 cm emitter (sparse fireflies, converging to the cone), and the extraction warns. Measured at 512 spp:
    inside, mean relative error 0.45 %, GPU 1.8 %; past it, Cycles/model 0.13. Median relative error over
    every lit pixel: 0.04 % with the inverse map, 41 % with the cone from the axes' lengths alone (the model
    before), 100 % dotting with the scaled axes instead of inverting."""
    scene, cam, planes, lob = _build_scene("SPOT", dict(shadow_soft_size=0.05, energy=150.0,
                                                        spot_size=math.radians(100), spot_blend=0.3),
                                           dict(rotation=(0.3, 0.0, 0.7), parent_scale=(1.6, 0.6, 1.0)), 512)
    img = _render_combined(scene).mean(-1)
    s = SUPERSAMPLE
    pos, nrm, ids = _pixel_geometry(cam, planes, W * s, H * s)
    hit = ~np.isnan(pos[:, 0])
    light = _light_from_object(lob)
    assert light.spot_linear is not None
    e = np.zeros(pos.shape)
    e[hit] = irradiance(light, pos[hit], nrm[hit])
    pred = (e / np.pi).reshape(H, s, W, s, 3).mean(axis=(1, 3)).mean(-1)
    # the angle of each sample off Cycles' spot axis against the light tree's bound
    m = np.array(lob.matrix_world)[:3, :3]
    axis = -m[:, 2] / np.linalg.norm(m[:, 2])
    length = np.linalg.norm(m, axis=0)
    bound = math.atan(math.tan(light.spot_size / 2) * max(length[0], length[1]) / length[2])
    to = np.where(hit[:, None], pos - light.position, 1.0)
    dist = np.linalg.norm(to, axis=1)
    off = np.arccos(np.clip(to @ axis / dist, -1.0, 1.0)) - np.arcsin(np.minimum(light.radius / dist, 1.0))
    ids, off = ids.reshape(H, s, W, s), off.reshape(H, s, W, s)
    one_plane = (ids.min(axis=(1, 3)) == ids.max(axis=(1, 3))) & (ids.min(axis=(1, 3)) >= 0)
    bright = one_plane & (pred > 0.05 * pred.max())
    inside = bright & (off.max(axis=(1, 3)) < bound - 0.01)
    outside = bright & (off.min(axis=(1, 3)) > bound + 0.01)
    assert inside.sum() > 150 and outside.sum() > 20, (inside.sum(), outside.sum())
    rel = np.abs(img[inside] - pred[inside]) / pred[inside]
    print(f"inside: mean rel err {rel.mean():.4f}; outside: Cycles/model {img[outside].sum() / pred[outside].sum():.3f}")
    assert rel.mean() < 0.02 and abs(img[inside].sum() / pred[inside].sum() - 1.0) < 0.01
    assert img[outside].sum() < 0.5 * pred[outside].sum()
    snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
    assert any("skewed axes" in w and "'light'" in w and "fireflies" in w for w in snap.warnings), snap.warnings
    gpu = np.flipud(pipeline.render(snap, RenderSettings(technique="HARD")).passes["Unshadowed"]).mean(-1)
    rel_gpu = np.abs(img[inside] - gpu[inside]) / img[inside]
    print(f"GPU Unshadowed inside: mean rel err {rel_gpu.mean():.4f}")
    assert rel_gpu.mean() < 0.02


@pytest.mark.parametrize("scale", [(1.0, 1.0, 1.0), (-1.0, 1.0, 1.0), (1.0, -1.0, 1.0)], ids=["plain", "x-", "y-"])
def test_textured_area_light_image_side(scale):
    """A 2 m square light 0.3 m over the ground, its image red on the upper half (+v) and green below: Cycles
    lays it along the object's own X and Y axes, a mirrored one included (red over world -Y when Y is
    mirrored, over +Y when X is). Light.texture, over the light frame's [-1, 1]², must put red on the same
    side (a mirrored matrix's right-handed frame has its Y against the object's: before, red came out on the
    wrong side for both mirrors)."""
    scene, cam, planes, lob = _build_scene("AREA", dict(shape="SQUARE", size=2.0, energy=200.0),
                                           dict(location=(0.0, 0.0, 0.3), scale=scale), 32)
    data = lob.data
    data.use_nodes = True
    image = bpy.data.images.new("halves", 2, 2)
    px = np.zeros((2, 2, 4), np.float32)
    px[..., 3] = 1.0
    px[1, :, 0] = 1.0                   # the upper row: red
    px[0, :, 1] = 1.0                   # the lower row: green
    image.pixels.foreach_set(px.ravel())
    tex = data.node_tree.nodes.new("ShaderNodeTexImage")
    tex.image, tex.interpolation = image, "Closest"
    emission = next(n for n in data.node_tree.nodes if n.type == "EMISSION")
    data.node_tree.links.new(tex.outputs["Color"], emission.inputs["Color"])
    img = _render_combined(scene)
    pos, nrm, ids = _pixel_geometry(cam, planes, W, H)
    ground = (ids.reshape(H, W) == 0) & (np.abs(pos[:, 0].reshape(H, W)) < 0.5)
    redness = img[..., 0] - img[..., 1]
    cycles_red_at_plus_y = redness[ground & (pos[:, 1].reshape(H, W) > 0.2)].mean()
    assert abs(cycles_red_at_plus_y) > 1.0
    light = _light_from_object(lob)
    row = -1 if light.matrix[1, 1] > 0 else 0           # the texture row over world +Y
    ours_red_at_plus_y = light.texture[row, 0, 0] - light.texture[row, 0, 1]
    assert np.sign(ours_red_at_plus_y) == np.sign(cycles_red_at_plus_y), (cycles_red_at_plus_y, light.texture)


@pytest.mark.parametrize("technique", ["REFERENCE", "PCSS"])
def test_skewed_spot_shadows_as_in_cycles(technique):
    """The skewed spot of test_skewed_spot (15 cm emitter) over a 30 cm cube on the ground: its shadow within
    the fuzz's bound for the technique (Cycles' second seed as the floor). Measured at 96²: REFERENCE 0.023,
    PCSS 0.050 (bounds 0.049 and 0.17; Cycles' noise floor 0.006)."""
    from penumbra.engine.measure import fuzz
    from penumbra.engine.measure.metrics import compare
    from penumbra.engine.measure.reference import cycles_visibility
    scene, cam, planes, lob = _build_scene("SPOT", dict(shadow_soft_size=0.15, energy=150.0,
                                                        spot_size=math.radians(100), spot_blend=0.3),
                                           dict(rotation=(0.3, 0.0, 0.7), parent_scale=(1.6, 0.6, 1.0)))
    bpy.data.objects.remove(planes[1][0])
    bpy.ops.mesh.primitive_cube_add(size=0.3, location=(-0.1, 0.1, 0.6))
    bpy.context.view_layer.update()
    ref, second = (cycles_visibility(scene, samples=SAMPLES, seed=k, width=W, height=H) for k in (0, 1))
    floor = compare(second.visibility, ref.visibility, ref.mask & second.mask)["mae_shadow"]
    snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
    v = pipeline.render(snap, RenderSettings(antialiasing=False, technique=technique)).passes["Visibility"][..., 0]
    m = compare(v, ref.visibility, ref.mask)
    assert m["n_shadow"] > 100
    assert m["mae_shadow"] < fuzz.bound(technique, floor, m["n_shadow"]), (m["mae_shadow"], floor)


def test_skewed_area_light_warns():
    """An area light with skewed axes: Cycles samples its skewed extents as a rectangle with perpendicular
    sides (kernel/light/area.h), which no parallelogram model reproduces (measured here: Cycles 2.6× the
    light of the rectangle of the same side lengths on the receivers lit). Extraction says so, naming it; a
    mirrored but perpendicular area light gets no such warning."""
    warnings = []
    for parent_scale, rotation in (((1.6, 0.6, 1.0), (0.0, 0.0, 0.7)), ((1.0, 1.0, 1.0), (0.3, 0.0, 0.4))):
        scene, cam, planes, lob = _build_scene("AREA", dict(shape="RECTANGLE", size=1.0, size_y=0.5, energy=80.0),
                                               dict(rotation=rotation, scale=(-1.4, 0.8, 1.0),
                                                    parent_scale=parent_scale))
        warnings.append(extract(bpy.context.evaluated_depsgraph_get(), scene).warnings)
    assert any("area light 'light' has skewed axes" in w for w in warnings[0]), warnings[0]
    assert not any("skewed" in w for w in warnings[1]), warnings[1]


def test_spot_with_coplanar_axes_warns():
    """A spot under a rotated parent flattened to zero on one axis: no axis of its own is zero, but all three
    lie in one plane, so the object map has no inverse; extraction names it in a warning instead of failing."""
    scene, cam, planes, lob = _build_scene("SPOT", dict(shadow_soft_size=0.05, energy=150.0,
                                                        spot_size=math.radians(100)),
                                           dict(rotation=(0.3, 0.4, 0.7), parent_scale=(1.6, 0.6, 0.0)))
    snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
    assert any("spot light 'light' has its three axes in one plane" in w for w in snap.warnings), snap.warnings
    assert snap.lights[0].spot_linear is None


def test_spot_zero_z_scale_reach():
    """A spot with a zero Z scale lights only where Cycles' light tree still resolves its radius in float32
    (irradiance.cycles_radius_share): all of it within ~2800 radii, none beyond ~5800, a falling share
    between. r = 5e-4 m puts that band on the visible ground (1.4–2.9 m from the light)."""
    scene, cam, planes, lob = _build_scene("SPOT", dict(shadow_soft_size=5e-4, energy=150.0,
                                                        spot_size=math.radians(50)),
                                           dict(rotation=(0.3, 0.0, 0.0), scale=(1.0, 1.0, 0.0)))
    img = _render_combined(scene).mean(-1).ravel()
    ss = SUPERSAMPLE                                            # Cycles' box filter spans the pixel
    pos, nrm, ids = _pixel_geometry(cam, planes, W * ss, H * ss)
    hit = ~np.isnan(pos[:, 0])
    light = _light_from_object(lob)
    assert light.spot_axisless and light.power > 0.0
    e = np.zeros(len(pos))
    e[hit] = irradiance(light, pos[hit], nrm[hit]).mean(-1) / np.pi
    share = np.zeros(len(pos))
    share[hit] = cycles_radius_share(np.linalg.norm(pos[hit] - light.position, axis=1), light.radius, True)

    def per_pixel(a, how):
        return how(a.reshape(H, ss, W, ss), axis=(1, 3)).ravel()
    pred = per_pixel(e, np.mean)
    ids = ids.reshape(H, ss, W, ss)
    one_plane = (ids.min(axis=(1, 3)) == ids.max(axis=(1, 3))).ravel() & (ids.min(axis=(1, 3)) >= 0).ravel()
    bright = one_plane & (pred > 0.05 * pred.max())
    full = bright & (per_pixel(share, np.min) == 1.0)
    none = one_plane & (per_pixel(share, np.max) == 0.0)
    band = one_plane & ~full & ~none
    assert full.sum() > 150 and none.sum() > 150 and band.sum() > 150
    # whole share: as every other light (2 %); the ground beyond reach: dark, as the half-space model is not
    rel = np.abs(img[full] - pred[full]) / pred[full]
    assert rel.mean() < 0.02, f"mean relative error where the share is 1: {rel.mean():.4f}"
    assert np.all(img[none] < 0.02 * pred.max())
    # the band: measured Cycles/prediction 0.91 (bins of d: Cycles' share 5-25 % below ours towards the far
    # edge; its light tree tests more than the leaf's importance, e.g. the node's box, not modelled); the
    # half-space without the share gives 0.45 here
    ratio = img[band].sum() / pred[band].sum()
    print(f"band Cycles/prediction {ratio:.3f}")
    assert 0.85 < ratio < 1.02, f"Cycles/prediction over the band {ratio:.3f}"
    snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
    assert any("zero Z scale" in w for w in snap.warnings), snap.warnings
    gpu = np.flipud(pipeline.render(snap, RenderSettings(technique="HARD")).passes["Unshadowed"]).mean(-1).ravel()
    lit = full | band
    ratio_gpu = gpu[lit].sum() / pred[lit].sum()
    print(f"GPU/prediction {ratio_gpu:.4f}")
    assert abs(ratio_gpu - 1.0) < 0.02, f"GPU Unshadowed/prediction {ratio_gpu:.4f}"


# Lights Cycles renders no light from (measured: its image is exactly black), with the warning extraction gives.
DARK_CASES = {
    "area_zero_size": ("AREA", dict(shape="SQUARE", size=0.0, energy=100.0), {}, "has zero size"),
    "area_zero_x_scale": ("AREA", dict(shape="RECTANGLE", size=1.0, size_y=0.5, energy=100.0),
                          dict(scale=(0.0, 1.0, 1.0)), "has zero size"),
    "area_zero_z_scale": ("AREA", dict(shape="SQUARE", size=1.0, energy=100.0), dict(scale=(1.0, 1.0, 0.0)),
                          "zero Z scale"),
    "spot_zero_x_scale": ("SPOT", dict(shadow_soft_size=0.05, energy=150.0, spot_size=math.radians(90)),
                          dict(rotation=(0.3, 0.0, 0.0), scale=(0.0, 1.0, 1.0)), "zero X or Y scale"),
    "spot_zero_scale": ("SPOT", dict(shadow_soft_size=0.0, energy=150.0, spot_size=math.radians(70),
                                     spot_blend=0.3), dict(rotation=(0.6, 0.0, 0.0), scale=(0.0, 0.0, 0.0)),
                        "zero X or Y scale"),
    "spot_zero_z_scale_no_radius": ("SPOT", dict(shadow_soft_size=0.0, energy=150.0),
                                    dict(rotation=(0.3, 0.0, 0.0), scale=(1.0, 1.0, 0.0)), "no radius"),
    "sun_zero_z_scale": ("SUN", dict(angle=0.3, energy=3.0), dict(rotation=(0.5, 0.2, 0.0), scale=(1.0, 1.0, 0.0)),
                         "zero Z scale"),
}


@pytest.mark.parametrize("case", list(DARK_CASES))
def test_lights_cycles_renders_dark_render_dark(case):
    kind, light_props, obj_props, warning = DARK_CASES[case]
    scene, cam, planes, lob = _build_scene(kind, light_props, obj_props)
    scene.cycles.samples = 16          # black is black at any sample count
    img = _render_combined(scene)
    assert img.max() == 0.0, f"{case}: Cycles now renders light ({img.max()}): revisit extract.make_light"
    snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
    assert any(warning in w and "Cycles renders no light" in w for w in snap.warnings), snap.warnings
    result = pipeline.render(snap, RenderSettings(technique="HARD"))
    assert np.all(result.passes["Unshadowed"] == 0.0) and np.all(result.passes["Combined"][..., :3] == 0.0)


def test_irradiance_edge_cases_finite():
    """Receivers on the light, on its plane, behind it, at the sphere centre: finite, non-negative."""
    m = np.eye(4)
    m[:3, 3] = LIGHT_POS
    pts = np.array([LIGHT_POS, (0.2, 0.0, 1.2), (0.0, 0.0, 1.5), (0.0, 0.0, 0.0), (0.1, 0.0, 1.1)])
    nrm = np.array([(0, 0, 1.0), (0, 0, -1.0), (0, 0, 1.0), (0, 0, 1.0), (1.0, 0, 0)])
    lights = [Light("a", "AREA", m, np.ones(3), 10.0, shape=sh, size_x=0.5, size_y=0.3)
              for sh in ("SQUARE", "ELLIPSE")]
    lights += [Light("a0", "AREA", m, np.ones(3), 10.0, shape="SQUARE", size_x=0.0, size_y=0.0)]
    for r in (0.0, 0.2):
        for kind in ("POINT", "SPOT"):
            for soft in (True, False):
                light = Light(kind, kind, m, np.ones(3), 10.0, radius=r, spot_size=1.0, spot_blend=0.0)
                light.use_soft_falloff = soft
                lights.append(light)
    lights += [Light("sun", "SUN", m, np.ones(3), 2.0, angle=a) for a in (0.0, 0.5, math.pi)]
    for light in lights:
        e = irradiance(light, pts, nrm)
        assert e.shape == (len(pts), 3)
        assert np.all(np.isfinite(e)) and np.all(e >= 0.0), (light.kind, e)


def _leaning_plane_scene(lean_deg: float, suns, samples: int = 1024, view: float = 1.0):
    """A 4 m plane whose custom split normals lean by `lean_deg` about X from its face normal +Z (smooth shading,
    so Cycles shades with the leaning normal), under `suns` (angle, elevation°, azimuth°, strength); an
    orthographic camera sees `view` metres of the plane around the origin. Returns the scene, the shading
    normal and the sun objects."""
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    scene.render.engine = "CYCLES"
    c = scene.cycles
    c.device, c.samples, c.use_adaptive_sampling, c.use_denoising = "CPU", samples, False, False
    c.max_bounces, c.light_sampling_threshold, c.pixel_filter_type, c.filter_width, c.seed = 0, 0.0, "BOX", 1.0, 0
    scene.render.resolution_x = scene.render.resolution_y = 24
    scene.render.resolution_percentage = 100
    lean = math.radians(lean_deg)
    ns = (0.0, math.sin(lean), math.cos(lean))
    mesh = bpy.data.meshes.new("leaning")
    mesh.from_pydata([(-2, -2, 0), (2, -2, 0), (2, 2, 0), (-2, 2, 0)], [], [(0, 1, 2, 3)])
    mesh.polygons[0].use_smooth = True
    mesh.normals_split_custom_set([ns] * 4)
    ob = bpy.data.objects.new("leaning", mesh)
    scene.collection.objects.link(ob)
    ob.data.materials.append(_white_material())
    ob.visible_shadow = False
    cam = bpy.data.objects.new("cam", bpy.data.cameras.new("cam"))
    cam.data.type, cam.data.ortho_scale, cam.data.clip_start = "ORTHO", view, 0.01
    scene.collection.objects.link(cam)
    cam.location = (0.0, 0.0, 0.5)
    scene.camera = cam
    from mathutils import Vector
    obs = []
    for i, (angle, elevation, azimuth, strength) in enumerate(suns):
        data = bpy.data.lights.new(f"sun{i}", "SUN")
        data.angle, data.energy = angle, strength
        lob = bpy.data.objects.new(f"sun{i}", data)
        scene.collection.objects.link(lob)
        el, az = math.radians(elevation), math.radians(azimuth)
        toward = Vector((math.cos(el) * math.sin(az), -math.cos(el) * math.cos(az), math.sin(el)))
        lob.rotation_euler = toward.to_track_quat("Z", "Y").to_euler()
        obs.append(lob)
    bpy.context.view_layer.update()
    return scene, np.array([ns]), obs


# Wide suns over a surface whose smooth normal leans from its face (irradiance.band_loss): directions between
# the two horizons count at the light strategy's MIS weight only, and the light tree's pick among the suns
# (sharp ones too) sets that weight. Measured, Cycles 1024 spp (mean over the plane) / the model / the model
# without the weight: one 3 rad sun 0.9504 / 0.9502 / 0.9869; 3.1 rad, low 0.8455 / 0.8458 / 0.9655; two suns
# 2.9365 / 2.9360 / 3.0188; three suns, one sharp, 3.4797 / 3.4894 / 3.5584.
LEANING_CASES = {
    "one_sun_3rad": (40.0, [(3.0, 60.0, 180.0, 1.0)]),
    "one_sun_3.1rad_low": (60.0, [(3.1, 10.0, 180.0, 1.0)]),
    "two_suns": (40.0, [(3.0, 40.0, 180.0, 1.0), (2.0, 60.0, 90.0, 3.0)]),
    "three_suns_one_sharp": (40.0, [(1.0, 20.0, 180.0, 1.0), (1.4, 15.0, 160.0, 3.0), (0.0, 50.0, 0.0, 2.0)]),
}


@pytest.mark.parametrize("case", list(LEANING_CASES))
def test_wide_suns_over_leaning_smooth_normals(case):
    lean, suns = LEANING_CASES[case]
    scene, ns, obs = _leaning_plane_scene(lean, suns)
    measured = float(_render_combined(scene)[..., 0].mean()) * math.pi       # E = π·L_o for albedo 1
    lights = [_light_from_object(ob) for ob in obs]
    x, ng = np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]])
    model = sum(irradiance(lt, x, ns, ng, lights)[0, 0] for lt in lights)
    unweighted = sum(irradiance(lt, x, ns, None, lights)[0, 0] for lt in lights)
    print(f"{case}: Cycles {measured:.4f}, model {model:.4f}, without the band's weight {unweighted:.4f}")
    assert abs(model / measured - 1.0) < 0.004, f"{case}: model/Cycles {model / measured:.4f}"
    # End to end: the pipeline's Irradiance pass reads the G-buffer's geometric normal.
    snap = extract(bpy.context.evaluated_depsgraph_get(), scene)
    gpu = pipeline.render(snap, RenderSettings(technique="HARD", debug_passes=True)).passes["Irradiance"][..., 0]
    assert abs(float(gpu.mean()) / measured - 1.0) < 0.004, f"{case}: GPU/Cycles {gpu.mean() / measured:.4f}"


# The same band under local lights with a radius, each alone in the scene (picked with probability 1), seen
# over 2 cm around the origin: Cycles samples a soft-falloff disk by area (pdf ∝ 1/cos³ off its axis), a true
# sphere's cone uniformly from outside and the cosine hemisphere from inside, where the band keeps half.
# Measured, Cycles 2048 spp / the model / without the band's weight: soft disk 3.1425 / 3.1433 / 3.1823; sphere
# outside 6.0057 / 6.0058 / 6.2153, inside 7.4919 / 7.4923 / 7.9577; wider soft disk at 60° 0.8924 / 0.8928 /
# 0.9274; a 150° spot's true sphere 5.5013 / 5.5006 / 5.5313. Area lights: Cycles samples a rectangle over
# its solid angle, an ellipse by area; 3 × 1.8 m rectangle 10.8073 / 10.7935 / 10.8724, 2.5 m disk
# 14.5442 / 14.5579 / 15.2533.
LEANING_LOCAL_CASES = {
    "point_soft": (40.0, "POINT", (0.0, 1.0, 0.3), 1.0, True),
    "point_sphere_outside": (40.0, "POINT", (0.0, 1.0, 0.3), 1.0, False),
    "point_sphere_inside": (40.0, "POINT", (0.0, 0.3, 0.3), 1.0, False),
    "point_soft_wide": (60.0, "POINT", (0.0, 2.0, 0.5), 2.0, True),
    "spot_sphere": (40.0, "SPOT", (0.0, 1.0, 0.6), 0.8, False),
    # area lights, facing the origin (size: the rectangle's X side, Y = 0.6 X; the disk's diameter)
    "rectangle": (40.0, "RECTANGLE", (0.0, 0.8, 0.6), 3.0, False),
    "disk": (60.0, "DISK", (0.0, 0.6, 0.4), 2.5, False),
}


@pytest.mark.parametrize("case", list(LEANING_LOCAL_CASES))
def test_wide_local_lights_over_leaning_smooth_normals(case):
    lean, kind, location, radius, soft = LEANING_LOCAL_CASES[case]
    scene, ns, _ = _leaning_plane_scene(lean, [], samples=2048, view=0.02)
    scene.render.resolution_x = scene.render.resolution_y = 8
    data = bpy.data.lights.new("local", "AREA" if kind in ("RECTANGLE", "DISK") else kind)
    data.energy = 100.0
    if kind in ("RECTANGLE", "DISK"):
        data.shape, data.size, data.size_y = kind, radius, 0.6 * radius
    else:
        data.shadow_soft_size, data.use_soft_falloff = radius, soft
    if kind == "SPOT":
        data.spot_size, data.spot_blend = math.radians(150), 0.0
    lob = bpy.data.objects.new("local", data)
    scene.collection.objects.link(lob)
    lob.location, lob.visible_camera = location, False
    if kind != "POINT":
        from mathutils import Vector
        lob.rotation_euler = Vector(tuple(-np.array(location))).to_track_quat("-Z", "Y").to_euler()
    bpy.context.view_layer.update()
    measured = float(_render_combined(scene)[..., 0].mean()) * math.pi
    light = _light_from_object(lob)
    x, ng = np.zeros((1, 3)), np.array([[0.0, 0.0, 1.0]])
    model = irradiance(light, x, ns, ng)[0, 0]
    unweighted = irradiance(light, x, ns, None)[0, 0]
    from penumbra.engine.gpu.context import GpuWorker
    from penumbra.engine.gpu.probes import irradiance_at
    shader = GpuWorker.get().submit(irradiance_at, light, x, ns, ng).result()[0, 0]
    print(f"{case}: Cycles {measured:.4f}, model {model:.4f}, shader {shader:.4f}, without the band's weight "
          f"{unweighted:.4f}")
    assert abs(model / measured - 1.0) < 0.003, f"{case}: model/Cycles {model / measured:.4f}"
    assert abs(shader / measured - 1.0) < 0.003, f"{case}: shader/Cycles {shader / measured:.4f}"
    assert abs(unweighted / measured - 1.0) > 0.005      # the band matters here
