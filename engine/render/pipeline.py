"""One frame, end to end on the GPU thread: G-buffer → per light (irradiance, light view, the structures the
technique declares, visibility) → shading sums → passes as numpy arrays.

Work a scene does not need is left out: a light that reaches no visible pixel is skipped before any shadow
map exists, a light that casts no shadow (or a scene with no casters) gets V = 1 without a map, and only the
structures the chosen technique declares are built.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core import lightview, passes
from ..gpu.context import GpuWorker, Job
from ..gpu.frame import Frame
from ..gpu.geometry import SceneGeometry
from ..gpu.multisample import shade_edges
from ..core.settings import RenderSettings
from ..core.light_shape import light_half_extent
from ..core.shading import light_defines, light_uniforms
from ..core.snapshot import AREA, SUN, SceneSnapshot
from ..techniques import TECHNIQUES, get as get_technique  # noqa: F401  (TECHNIQUES: the layers above list them here)
from .. import structures
from ..techniques.base import LightContext

BACKGROUND_DEPTH = 1.0e10   # Blender's Depth pass value where nothing was hit


@dataclass
class FrameResult:
    passes: dict            # pass name → (H, W, C) float32, row 0 at the bottom
    timings: dict           # stage → milliseconds
    warnings: list = field(default_factory=list)
    stats: dict = field(default_factory=dict)

    @property
    def total_ms(self) -> float:
        return float(sum(self.timings.values()))


class Progress:
    """Splits the frame's progress between lights; techniques report their own fraction of one light."""

    def __init__(self, job: Job, lights: int):
        self.job, self.lights, self.index = job, max(lights, 1), 0

    def step(self, fraction: float, message: str = "") -> None:
        self.job.progress((self.index + min(max(fraction, 0.0), 1.0)) / self.lights, message)

    def check(self) -> None:
        self.job.check()


def render(snap: SceneSnapshot, settings: RenderSettings, *, on_progress=None, should_stop=None,
           worker: GpuWorker | None = None, stage_times: bool = False) -> FrameResult:
    """Render one frame on the GPU thread; blocks this thread, forwarding progress and cancellation.
    `stage_times`: synchronise the GPU after every timed stage so FrameResult.timings are true per-stage
    times (the bench); otherwise the GPU runs ahead and waits only where a result is read back."""
    settings.validate()
    worker = worker or GpuWorker.get()
    return worker.run(render_job, snap, settings, on_progress=on_progress, should_stop=should_stop,
                      stage_times=stage_times)


def render_job(worker, job: Job, snap: SceneSnapshot, settings: RenderSettings,
               geometry: SceneGeometry | None = None, stage_times: bool = False) -> FrameResult:
    job.check()
    technique = get_technique(settings.technique)
    frame = Frame(worker, snap, settings, geometry, stage_times=stage_times)
    try:
        frame.progress = Progress(job, len(snap.lights))
        offset, mixed = snap.terminator_offset()
        if mixed:
            frame.warn(mixed)
        frame.bias_uniforms = {"u_bias": float(settings.bias), "u_normal_offset": float(settings.normal_offset),
                               "u_terminator_offset": offset}
        result = _render_lights(frame, technique)
    finally:
        frame.release()
    return result


