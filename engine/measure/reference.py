"""Cycles ground truth for shadow visibility.

`cycles_visibility(scene)` renders the scene twice with Cycles on the CPU, direct light only, every
surface replaced by a white Lambertian diffuse material and the world black:

  shadowed    the scene as is
  unshadowed  the same with every object's `visible_shadow` and `visible_diffuse` off (nothing blocks any
              light: Cycles also reaches lights by BSDF-sampled diffuse rays, weighted by MIS; under a 172°
              sun, casters hidden from shadow rays only still took 24 % of the unshadowed light)

and returns V_ref = L(shadowed) / L(unshadowed) (L = Rec. 709 luminance). Because the material is white
Lambertian and only direct light is traced, this ratio is the irradiance-weighted visibility
sum_i E_i V_i / sum_i E_i over all lights and all points of each light, which is what a soft-shadow
technique estimates. Both renders use the same seed, so their light samples coincide: the ratio is
then a ratio estimator over identical samples (much less noisy than two independent renders) and
never exceeds 1 except by float rounding.

A scene with two to PER_LIGHT_MAX lights is rendered one light at a time and summed (each light twice:
shadowed and unshadowed), as Cycles' light tree can give a degenerate light a tiny share of the samples (see
`_render_pair`).

`centre_lights=True` renders every light shrunk to its centre (`_shrink_lights`): the hard shadow of the light
centre, what a hard shadow-map technique estimates, as Cycles traces it.

Pixel filter: Cycles spreads each pixel's samples over a filter footprint around the pixel centre;
Penumbra shades one point per pixel, at its centre. The matching choice is a Gaussian filter of the
minimal width (0.01 px): every camera ray then passes (within 0.005 px) through the pixel centre, and
only the integral over the lights is estimated. BOX is not usable for this: Cycles forces its width to
1 px, which averages V over the pixel's area (measured: against an exact quadrature of a square light
over a square occluder at 1024 spp, mae_shadow 0.0004 with the narrow Gaussian, 0.0019 with BOX).
`filter_type`/`filter_width` can select an antialiased target instead.

Material: a Diffuse BSDF with roughness 0, which Cycles evaluates as pure Lambert (roughness > 0 turns
it into Oren-Nayar; Principled adds specular/sheen/coat lobes unless each is zeroed).

Arrays use row 0 = BOTTOM of the image (Blender/OpenGL convention, as `gpu` framebuffers read back);
EXR files store the top row first, so the rows are flipped on reading.

Results are cached on disk (`cache_dir`, default $PENUMBRA_CACHE/reference or
~/.cache/penumbra/reference) under a hash of everything that affects the two renders: evaluated
geometry, object matrices and shadow/camera visibility flags, lights, camera, resolution, samples,
seed, filter and the Blender version. The mask threshold is applied after loading, so changing it
never re-renders. The hash reads the view layer's (viewport-evaluated) depsgraph: a modifier whose
render and viewport settings differ is hashed as the viewport shows it.

Other settings held fixed during the renders (and restored after, also on error): CPU device, adaptive
sampling and denoising off, no animated seed, direct-light clamp off, light threshold 0, motion blur,
compositing and sequencer off, light emitters hidden from the camera, other view layers disabled.
"""
from __future__ import annotations

import hashlib
import os
import shutil
import tempfile
import threading
import time
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .metrics import compare, luminance
from ..blender.compat import SettingsRecorder, set_file_format

# Bump when the rendering method changes, so old cache entries are not reused.
CACHE_VERSION = 2     # 2: the unshadowed render hides casters from diffuse (MIS) rays too
# Gaussian filter width (pixels) that approximates point sampling at pixel centres; Blender's minimum.
POINT_FILTER_WIDTH = 0.01
# Default mask threshold, relative to the 99th percentile of the unshadowed luminance.
DEFAULT_THRESHOLD = 1e-3

# Scenes with up to this many lights are rendered one light at a time (_render_pair): the random scenes' 0-4
# lights. Each light's render costs about what the scene's does, so a user's scene with more lights keeps one.
PER_LIGHT_MAX = 4

# An area light's side when shrunk to its centre (`_shrink_lights`): a zero size makes Cycles drop the light,
# and its power does not depend on its size, so a tiny one keeps its light and its emission lobe.
CENTRE_AREA_SIZE = 1e-5