def _render_lights(frame: Frame, technique) -> FrameResult:
    snap, settings, t = frame.snap, frame.settings, frame.timings
    size = (frame.width, frame.height)
    combined, unshadowed, irradiance_sum = frame.texture(size, 4), frame.texture(size, 4), frame.texture(size, 4)
    sums = frame.texture(size, 2)       # all four zero-filled (Frame.texture)
    irradiance, visibility = frame.texture(size, 4), frame.texture(size, 1)
    ones = np.ones((frame.height, frame.width), np.float32).tobytes()
    zeros = bytes(len(ones))

    with t.stage("readback"):
        position = frame.read(frame.gbuffer["g_position"])
    normals = {}        # g_normal, g_geometric: read back once per frame, when a light first needs them

    def gbuffer_array(name: str) -> np.ndarray:
        if name not in normals:
            with t.stage("readback"):
                normals[name] = frame.read(frame.gbuffer[name])
        return normals[name]
    covered = position[..., 3] > 0.0
    bounds_buffer = frame.buffer(_BOUNDS_RESET)
    caster_objects = np.array([o.caster for o in snap.objects], bool)
    caster_indices = np.flatnonzero(caster_objects)
    object_bounds = frame.geometry.object_bounds()
    has_casters = frame.geometry.has_casters
    # Where the visible pixels lie against flat and convex casters, once per frame (lightview.receiver_sides)
    frame.receiver_sides = sides = lightview.receiver_sides(
        snap.lights, frame.geometry.flat_objects(), frame.geometry.convex_objects(), position[..., :3], covered)
    sheet_light = _sheet_light(frame, frame.geometry.coincident_sheets(), position, covered)
    debug: dict = {}
    stats = {"lights": len(snap.lights), "lights_skipped": 0, "lights_unshadowed": 0, "lights_enclosed": 0,
             "covered_pixels": int(covered.sum()), "technique": technique.identifier}
    if not snap.lights:
        frame.warn(f"Scene '{snap.name}' has no lights: Combined is black and Visibility is 1.")
    if not has_casters and snap.lights:
        frame.warn(f"Scene '{snap.name}' has no shadow casters: every light is unshadowed.")

    for index, light in enumerate(snap.lights):
        frame.progress.index = index
        frame.progress.step(0.0, f"{light.name}: irradiance")
        frame.progress.check()
        with t.stage("irradiance"):
            frame.dispatch("shading/irradiance.comp", light_uniforms(light, snap.lights), images={0: irradiance},
                           defines=light_defines(light))
        # Only an emitter with an extent can light what its centre does not reach (lightview.sun_rim_faces,
        # local_rim_lights): count such pixels on the GPU, for the techniques that take rim views
        rim = technique.rim_views and not light.is_delta
        centre = (*(-light.direction), 0.0) if light.kind == SUN else (*light.position, 1.0)
        with t.stage("readback"):
            receivers, hidden, nearest = _lit_bounds(frame, irradiance, bounds_buffer, centre, count_hidden=rim)
        if receivers is None:
            stats["lights_skipped"] += 1        # reaches no visible pixel: nothing to build
            continue
        casters = shell = None
        if light.casts_shadow and has_casters:
            # A closed caster with the camera on one side and the light on the other (a shell around the
            # camera lit from outside, a lamp in a closed box seen from outside): every path from a visible
            # receiver to the light crosses it, so nothing is lit, whatever the light's size. Decided here for
            # every technique: from inside, a wide light's rays leave through the shell's half turned away
            # from the light, which a map from the light holds in no single layer.
            shell = lightview.enclosing_shell(snap, light, caster_indices, bounds=object_bounds)
            if shell is None:
                casters = lightview.shadowing_caster_bounds(light, object_bounds, caster_objects, receivers, sides)
        rgb = None
        if shell is not None:
            visibility.write(zeros)             # walled off from every visible receiver
            stats["lights_enclosed"] += 1
        elif casters is None:
            visibility.write(ones)              # nothing can shadow what this light reaches
            stats["lights_unshadowed"] += 1
        else:
            with t.stage("light_view"):
                view = lightview.fit(light, receivers, casters, settings.shadow_map_size)
                parts = lit_xyz = lifted = None
                # Only a clamped view can leave lit pixels outside, and only pixels with the light's centre
                # below their horizon need rim views: read the lit pixels back then; and on smooth triangles
                # for a technique whose sample views must hold the lifted shadow-ray starts.
                samples_lift = technique.fits_sample_views and frame.geometry.has_smooth
                if view.clamped or hidden or samples_lift:
                    lit = (frame.read(irradiance)[..., 3] > 0.0) & covered
                    lit_xyz = position[lit][:, :3]
                    normal, geometric = gbuffer_array("g_normal")[lit], gbuffer_array("g_geometric")[lit]
                    lifted = _lifted_points(normal, geometric, lit_xyz) \
                        if view.clamped or samples_lift or (hidden and light.kind != SUN) else None
                    if view.clamped:
                        # The lit points bound the window tighter than their box, whose corners can straddle
                        # the light's plane where no lit point does (fuzz 8217: a tilted light over a floor)
                        view = lightview.fit(light, receivers, casters, settings.shadow_map_size,
                                             receiver_points=_with_lifted(lit_xyz, lifted))
                    parts = _view_parts(light, view, lit_xyz, lifted, normal, geometric, rim=hidden > 0)
            if parts is None:
                points = None if lit_xyz is None else _with_lifted(lit_xyz, lifted)
                rgb = _view_visibility(frame, technique, light, view, irradiance, receivers, casters, visibility,
                                       stats, debug, points=points, nearest=nearest)
            else:
                rgb = _face_visibility(frame, technique, light, view, receivers, casters, parts, lit, lit_xyz,
                                       lifted, geometric[:, :3], irradiance, object_bounds, caster_objects,
                                       visibility, stats, debug)
        with t.stage("accumulate"):
            sheets = casters is not None and sheet_light is not None       # a light whose shadows count
            samplers = {"g_irradiance": irradiance, "u_visibility": visibility,
                        "u_visibility_rgb": rgb if rgb is not None else visibility,
                        "u_sheet_light": sheet_light if sheets else visibility}
            images = {0: combined, 1: unshadowed, 2: sums, 3: irradiance_sum}
            frame.dispatch("shading/accumulate.comp", {"u_has_rgb": int(rgb is not None), "u_sheets": int(sheets)},
                           samplers=samplers, images=images)
            if frame.msaa_edges is not None:    # anti-aliased: every sample of the edge pixels shaded (§7)
                shade_edges(frame, light, settings.aa_depth_threshold, samplers, images, has_rgb=rgb is not None,
                            sheets=sheets)
        frame.end_light()                   # per-light structures (an MSSM) go before the next light
        frame.progress.step(1.0, f"{light.name}: done")

    with t.stage("readback"):
        out = _finish(frame, combined, unshadowed, sums, irradiance_sum, covered, debug)
    for name, value in frame.stats.items():
        stats[name] = stats.get(name, 0) + value
    return FrameResult(out, dict(t), frame.warnings, stats)


def _sheet_light(frame: Frame, sheets: dict, position: np.ndarray, covered: np.ndarray):
    """The share of a shadowed light each pixel keeps where it lies on a flattened closed caster, which Cycles
    shadows through its own coincident faces (SceneSnapshot.coincident_sheets: none, or half where the
    plane's coordinate is not one float), as an R32F texture; None when no pixel lies on one. A pixel is on
    it when it lies on the caster's plane within its bounds, to 1e-5 of their size."""
    if not sheets:
        return None
    p = position[..., :3].astype(np.float64)
    keep = np.ones(covered.shape, np.float32)
    for normal, offset, (lo, hi), share in sheets.values():
        tol = 1e-5 * max(1.0, abs(offset), float(np.max(hi - lo)))
        on = covered & (np.abs(p @ normal - offset) <= tol) & np.all((p >= lo - tol) & (p <= hi + tol), axis=-1)
        keep[on] *= 1.0 - share
    if np.all(keep == 1.0):
        return None
    texture = frame.texture((frame.width, frame.height), 1)
    texture.write(keep.tobytes())
    return texture


_BOUNDS_BYTES = 36     # render/lit_bounds.comp: a count, encoded min and max xyz, the hidden count, the nearest
_BOUNDS_RESET = np.array([0] + [0xFFFFFFFF] * 3 + [0] * 3 + [0, 0xFFFFFFFF], np.uint32).tobytes()


def _lit_bounds(frame: Frame, irradiance, buffer, centre, count_hidden: bool = False):
    """Reduced on the GPU (render/lit_bounds.comp), so only 36 bytes are read back: the world box (lo, hi) of
    the covered pixels this light reaches and of their shadow rays' starts lifted off smooth triangles (exactly
    their float32 min and max), or None if it reaches none; with `count_hidden`, how many of them have the
    light's `centre` at or below their horizon (else 0); and for a point `centre` the distance from it to the
    nearest of them (None for a direction). `centre`: (x, y, z, 0),
    a world unit vector towards a sun's centre, or (x, y, z, 1), a local light's position."""
    buffer.write(_BOUNDS_RESET)
    frame.dispatch("render/lit_bounds.comp",
                   {"u_count_hidden": int(count_hidden), "u_light_centre": tuple(float(v) for v in centre)},
                   samplers={"g_irradiance": irradiance}, buffers={0: buffer})
    raw = np.frombuffer(buffer.read(), np.uint32)
    if raw[0] == 0:
        return None, 0, None
    enc = raw[[1, 2, 3, 4, 5, 6, 8]]    # invert lit_bounds.comp's ordered(): positives had the sign bit set
    bits = np.where(enc & np.uint32(0x80000000), enc ^ np.uint32(0x80000000), ~enc).astype(np.uint32)
    values = bits.view(np.float32).astype(np.float64)
    return (values[:3], values[3:6]), int(raw[7]), float(values[6]) if centre[3] else None