# Number of Cycles renders actually run in this process (cache hits do not count). Tests read it.
render_count = 0

# Set by a SIGINT handler (the command line's): Cycles renders from a Python callback and Blender swallows a
# KeyboardInterrupt raised there (it logs it and writes what was rendered), so every render is checked
# against this flag afterwards and an interrupted one is neither returned nor cached.
interrupted = threading.Event()


@dataclass
class ReferenceResult:
    """One Cycles reference. Images have row 0 = bottom of the frame.

    visibility  (H, W) float32 V_ref in [0, 1]; 1.0 where `mask` is False
    mask        (H, W) bool, pixels whose unshadowed luminance is above the threshold
    shadowed    (H, W, 3) float32 linear RGB, the normal direct-light render
    unshadowed  (H, W, 3) float32 linear RGB, the same with no shadow casters
    seconds     Cycles wall time of the two renders (of the original renders for a cache hit)
    shadowed_seconds  wall time of the shadowed render alone, the one a user's render would cost (None for
                cache entries written before it was recorded)
    centre_unknown  (H, W) float32, for a reference of the lights' centres (`centre_lights`): the share of the
                pixel's light that comes from lights whose centre lies below its horizon, on which the centre's
                shadow says nothing; `visibility` counts that share as shadowed (None otherwise)
    """

    visibility: np.ndarray
    mask: np.ndarray
    shadowed: np.ndarray
    unshadowed: np.ndarray
    seconds: float
    samples: int
    seed: int
    threshold: float = DEFAULT_THRESHOLD
    cached: bool = False
    key: str = ""
    shadowed_seconds: float | None = None
    centre_unknown: np.ndarray | None = None

    @property
    def shape(self) -> tuple[int, int]:
        return tuple(self.visibility.shape)


def default_cache_dir() -> Path:
    root = os.environ.get("PENUMBRA_CACHE")
    base = Path(root).expanduser() if root else Path.home() / ".cache" / "penumbra"
    return base / "reference"


def visibility_from(shadowed: np.ndarray, unshadowed: np.ndarray, threshold: float = DEFAULT_THRESHOLD):
    """(visibility, mask) from the two renders. `threshold` is relative: a pixel is in the mask when its
    unshadowed luminance exceeds `threshold` times the 99th percentile of the unshadowed luminance
    (and is strictly positive). V is clipped to [0, 1] and set to 1 outside the mask."""
    ls = luminance(shadowed)
    lu = luminance(unshadowed)
    finite = np.isfinite(ls) & np.isfinite(lu)
    pos = lu[finite & (lu > 0)]
    level = float(np.percentile(pos, 99)) * threshold if pos.size else np.inf
    mask = finite & (lu > 0) & (lu > level)
    vis = np.ones(lu.shape, dtype=np.float64)
    vis[mask] = np.clip(ls[mask] / lu[mask], 0.0, 1.0)
    return vis.astype(np.float32), mask


# ----------------------------------------------------------------------------------------------------
# Scene hashing


_SKIP_PROPS = {"rna_type", "name", "name_full", "session_uid", "users", "use_fake_user", "use_extra_user",
               "tag", "is_evaluated", "is_embedded_data", "is_linked_packed", "is_missing",
               "is_runtime_data", "is_editable", "is_library_indirect", "id_type", "display_size",
               "passepartout_alpha", "composition_guide_color", "custom_bytecode_hash"}


def _rna_values(struct) -> list:
    """Plain (float/int/bool/enum/string) RNA properties of a datablock, for hashing. Pointers,
    collections and viewport-display settings are skipped."""
    out = []
    for prop in struct.bl_rna.properties:
        ident = prop.identifier
        if ident in _SKIP_PROPS or ident.startswith("show_") or prop.type in ("POINTER", "COLLECTION"):
            continue
        try:
            val = getattr(struct, ident)
        except Exception:
            continue
        if isinstance(val, set):
            val = tuple(sorted(val))
        elif hasattr(val, "__len__") and not isinstance(val, str):
            val = tuple(val)
        out.append((ident, val))
    return out