def _view_visibility(frame: Frame, technique, light, view, irradiance, receivers, casters, out, stats: dict,
                     debug: dict, split: bool = False, points=None, share: float = 1.0, nearest=None):
    """One light view: build the structures the technique declares, then its visibility into `out`. Returns
    the technique's coloured visibility texture, if it made one. `points`: the view's lit points (and their
    lifted points), where they were read back; `share`: the view's part of the light's lit pixels; `nearest`:
    the distance from a local light's centre to the nearest lit pixel (from `points` where they are given)."""
    t = frame.timings
    if points is not None and len(points) and light.kind != SUN:
        offsets = np.asarray(points, float) - np.asarray(light.position, float)
        nearest = float(np.sqrt(np.min(np.einsum("ij,ij->i", offsets, offsets))))
    lc = LightContext(light, view, irradiance, receivers, casters, {**view.uniforms(), **frame.bias_uniforms},
                      frame.receiver_sides, split=split, receiver_points=points, share=share,
                      nearest_receiver=nearest)
    memory = stats.setdefault("structure_bytes", {})    # per structure: the largest light view's
    for need in structures.plan(technique.needs_for(frame.settings)):    # what the technique declares, once
        with t.stage("shadow_map"):
            built = lc.structures[need.name] = structures.build(need, frame, lc)
        memory[need.name] = max(memory.get(need.name, 0), structures.nbytes(built))
    with t.stage("visibility"):
        technique.visibility(frame, lc, out)
    stats["views"] = stats.get("views", 0) + 1
    stats["view_texels"] = stats.get("view_texels", 0) + view.width * view.height     # what its maps cover
    if lc.stats:
        stats.setdefault("per_light", []).append({"light": light.name, **lc.stats})
    _keep_max(debug, lc.debug)
    return lc.visibility_rgb


def _keep_max(debug: dict, more: dict) -> None:
    """Debug passes of several lights (or views): keep the per-pixel maximum."""
    for name, array in more.items():
        debug[name] = array if name not in debug else np.maximum(debug[name], array)


def _lifted_points(normal: np.ndarray, geometric: np.ndarray, xyz: np.ndarray) -> np.ndarray:
    """The points (N, 3) that the lit pixels' shadow rays leave from at the whole terminator lift (their
    g_normal and g_geometric texels, N × 4; common/gbuffer.frag: g_geometric.w along the shading normal;
    light_view.glsl make_lit_receiver lifts by at most that): where a ray aimed into its own smooth triangle
    starts, which a view must hold to test it."""
    return xyz + normal[:, :3] * geometric[:, 3:4]


@dataclass
class ViewPart:
    """Some of a light's lit pixels (`mask` over them) and the view they take: the light's single view (all
    else None), a rotation `rotation` of the view frame `frame` (a cube face, a sun's rim view), or the single
    view of a stand-in `light` (for the part of a local light's emitter its pixels see,
    lightview.local_rim_lights)."""
    mask: np.ndarray
    light: object = None
    frame: np.ndarray | None = None
    rotation: np.ndarray | None = None


def _with_lifted(xyz: np.ndarray, lifted: np.ndarray | None) -> np.ndarray:
    """Lit points (N × 3) and, where known, where their shadow rays leave from: the points a view must hold."""
    return (xyz if lifted is None else np.concatenate([xyz, lifted])).astype(np.float64)


def _view_parts(light, view, xyz, lifted, normal, geometric, rim: bool):
    """The views a light's lit pixels (xyz, N × 3, where their shadow rays leave from, and their g_normal and
    g_geometric texels) are split over, as ViewParts; None when the single view holds them all. Rim views
    first take the pixels whose horizon hides the light's centre; a clamped view's pixels outside it go to
    the cube faces (lightview.split_faces)."""
    local_rim = rim and light.kind != SUN
    parts = []
    if rim and light.kind == SUN:
        for rotation, mask in lightview.sun_rim_faces(light, view, geometric[:, :3], normal[:, :3]) or []:
            if rotation is not None:
                parts.append(ViewPart(mask, frame=view.view, rotation=rotation))
    elif local_rim:
        for point, mask in lightview.local_rim_lights(light, xyz, geometric[:, :3], normal[:, :3]) or []:
            if point is not None:
                parts.append(ViewPart(mask, light=point))
    rest = ~np.any([p.mask for p in parts], axis=0) if parts else np.ones(len(xyz), bool)
    parts += _face_parts(view, xyz, lifted, rest, margin=_sample_margin(light))
    return parts if _splits(parts) else None


def _splits(parts: list, light=None) -> bool:
    """Whether ViewParts ask for more than the single view of `light` (a stand-in; None: the light's own)."""
    return len(parts) > 1 or (len(parts) == 1 and (parts[0].rotation is not None or parts[0].light is not light))


def _sample_margin(light) -> float:
    """How far a point of `light` lies from its centre at most (metres; 0 for a sun, whose views are never
    split). A clamped view's single view keeps only the pixels a view from any such point holds too:
    REFERENCE's sample maps look from there, and near the window's edge some missed pixels they should
    shadow, which counted lit (fuzz 29050: floor pixels off 120 of a 0.83 m light's 256 sample maps)."""
    if light.kind == SUN:
        return 0.0
    half = light_half_extent(light)
    return float(np.hypot(*half) if light.kind == AREA else max(half))


def _face_parts(view, xyz, lifted, where, light=None, margin: float = 0.0) -> list:
    """The pixels `where` (a mask over xyz) of a view: the ViewParts of its single view and of the cube faces
    that take what a clamped view does not hold, or holds closer to its edge than `margin` allows
    (lightview.split_faces); `light` is the view's stand-in light, if any."""
    index = np.flatnonzero(where)
    faces = lightview.split_faces(view, xyz[index], None if lifted is None else lifted[index], margin=margin)
    if faces is None:
        return [ViewPart(where, light=light)] if where.any() else []
    parts = []
    for rotation, sub in faces:
        mask = np.zeros(len(xyz), bool)
        mask[index[sub]] = True
        parts.append(ViewPart(mask, light=light, frame=None if rotation is None else view.view, rotation=rotation))
    return parts