def _mesh_digest(mesh) -> bytes:
    h = hashlib.sha1()
    nv, nl, npoly = len(mesh.vertices), len(mesh.loops), len(mesh.polygons)
    h.update(np.array([nv, nl, npoly], np.int64).tobytes())
    co = np.empty(nv * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    h.update(co.tobytes())
    li = np.empty(nl, np.int32)
    mesh.loops.foreach_get("vertex_index", li)
    h.update(li.tobytes())
    tot = np.empty(npoly, np.int32)
    mesh.polygons.foreach_get("loop_total", tot)
    h.update(tot.tobytes())
    smooth = np.empty(npoly, bool)
    mesh.polygons.foreach_get("use_smooth", smooth)
    h.update(smooth.tobytes())
    return h.digest()


def scene_key(scene, *, samples: int, seed: int, width: int, height: int, filter_width: float,
              filter_type: str = "GAUSSIAN", view_layer=None, per_light: bool = False,
              centre_lights: bool = False) -> str:
    """Hex digest of everything that changes the two reference renders."""
    import bpy

    view_layer = view_layer or _pick_view_layer(scene)
    depsgraph = view_layer.depsgraph
    depsgraph.update()
    h = hashlib.sha256()

    def put(*items):
        h.update(repr(items).encode())

    put("penumbra-reference", CACHE_VERSION, bpy.app.version_string, int(samples), int(seed),
        int(width), int(height), str(filter_type), round(float(filter_width), 6))
    put("pixel_aspect", scene.render.pixel_aspect_x, scene.render.pixel_aspect_y)
    if _lights_alone(scene, view_layer, per_light, centre_lights):
        put("per-light")        # one light's key is the same either way
    if centre_lights:
        put("centre-lights", CENTRE_AREA_SIZE, 3)

    mesh_cache: dict[str, bytes] = {}
    records = []
    for inst in depsgraph.object_instances:
        ob = inst.object
        orig = ob.original
        mat = np.array(inst.matrix_world, dtype=np.float64).tobytes()
        flags = (orig.name, ob.type, bool(orig.visible_shadow), bool(orig.visible_camera),
                 bool(orig.hide_render))
        if ob.type == "LIGHT":
            records.append((b"L", repr((flags, _rna_values(ob.data), _rna_values(ob.data.cycles)
                                        if hasattr(ob.data, "cycles") else None)).encode(), mat))
        elif ob.type in ("MESH", "CURVE", "SURFACE", "META", "FONT"):
            dkey = f"{ob.type}:{ob.data.name if ob.data else ob.name}:{ob.name}"
            digest = mesh_cache.get(dkey)
            if digest is None:
                if ob.type == "MESH":
                    digest = _mesh_digest(ob.data)
                else:
                    me = ob.to_mesh()
                    try:
                        digest = _mesh_digest(me) if me is not None else b""
                    finally:
                        ob.to_mesh_clear()
                mesh_cache[dkey] = digest
            records.append((b"M", repr(flags).encode() + digest, mat))
        elif ob.type in ("CURVES", "POINTCLOUD", "VOLUME"):
            records.append((b"O", repr(flags).encode(), mat))
    for tag, payload, mat in sorted(records):
        h.update(tag)
        h.update(payload)
        h.update(mat)

    cam = scene.camera
    if cam is None:
        raise ValueError(f"scene {scene.name!r} has no camera")
    cam_eval = cam.evaluated_get(depsgraph)
    put("camera", _rna_values(cam_eval.data))
    h.update(np.array(cam_eval.matrix_world, dtype=np.float64).tobytes())
    return h.hexdigest()


# ----------------------------------------------------------------------------------------------------
# Rendering


# Scene-settings recorder (undone in reverse, also after an error), shared with the blender layer.
_Settings = SettingsRecorder


def _pick_view_layer(scene):
    import bpy

    ctx_layer = getattr(bpy.context, "view_layer", None)
    if bpy.context.scene == scene and ctx_layer is not None:
        return ctx_layer
    for layer in scene.view_layers:
        if layer.use:
            return layer
    return scene.view_layers[0]


def _make_material():
    import bpy

    mat = bpy.data.materials.new("penumbra_reference_white")
    nodes = mat.node_tree.nodes
    nodes.clear()
    bsdf = nodes.new("ShaderNodeBsdfDiffuse")
    bsdf.inputs["Color"].default_value = (1.0, 1.0, 1.0, 1.0)
    bsdf.inputs["Roughness"].default_value = 0.0  # 0 = Lambert; > 0 would be Oren-Nayar
    out = nodes.new("ShaderNodeOutputMaterial")
    out.target = "ALL"
    mat.node_tree.links.new(bsdf.outputs["BSDF"], out.inputs["Surface"])
    return mat


def read_exr_combined(path: str) -> np.ndarray:
    """(H, W, 3) float32 RGB of the Combined pass in an EXR Blender wrote, row 0 = bottom. Measurement renders
    write a single view layer (set_measurement_output), so the pass name alone identifies it."""
    from ..core.exr import read
    passes = read(str(path))
    if "Combined" not in passes:
        raise RuntimeError(f"no Combined pass in {path} (passes: {sorted(passes)})")
    return np.ascontiguousarray(passes["Combined"][..., :3])


def set_measurement_output(st: "_Settings", scene, world, material, view_layer, width: int, height: int):
    """Scene settings every measurement render shares (Cycles reference, EEVEE peer): black world, white
    Lambert override, exact resolution, nothing but the one view layer, 32-bit multilayer EXR output.
    Every change goes through `st`, so it is undone afterwards."""
    r = scene.render
    st.set(scene, "world", world)
    st.set(r, "resolution_x", int(width))
    st.set(r, "resolution_y", int(height))
    st.set(r, "resolution_percentage", 100)
    st.set(r, "use_border", False)
    st.set(r, "use_motion_blur", False)
    st.set(r, "use_compositing", False)
    st.set(r, "use_sequencer", False)
    st.set(r, "film_transparent", False)
    st.set(r, "use_file_extension", True)
    st.set(r, "use_single_layer", True)
    img = r.image_settings
    set_file_format(st, img, "OPEN_EXR_MULTILAYER")      # media_type first where Blender has one (5.0)
    st.set(img, "color_depth", "32")
    st.set(img, "exr_codec", "ZIP")
    for layer in scene.view_layers:
        if layer != view_layer and layer.use:
            st.set(layer, "use", False)
    st.set(view_layer, "use", True)
    st.set(view_layer, "material_override", material)


@contextmanager
def measurement_scene(scene, view_layer, width: int, height: int, prefix: str, *, white: bool = True):
    """Set `scene` up for a measurement render (black world, white Lambert override unless `white` is False,
    exact resolution, one view layer, 32-bit multilayer EXR) and yield (settings recorder, temp folder). On
    exit every setting is restored and the temporary material, world and files are removed, also on error."""
    import bpy

    from .scenes import black_world
    st = _Settings()
    temp_ids = []
    tmpdir = tempfile.mkdtemp(prefix=prefix)
    try:
        mat = _make_material() if white else None
        if mat is not None:
            temp_ids.append(("materials", mat))
        world = black_world(prefix + "black")
        temp_ids.append(("worlds", world))
        set_measurement_output(st, scene, world, mat, view_layer, width, height)
        yield st, tmpdir
    finally:
        try:
            st.restore()
        finally:
            for coll, idb in temp_ids:
                try:
                    getattr(bpy.data, coll).remove(idb)
                except Exception:
                    pass
            shutil.rmtree(tmpdir, ignore_errors=True)


def _render_still(st, scene, view_layer, path: str) -> np.ndarray:
    """Render `view_layer` to the EXR `path` (through `st`) and read its Combined back."""
    import bpy

    global render_count
    st.set(scene.render, "filepath", path)
    bpy.ops.render.render(write_still=True, scene=scene.name, layer=view_layer.name)
    if interrupted.is_set():
        raise KeyboardInterrupt("Cycles render interrupted")
    render_count += 1
    if not os.path.exists(path):
        raise RuntimeError(f"Cycles wrote no image to {path}")
    return read_exr_combined(path)


def _render_lights(scene, view_layer) -> list:
    """The light objects a render of `view_layer` may include, each of which hide_render can take out alone;
    empty where some light cannot be (one instanced by a collection instance or a particle system), as a
    light the list misses would be counted in every light's render. A light the viewport hides still renders,
    so it is listed (a listed light that does not render only costs an empty render)."""
    lights = [ob for ob in view_layer.objects if ob.type == "LIGHT" and not ob.hide_render]
    names = {ob.name for ob in lights}
    depsgraph = view_layer.depsgraph
    depsgraph.update()
    for inst in depsgraph.object_instances:
        if inst.object.type == "LIGHT" and (inst.is_instance or inst.object.original.name not in names):
            return []
    return lights


def _lights_alone(scene, view_layer, per_light: bool, centre_lights: bool) -> list:
    """The lights `_render_pair` renders one at a time: with `per_light`, two to PER_LIGHT_MAX of them
    (_render_lights), else none; with `centre_lights`, two or more whatever their number, as each light's
    centre visibility is weighted by that light's own light (a few samples each: the cost stays low)."""
    lights = _render_lights(scene, view_layer) if per_light or centre_lights else []
    most = len(lights) if centre_lights else PER_LIGHT_MAX
    return lights if 1 < len(lights) <= most else []


def _shrink_lights(st, scene) -> None:
    """Every light of `scene` shrunk to its centre, through `st`: point and spot radii and sun angles 0, area
    lights CENTRE_AREA_SIZE across (one of zero size stays so: Cycles renders no light for it either way). Power,
    direction, cone and transform are kept, so each light's share of a pixel's light stays about the same."""
    for ob in scene.objects:
        if ob.type != "LIGHT":
            continue
        light = ob.data
        if light.type in ("POINT", "SPOT") and light.shadow_soft_size != 0.0:
            st.set(light, "shadow_soft_size", 0.0)
        elif light.type == "SUN" and light.angle != 0.0:
            st.set(light, "angle", 0.0)
        elif light.type == "AREA":
            for attr in ("size", "size_y"):
                if getattr(light, attr) > CENTRE_AREA_SIZE:
                    st.set(light, attr, CENTRE_AREA_SIZE)


def _hide_casters(st, scene) -> None:
    """Every object but the lights hidden from shadow rays and from diffuse rays, through `st`: Cycles also
    reaches a light by BSDF-sampled rays (MIS), which are diffuse rays, not shadow rays, so an object left
    visible to those still blocks the light."""
    for ob in scene.objects:
        if ob.type == "LIGHT":
            continue
        for attr in ("visible_shadow", "visible_diffuse"):
            if getattr(ob, attr):
                st.set(ob, attr, False)


def _render_pair(scene, *, samples, seed, width, height, filter_type, filter_width, view_layer,
                 per_light: bool = False, centre_lights: bool = False):
    """Render shadowed and unshadowed images; returns (shadowed, unshadowed, [seconds of each]).

    `per_light`: render each light alone and sum (direct light is linear in the lights). Cycles picks one
    light per sample by its light tree's importance estimate, and where that estimate is degenerate the
    light's share arrives in rare, heavily weighted samples: a spot with a zero Z scale beside another light
    (fuzz seeds 26029, 27032) is picked so seldom that at 1024 spp some pixels hold none of its light and
    others several times it, while each light alone converges (its pick probability is 1).

    `centre_lights`: every light shrunk to its centre (`_shrink_lights`), each light's centre visibility
    weighted by the light's own unshadowed light, as a hard technique weights its lights (a 46 m area light
    shrunk to a point lights a pixel very differently). The shadowed image is then sum_i U_i V_i and the
    unshadowed sum_i U_i (U_i the light as it is, V_i its centre's visibility, each light alone), and a fourth
    value holds the light of the lights whose centre lies below the pixel's horizon (no V_i: counted shadowed
    in the first image). Otherwise the fourth value is None."""
    lights = _lights_alone(scene, view_layer, per_light, centre_lights)
    with measurement_scene(scene, view_layer, width, height, "penumbra_ref_") as (st, tmpdir):
        _cycles_direct_light(st, scene, samples, seed, filter_type, filter_width)

        def render(name: str) -> np.ndarray:
            return _render_still(st, scene, view_layer, os.path.join(tmpdir, f"{name}.exr"))

        def each_light(name: str) -> list:
            """One render per light of `lights` (the others hidden, then all shown again); one render of them
            all where `lights` is empty."""
            if not lights:
                return [render(name)]
            images = []
            for i, alone in enumerate(lights):
                for ob in lights:
                    if ob.hide_render != (ob is not alone):
                        st.set(ob, "hide_render", ob is not alone)
                images.append(render(f"{name}_{i}"))
            for ob in lights:
                if ob.hide_render:
                    st.set(ob, "hide_render", False)
            return images

        if centre_lights:
            hidden = _Settings()
            try:
                _hide_casters(hidden, scene)
                weights = each_light("weight")
            finally:
                hidden.restore()
            _shrink_lights(st, scene)
            t1 = time.perf_counter()
            shadowed = each_light("shadowed")
            seconds = [time.perf_counter() - t1]
            _hide_casters(st, scene)
            t1 = time.perf_counter()
            unshadowed = each_light("unshadowed")
            seconds.append(time.perf_counter() - t1)
            lit, unknown = 0.0, 0.0
            for w, a, b in zip(weights, shadowed, unshadowed):
                # every pixel the centre reaches at all: a light faint beside its own brightest pixels may
                # still carry much of a pixel's light beside the other lights
                v, reached = visibility_from(a, b, threshold=0.0)
                lit = lit + w * (v * reached)[..., None]
                unknown = unknown + w * (~reached)[..., None]
            return lit, sum(weights), seconds, unknown

        images = []
        seconds = []
        for unshadowed in (False, True):
            if unshadowed:
                _hide_casters(st, scene)
            t0 = time.perf_counter()
            images.append(sum(each_light("unshadowed" if unshadowed else "shadowed")))
            seconds.append(time.perf_counter() - t0)
        return images[0], images[1], seconds, None


def _cycles_direct_light(st, scene, samples, seed, filter_type, filter_width):
    """Cycles settings of every reference render (through `st`, so they are undone): CPU, fixed samples and
    seed, direct light only, no clamping or light threshold, the given pixel filter, lights unseen."""
    cy = scene.cycles
    st.set(scene.render, "engine", "CYCLES")
    st.set(cy, "device", "CPU")
    st.set(cy, "samples", int(samples))
    st.set(cy, "use_adaptive_sampling", False)
    st.set(cy, "use_denoising", False)
    st.set(cy, "seed", int(seed))
    st.set(cy, "use_animated_seed", False)
    st.set(cy, "max_bounces", 0)
    st.set(cy, "sample_clamp_direct", 0.0)
    st.set(cy, "light_sampling_threshold", 0.0)
    # Cycles ignores filter_width for BOX (always 1 px), so a narrow Gaussian is the point sampler.
    st.set(cy, "pixel_filter_type", filter_type)
    st.set(cy, "filter_width", float(filter_width))
    for ob in scene.objects:
        if ob.type == "LIGHT" and ob.visible_camera:
            st.set(ob, "visible_camera", False)  # the light's own emitter must not appear in the image


def cycles_combined(scene=None, *, samples: int = 256, seed: int = 0, width: int, height: int,
                    filter_type: str = "GAUSSIAN", filter_width: float = POINT_FILTER_WIDTH,
                    view_layer=None) -> np.ndarray:
    """Cycles' Combined (H, W, 3), row 0 = bottom, of `scene` with its own materials (textures included), direct
    light only and the reference's other settings: what Penumbra's Combined estimates. Not cached (the cache
    key does not cover materials and images)."""
    import bpy

    scene = scene or bpy.context.scene
    view_layer = view_layer or _pick_view_layer(scene)
    with measurement_scene(scene, view_layer, width, height, "penumbra_rgb_", white=False) as (st, tmpdir):
        _cycles_direct_light(st, scene, samples, seed, filter_type, filter_width)
        return _render_still(st, scene, view_layer, os.path.join(tmpdir, "combined.exr"))


def cycles_visibility(scene=None, *, samples: int = 256, seed: int = 0, width: int | None = None,
                      height: int | None = None, cache_dir=None, threshold: float = DEFAULT_THRESHOLD,
                      filter_type: str = "GAUSSIAN", filter_width: float = POINT_FILTER_WIDTH,
                      use_cache: bool = True,
                      view_layer=None, per_light: bool = True, centre_lights: bool = False) -> ReferenceResult:
    """Cycles reference visibility of `scene` (default: the context scene). See the module docstring.

    width/height default to the scene's resolution (percentage applied). `threshold` is relative to the
    99th percentile of the unshadowed luminance (see `visibility_from`). `use_cache=False` always
    renders (and does not write the cache). Every scene setting changed is restored afterwards, also on
    error. `per_light` (the reference's default) renders each of several lights alone and sums them (see
    `_render_pair`); peers that stand for a user's Cycles render at some sample count pass False.
    `centre_lights`: every light shrunk to its centre (`_shrink_lights`), the hard techniques' target.
    """
    import bpy

    scene = scene or bpy.context.scene
    view_layer = view_layer or _pick_view_layer(scene)
    if width is None or height is None:
        pct = scene.render.resolution_percentage / 100.0
        width = width or max(1, int(scene.render.resolution_x * pct))
        height = height or max(1, int(scene.render.resolution_y * pct))

    if filter_type == "BOX":
        filter_width = 1.0  # what Cycles uses for BOX whatever the setting says
    key = scene_key(scene, samples=samples, seed=seed, width=width, height=height,
                    filter_type=filter_type, filter_width=filter_width, view_layer=view_layer,
                    per_light=per_light, centre_lights=centre_lights)
    cdir = Path(cache_dir).expanduser() if cache_dir is not None else default_cache_dir()
    path = cdir / f"{key[:40]}.npz"
    if use_cache and path.exists():
        try:
            with np.load(path) as data:
                shadowed, unshadowed = data["shadowed"], data["unshadowed"]
                seconds = float(data["seconds"])
                one = float(data["shadowed_seconds"]) if "shadowed_seconds" in data.files else None
                unknown = data["centre_unknown"] if "centre_unknown" in data.files else None
            vis, mask = visibility_from(shadowed, unshadowed, threshold)
            return ReferenceResult(vis, mask, shadowed, unshadowed, seconds, int(samples), int(seed),
                                   threshold, cached=True, key=key, shadowed_seconds=one,
                                   centre_unknown=_unknown_share(unknown, unshadowed))
        except Exception:
            pass  # unreadable entry: render again and overwrite it

    shadowed, unshadowed, each, unknown = _render_pair(scene, samples=samples, seed=seed, width=width,
                                                 height=height, filter_type=filter_type,
                                                 filter_width=filter_width,
                                                 view_layer=view_layer, per_light=per_light,
                                                 centre_lights=centre_lights)
    if use_cache:
        cdir.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f"{path.stem}.{os.getpid()}.tmp.npz")
        np.savez_compressed(tmp, shadowed=shadowed, unshadowed=unshadowed, seconds=np.float64(sum(each)),
                            shadowed_seconds=np.float64(each[0]), samples=np.int64(samples), seed=np.int64(seed),
                            **({} if unknown is None else {"centre_unknown": unknown}))
        os.replace(tmp, path)  # atomic: concurrent readers never see a partial file
    vis, mask = visibility_from(shadowed, unshadowed, threshold)
    return ReferenceResult(vis, mask, shadowed, unshadowed, float(sum(each)), int(samples), int(seed),
                           threshold, cached=False, key=key, shadowed_seconds=each[0],
                           centre_unknown=_unknown_share(unknown, unshadowed))


def _unknown_share(unknown, unshadowed):
    """The luminance share of `unshadowed` in the image `unknown` (None stays None)."""
    if unknown is None:
        return None
    total = luminance(unshadowed)
    part = luminance(unknown)
    return np.where(total > 0.0, np.clip(part / np.where(total > 0.0, total, 1.0), 0.0, 1.0), 0.0).astype(np.float32)


def noise_floor(scene=None, samples: int = 256, *, seeds: tuple[int, int] = (0, 1), **kwargs) -> dict:
    """The reference's own noise: `metrics.compare` between two Cycles renders that differ only in seed
    (the first seed's render plays the reference), over the pixels both masks keep. Extra keyword
    arguments go to `cycles_visibility`. Adds `seconds` (Cycles time of both references) to the dict."""
    a = cycles_visibility(scene, samples=samples, seed=seeds[0], **kwargs)
    b = cycles_visibility(scene, samples=samples, seed=seeds[1], **kwargs)
    out = compare(b.visibility, a.visibility, a.mask & b.mask)
    out["seconds"] = a.seconds + b.seconds
    out["samples"] = int(samples)
    return out