def _face_visibility(frame: Frame, technique, light, view, view_receivers, view_casters, parts, lit, lit_xyz,
                     lifted, facing, irradiance, object_bounds, caster_objects, out, stats: dict, debug: dict):
    """A light whose lit pixels do not fit one view (`parts`, ViewParts from _view_parts): its single view for
    the pixels it holds, one view per cube face for the rest (lightview.split_faces), a sun's rim views
    (rotations of its frame, as faces are) and a local light's stand-ins (lightview.local_rim_lights: area
    lights with views of their own, split into cube faces in turn where one view cannot hold their pixels), each
    fitted to the
    receivers it owns, with its own structures; every pixel takes the visibility of the view that owns it, so
    none is left outside every map."""
    t = frame.timings
    size = (frame.width, frame.height)
    owner = np.full(lit.shape, -1.0, np.float32)
    owner_tex, face_out = frame.texture(size, 1), frame.texture(size, 1)
    merged_rgb, rgb_seen = frame.texture(size, 4), False
    face_debug: dict = {}
    lit_index = np.flatnonzero(lit.ravel())          # the order of position[lit], which the masks follow
    queue = list(parts)

    def own(first: int) -> None:                     # the pixels of queue[first:] to their parts
        for index in range(first, len(queue)):
            owner.reshape(-1)[lit_index[queue[index].mask]] = index
        owner_tex.write(owner.tobytes())
    own(0)
    index = 0
    while index < len(queue):
        part = queue[index]
        part_light = part.light or light
        rgb, casters = None, None
        pts = _with_lifted(lit_xyz[part.mask], None if lifted is None else lifted[part.mask])
        if part.light is None and part.rotation is None:    # the light's single view keeps the pixels it holds
            receivers, casters, face_view = view_receivers, view_casters, view
        else:
            # the view holds its receivers and the points their shadow rays leave from (lifted off smooth
            # triangles), so a lifted point is looked up in a map instead of falling off it
            receivers = (pts.min(axis=0), pts.max(axis=0))
            if part_light.casts_shadow and frame.geometry.has_casters:
                # a part's pixels are known one by one: a convex caster none of them sees the light past is
                # left out (a ball's terminator band under a stand-in: often no view at all)
                casters = lightview.shadowing_caster_bounds(part_light, object_bounds, caster_objects, receivers,
                                                            frame.receiver_sides, points=lit_xyz[part.mask],
                                                            lifted=None if lifted is None else lifted[part.mask],
                                                            facing=facing[part.mask],
                                                            convex=frame.geometry.convex_casters())
            if casters is not None:
                with t.stage("light_view"):
                    size = frame.settings.shadow_map_size
                    face_view = lightview.fit(part_light, receivers, casters, size, frame=part.frame,
                                              face=part.rotation, receiver_points=pts)
                    # a part's map only as fine as the pixels it holds need (the light's own view keeps the
                    # size the settings ask for)
                    needed = lightview.needed_map_size(face_view, lit_xyz[part.mask], frame.snap.camera, size)
                    if needed < size:
                        face_view = face_view.resized(needed)
                    more = []
                    if face_view.clamped and part.light is not None and part.rotation is None:
                        more = _face_parts(face_view, lit_xyz, lifted, part.mask, light=part.light,
                                           margin=_sample_margin(part.light))
                if _splits(more, part.light):
                    # a stand-in's view too wide for one map: it keeps what it holds, its faces take the rest
                    held = [p for p in more if p.rotation is None]
                    queue[index] = ViewPart(held[0].mask if held else np.zeros_like(part.mask), light=part.light)
                    queue += [p for p in more if p.rotation is not None]
                    own(index)
                # Pixels outside a face's window lie where no caster can shadow them (fit's window holds the
                # shadowable receivers); only a face too wide for its map would leave shadowable ones out.
                elif face_view.clamped:
                    frame.warn(f"Light '{light.name}': some pixels fall outside its cube-face views "
                               "(please report this scene).")
        if casters is not None:
            view_debug: dict = {}
            with frame.view_of(owner_tex, index):    # its structures and visibility for its own pixels only
                rgb = _view_visibility(frame, technique, part_light, face_view, irradiance, receivers, casters,
                                       face_out, stats, view_debug, split=True, points=pts,
                                       share=float(part.mask.sum()) / max(len(part.mask), 1))
            owned = owner == index
            for name, array in view_debug.items():      # debug passes too come from the owning view
                merged = face_debug.setdefault(name, np.zeros_like(array))
                merged[owned] = array[owned]
        rgb_seen |= rgb is not None
        with t.stage("visibility"), frame.view_of(owner_tex, index):
            frame.dispatch("render/merge_view.comp", {"u_unshadowed": int(casters is None),
                                                      "u_has_rgb": int(rgb is not None)},
                           samplers={"u_view_visibility": face_out,
                                     "u_view_rgb": rgb if rgb is not None else face_out},
                           images={0: out, 1: merged_rgb})
        index += 1
    _keep_max(debug, face_debug)
    stats["lights_split"] = stats.get("lights_split", 0) + 1
    return merged_rgb if rgb_seen else None


def _finish(frame: Frame, combined, unshadowed, sums, irradiance_sum, covered, debug: dict) -> dict:
    s = frame.read(sums)
    with np.errstate(divide="ignore", invalid="ignore"):
        vis = np.where(s[..., 1] > 0.0, s[..., 0] / s[..., 1], 1.0)
    vis = np.clip(np.nan_to_num(vis, nan=1.0), 0.0, 1.0).astype(np.float32)
    rgba = frame.read(combined).copy()
    rgba[..., 3] = 1.0
    depth = np.where(covered, frame.read(frame.gbuffer["g_normal"])[..., 3], BACKGROUND_DEPTH)
    out = {
        "Combined": rgba,
        "Depth": depth[..., None].astype(np.float32),
        "Visibility": vis[..., None],
        "Unshadowed": frame.read(unshadowed, 3).copy(),
    }
    if frame.settings.debug_passes:
        out["Irradiance"] = frame.read(irradiance_sum, 3).copy()
    result = {}
    for name, channels, *_ in passes.render_passes(frame.settings):
        array = out.get(name, debug.get(name))
        if array is None:       # a technique debug pass no light produced
            array = np.zeros((frame.height, frame.width, channels), np.float32)
        result[name] = np.asarray(array, np.float32).reshape(frame.height, frame.width, channels)
    return result
