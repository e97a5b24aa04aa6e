"""SSM: soft shadow maps (Atty, Holzschuch, Lapierre, Hasenfratz, Hansen, Sillion 2006, "Soft Shadow Maps:
Efficient Sampling of Light Source Visibility").

Per light (Fig. 3 of the paper):
  1. occluder map (casters) and receiver depth maps (receivers) from the light centre, aligned with the
     light and with texels of its aspect ratio (§3.1–3.2);
  2. every occluder texel becomes a micro-patch parallel to the light; its penumbra extent on the
     soft-shadow-map plane is an axis-aligned rectangle (§3.3, computed on the CPU as in the paper, with
     the work estimate that can lower the map resolution);
  3. scatter: for every SSM texel inside that rectangle the patch is back-projected onto the light and the
     hidden fraction added (§3.4) — instanced quads with additive blending (default) or a compute pass with
     fixed-point integer atomics (`ssm_scatter`);
  4. two-sided (§3.5): a second occluder map of the farthest back faces gets its own SSM; merged by maximum;
  5. the SSM is projected onto the receivers in the camera view: V = 1 - occlusion.

Roles (Object Properties → Penumbra → Shadow Role): micro-patches come from CASTER and BOTH objects,
receiver depths from RECEIVER and BOTH objects. Self-shadowing is not modelled by this technique (the
paper's occluder/receiver split, §1 and §6): an object never shadows itself — the maps carry object
indices and a patch skips receivers of its own object. (Without that, the staircase of micro-patches
parallel to the light shadows any surface steeper than ~50° to the light plane: measured on suzanne,
mae_shadow 0.126 → 0.078.)

How BOTH maps into the split: BOTH objects appear in both the occluder and the receiver maps. A flat,
axis-aligned caster that every visible receiver lies on the light side of (a ground plane) cannot shadow
anything and is left out of the occluder maps (lightview.shadowing_caster_bounds), so a BOTH floor is a
receiver only. A floating BOTH occluder hides the floor beneath it from the light centre, so one receiver
depth per texel is not enough: each SSM texel stores the occlusion for the nearest and for the farthest
receiver seen through it (two channels of one scatter), and a camera pixel takes the one whose depth it
matches, interpolating by depth for a third layer in between (deviation: the paper has one receiver map).
Pixels of camera-visible objects that are not receivers (CASTER role) get V = 1.

Accumulation precision (appendix A): float32 blending (default); half-float blending, which loses the
contributions of micro-patches hiding less than ~2^-11 of the light once the sum grows (large maps); and
half-float with the paper's workaround: ⌊√M⌋ batches summed separately and then added together.

Lights: rectangle and square exactly; disk, ellipse, sphere (point/spot radius) and sun (disk of
directions) through their bounding rectangle (square).
"""
from __future__ import annotations

import math

import numpy as np

from ..core import lightview
from ..gpu.frame import NO_OCCLUDER
from ..gpu.programs import program
from ..core.lightview import LightView
from .base import Option, Technique, light_shape_uniforms
from ..gpu.programs import bind_samplers, mat_uniform, set_uniforms

CASTER_ROLES = ("CASTER", "BOTH")
RECEIVER_ROLES = ("RECEIVER", "BOTH")
DEPTH_EPSILON = 1e-5       # relative: a patch occludes a receiver only when zo < zr·(1 − ε)
FIXED_POINT = 1 << 24       # compute scatter: occlusion units per 1.0 (sum of ≤ 256 full occlusions fits u32)

PRECISION_ITEMS = (
    ("FLOAT32", "Float32", "32-bit float blending: exact to ~1e-7 per micro-patch (default)"),
    ("HALF", "Half Float", "16-bit float blending as on 2006 GPUs: contributions below 2^-11 of the running "
                           "sum are lost, so large maps under-shadow (appendix A)"),
    ("HALF_BATCHED", "Half Float, Batched", "16-bit float blending with the paper's workaround: ⌊√M⌋ "
                                            "batches summed separately, then added (appendix A)"),
)


def split_roles(snap) -> tuple[list[int], list[int]]:
    """Object indices whose micro-patches occlude (CASTER/BOTH and casting shadows) and whose surfaces
    receive (RECEIVER/BOTH and seen by the camera)."""
    casters = [i for i, o in enumerate(snap.objects) if o.caster and getattr(o, "role", "BOTH") in CASTER_ROLES]
    receivers = [i for i, o in enumerate(snap.objects)
                 if o.receiver and getattr(o, "role", "BOTH") in RECEIVER_ROLES]
    return casters, receivers


def role_warnings(snap) -> list[str]:
    casters, receivers = split_roles(snap)
    out = []
    if not casters:
        out.append(f"SSM: scene '{snap.name}' has no object with Shadow Role Caster or Both: no shadows.")
    if not receivers:
        out.append(f"SSM: scene '{snap.name}' has no object with Shadow Role Receiver or Both: no shadows.")
    return out


def ssm_view(view: LightView, half, size: int) -> LightView:
    """The pipeline's light view with texels of the light's aspect ratio (§3.2: micro-patches axis-aligned
    with the light and of its aspect ratio); the longer side in texels gets `size`. The window grows
    symmetrically on the short side to a whole number of texels."""
    x0, x1, y0, y1 = view.window
    w, h = max(x1 - x0, 1e-30), max(y1 - y0, 1e-30)
    aspect = float(half[0]) / float(half[1]) if half[0] > 0 and half[1] > 0 else 1.0   # texel width / height
    if w >= h * aspect:
        width = size
        tw = w / width
        th = tw / aspect
        height = int(min(max(math.ceil(h / th - 1e-9), 1), size))
        grow = (height * th - h) / 2.0
        window = (x0, x1, y0 - grow, y1 + grow)
    else:
        height = size
        th = h / height
        tw = th * aspect
        width = int(min(max(math.ceil(w / tw - 1e-9), 1), size))
        grow = (width * tw - w) / 2.0
        window = (x0 - grow, x1 + grow, y0, y1)
    proj = (lightview.ortho if view.is_ortho else lightview.frustum)(window, view.near, view.far)
    return LightView(view.view, proj, width, height, view.near, view.far, view.is_ortho,
                     tuple(float(v) for v in window), view.clamped)


def spread(zo, zr, ortho: bool):
    """§3.4 (see glsl/ssm/patch.glsl): window units per unit of light offset between a patch at depth zo
    and a receiver at depth zr: 1/zo − 1/zr (perspective), zr − zo (sun)."""
    return zr - zo if ortho else 1.0 / zo - 1.0 / zr


def patch_list(depth_id: np.ndarray, view: LightView, half, zr_max: float, bias_texels: float):
    """Micro-patches of an occluder map and their penumbra extents (§3.3).

    The extent of a patch [lo, hi] at depth zo on the plane of a receiver at depth zr is
    [lo − h·s, hi + h·s] with s = spread(zo, zr) — the section of the patch's penumbra pyramid, whose apex
    is C_L + r/(1+r)·(C_P − C_L) with r = LL'/PP' (§3.3; at zr the paper's RR' = LL'(zr − z_apex)/z_apex
    equals the patch's projection zr/zo·PP' plus LL'(zr − zo)/zo, the same rectangle). It grows with zr, so
    the farthest receiver depth bounds it. Returns (float32 (M, 8) rows: x0, y0, x1, y1 in texels, i, j,
    zo, object; estimated SSM texel updates). `depth_id`: (H, W, 2) depth and object index per texel."""
    depth, ids = depth_id[..., 0], depth_id[..., 1]
    valid = (depth > 0.0) & (depth < 1.0e30)
    j, i = np.nonzero(valid)
    if i.size == 0 or not np.isfinite(zr_max):
        return np.zeros((0, 8), np.float32), 0.0
    zo = depth[j, i].astype(np.float64)
    tw, th = view.texel_size()
    keep = zo < zr_max * (1.0 - bias_texels)
    zo, i, j = zo[keep], i[keep], j[keep]
    obj = ids[j, i]
    with np.errstate(divide="ignore", over="ignore", invalid="ignore"):
        s = np.maximum(spread(np.maximum(zo, 1e-30), zr_max, view.is_ortho), 0.0)
        gx = np.minimum(half[0] * s / tw, 4.0 * view.width)     # clamp: an occluder at the light plane
        gy = np.minimum(half[1] * s / th, 4.0 * view.height)    # covers the map, never infinity
    rect = np.stack([np.clip(i - gx, 0, view.width), np.clip(j - gy, 0, view.height),
                     np.clip(i + 1 + gx, 0, view.width), np.clip(j + 1 + gy, 0, view.height)], axis=1)
    area = np.clip(rect[:, 2] - rect[:, 0], 0, None) * np.clip(rect[:, 3] - rect[:, 1], 0, None)
    keep = area > 0.0
    rows = np.zeros((int(keep.sum()), 8), np.float32)
    rows[:, 0:4] = rect[keep]
    rows[:, 4], rows[:, 5], rows[:, 6], rows[:, 7] = i[keep], j[keep], zo[keep], obj[keep]
    return rows, float(area[keep].sum())


def casters_reach_receivers(light, world_to_local, half, is_ortho: bool, casters, receivers) -> bool:
    """False when the casters' penumbrae cannot reach the visible receivers: all casters behind the
    receivers, or their windows (widened by the largest penumbra) disjoint. Conservative: True when a box
    reaches the light plane."""
    def corners(box):
        lo, hi = (np.asarray(v, float) for v in box)
        return lightview.to_local(world_to_local, lightview.box_corners(lo, hi))
    c, r = corners(casters), corners(receivers)
    cd, rd = -c[:, 2], -r[:, 2]
    if cd.min() >= rd.max():
        return False
    if is_ortho:
        cw, rw = c[:, :2], r[:, :2]
        grow = np.asarray(half) * (rd.max() - cd.min())
    else:
        if cd.min() <= 1e-9 or rd.min() <= 1e-9:
            return True
        cw, rw = c[:, :2] / cd[:, None], r[:, :2] / rd[:, None]
        grow = np.asarray(half) * (1.0 / cd.min() - 1.0 / rd.max())
    lo_c, hi_c = cw.min(axis=0) - grow, cw.max(axis=0) + grow
    lo_r, hi_r = rw.min(axis=0), rw.max(axis=0)
    return bool(np.all(lo_c < hi_r) and np.all(lo_r < hi_c))


class SoftShadowMaps(Technique):
    identifier = "SSM"
    label = "Soft Shadow Maps"
    description = ("Atty et al. 2006: occluder-map texels scattered as micro-patches onto a soft shadow map. "
                   "Casters shadow receivers (Object → Penumbra → Shadow Role); self-shadowing within one "
                   "role is not modelled. Disk, ellipse, sphere and sun lights use their bounding rectangle")
    needs = ()
    options = (
        Option("ssm_map_size", 256, "Occluder Map Size",
               "Texels along the longer side of the occluder, receiver and soft shadow maps (the paper "
               "finds ~200 near optimal; cost grows with its square times the penumbra area)", 16, 2048),
        Option("ssm_passes", "TWO", "Passes", "Occluder maps scattered", items=(
            ("ONE", "One Pass", "Front-most occluder surfaces only"),
            ("TWO", "Two Passes", "Front-most and farthest back-facing occluder surfaces, merged by maximum "
                    "(§3.5)"))),
        Option("ssm_precision", "FLOAT32", "Accumulation", "Precision of the soft-shadow-map sums",
               items=PRECISION_ITEMS),
        Option("ssm_scatter", "RASTER", "Scatter", "How micro-patches are scattered", items=(
            ("RASTER", "Instanced Quads", "One quad per micro-patch, additive float blending (faster here)"),
            ("COMPUTE", "Compute + Atomics", "One invocation per micro-patch, fixed-point integer atomics"))),
        Option("ssm_weighting", "IRRADIANCE", "Weighting", "How a micro-patch's hidden part of the light counts",
               items=(("IRRADIANCE", "Irradiance", "Weighted by its share of the light's irradiance at a "
                       "receiver facing the light (parallel-rectangle form factor): closer to Cycles"),
                      ("UNIFORM", "Uniform (paper)", "Plain share of the light's area, as in the paper"))),
        Option("ssm_budget", 200.0, "Work Budget (M)",
               "Millions of soft-shadow-map texel updates allowed per occluder map; above it the maps are "
               "made coarser (the paper's remedy for large penumbrae, §5.1)", 1.0, 1.0e5),
    )
    debug_passes = (("SSM Occlusion", 1, "X", "VALUE"),)
    coarse = {"ssm_map_size": 64, "ssm_weighting": "UNIFORM"}
    sweep = ({"ssm_map_size": 64}, {"ssm_map_size": 128}, {"ssm_map_size": 256}, {"ssm_map_size": 512},
             {"ssm_weighting": "UNIFORM"})

    # ------------------------------------------------------------------------------------------------------
    def visibility(self, frame, lc, out):
        s, light = frame.settings, lc.light
        ones = np.ones((frame.height, frame.width), np.float32).tobytes()
        for text in role_warnings(frame.snap):
            frame.warn(text)
        casters, receivers = split_roles(frame.snap)
        bounds = frame.geometry.object_bounds()
        # A flat caster every visible receiver lies on the light side of shadows nothing (a BOTH floor).
        flags = np.zeros(len(frame.snap.objects), bool)
        kept = []
        for index in casters:
            flags[:] = False
            flags[index] = True
            if lightview.shadowing_caster_bounds(light, bounds, flags, lc.receivers) is not None:
                kept.append(index)
        casters = kept
        half = tuple(float(v) for v in light_shape_uniforms(light, lc.view)["u_light_half"])
        if not casters or not receivers:
            out.write(ones)
            frame.count(ssm_lights_skipped=1)
            return
        caster_box = (bounds[casters, 0].min(axis=0), bounds[casters, 1].max(axis=0))
        if not casters_reach_receivers(light, lc.view.view, half, lc.view.is_ortho, caster_box, lc.receivers):
            out.write(ones)         # the casters' penumbrae fall nowhere near a visible receiver: no work
            frame.count(ssm_lights_skipped=1)
            return

        size = int(s.option("ssm_map_size"))
        budget = float(s.option("ssm_budget")) * 1e6
        two_pass = s.option("ssm_passes") == "TWO"
        bias = DEPTH_EPSILON
        for _attempt in range(4):
            view = ssm_view(lc.view, half, size)
            with frame.timings.stage("ssm_maps"):
                maps = self._maps(frame, view, casters, receivers, two_pass)
                far = frame.read(maps["far"])[..., 0]
                valid_far = (far > 0.0) & (far < 1.0e30)
                zr_max = float(far[valid_far].max()) if valid_far.any() else math.inf
                lists = [patch_list(frame.read(maps["front"]), view, half, zr_max, bias)]
                if two_pass:
                    lists.append(patch_list(frame.read(maps["back"]), view, half, zr_max, bias))
            work = sum(w for _, w in lists)
            if work <= budget or size <= 32:
                break
            new = max(32, int(size * (budget / work) ** 0.25 * 0.95))
            frame.warn(f"SSM: light '{light.name}': occluder map lowered from {size} to {new} texels to "
                            f"keep the scatter within ssm_budget ({work / 1e6:.0f} M texel updates)")
            size = new
        frame.count(ssm_patches=sum(len(p) for p, _ in lists), ssm_work=int(work), ssm_map_size=size)
        if all(len(p) == 0 for p, _ in lists):
            out.write(ones)
            frame.count(ssm_lights_skipped=1)
            return

        frame.progress.check()
        with frame.timings.stage("ssm_scatter"):
            ssms = [self._scatter(frame, view, maps, rows, half, bias, s.option("ssm_precision"),
                                  s.option("ssm_scatter")) if len(rows) else None for rows, _ in lists]
        front = ssms[0] if ssms[0] is not None else self._zero_ssm(frame, view)
        back = ssms[1] if len(ssms) > 1 and ssms[1] is not None else None
        debug = frame.texture((frame.width, frame.height), 1) if s.debug_passes else out
        with frame.timings.stage("ssm_project"):
            mask = self._receiver_mask(frame, receivers)
            frame.dispatch("ssm/project.comp", {
                **view.uniforms(), **frame.bias_uniforms, "u_two_pass": int(back is not None),
                "u_debug": int(s.debug_passes), "u_has_mask": int(mask is not None)},
                samplers={"g_irradiance": lc.irradiance, "u_ssm_front": front,
                          "u_ssm_back": back if back is not None else front,
                          "u_recv_near": maps["near"], "u_recv_far": maps["far"],
                          "u_receiver_mask": mask if mask is not None else maps["near"]},
                images={0: out, 1: debug})
        if s.debug_passes:
            lc.debug["SSM Occlusion"] = frame.read(debug).copy()

    # ------------------------------------------------------------------------------------------------------
    def _maps(self, frame, view, casters, receivers, two_pass) -> dict:
        """Occluder maps (front-most casters; farthest back faces, §3.5) and receiver maps (nearest; farthest),
        linear depth from the light centre. Empty texels: NO_OCCLUDER (nearest) or 0 (farthest)."""
        ctx = frame.ctx
        prog = program(frame.worker, "common/depth.vert", "ssm/depth.frag")
        set_uniforms(prog, {"u_light_view": mat_uniform(view.view), "u_light_view_proj": mat_uniform(view.view_proj)})
        jobs = [("front", "caster", casters, False, False), ("near", "receiver", receivers, False, False),
                ("far", "receiver", receivers, True, False)]
        if two_pass:
            jobs.append(("back", "caster", casters, True, True))
        out = {}
        ctx.enable(ctx.DEPTH_TEST)
        ctx.disable(ctx.CULL_FACE)
        ctx.disable(ctx.BLEND)
        try:
            for name, role, objects, farthest, back_only in jobs:
                tex = frame.texture((view.width, view.height), 2)
                depth = frame._own(ctx.depth_texture((view.width, view.height)))
                fbo = frame._own(ctx.framebuffer(color_attachments=[tex], depth_attachment=depth))
                fbo.use()
                if farthest:
                    fbo.clear(0.0, -1.0, 0.0, 0.0, depth=0.0)
                    ctx.depth_func = ">"
                else:
                    fbo.clear(NO_OCCLUDER, -1.0, 0.0, 0.0, depth=1.0)
                    ctx.depth_func = "<"
                set_uniforms(prog, {"u_back_only": int(back_only)})
                for index in objects:         # one draw per object, tagged with its index
                    set_uniforms(prog, {"u_object": float(index)})
                    _draw(frame, prog, role, (index,))
                out[name] = tex
        finally:
            ctx.depth_func = "<"
        out["receivers"] = frame.texture((view.width, view.height), 4)
        frame.dispatch("ssm/pack.comp", samplers={"u_recv_near": out["near"], "u_recv_far": out["far"]},
                       images={0: out["receivers"]}, size=(view.width, view.height))
        return out

    def _receiver_mask(self, frame, receivers):
        """Camera-resolution mask (g = 1) of the pixels whose nearest surface is a receiver, or None when
        every camera-visible object is one. Depth matching alone cannot tell a CASTER-only surface that
        lies between two receivers (seen from the light centre) from a receiver there."""
        visible = [i for i, o in enumerate(frame.snap.objects) if o.receiver]
        others = [i for i in visible if i not in set(receivers)]
        if not others:
            return None
        ctx, cam = frame.ctx, frame.snap.camera
        size = (frame.width, frame.height)
        tex = frame.texture(size, 2)
        depth = frame._own(ctx.depth_texture(size))
        fbo = frame._own(ctx.framebuffer(color_attachments=[tex], depth_attachment=depth))
        prog = program(frame.worker, "common/depth.vert", "ssm/depth.frag")
        set_uniforms(prog, {"u_light_view": mat_uniform(cam.view), "u_light_view_proj": mat_uniform(cam.projection @ cam.view),
                    "u_back_only": 0})
        fbo.use()
        fbo.clear(0.0, 0.0, 0.0, 0.0, depth=1.0)
        ctx.enable(ctx.DEPTH_TEST)
        ctx.disable(ctx.CULL_FACE)
        ctx.disable(ctx.BLEND)
        ctx.depth_func = "<"
        for flag, objects in ((1.0, receivers), (0.0, others)):
            set_uniforms(prog, {"u_object": flag})
            _draw(frame, prog, "receiver", objects)
        return tex

    def _zero_ssm(self, frame, view):
        tex = frame.texture((view.width, view.height), 2)
        tex.write(np.zeros((view.height, view.width, 2), np.float32).tobytes())
        return tex

    def _scatter(self, frame, view, maps, rows, half, bias, precision, method):
        """Sum every micro-patch's hidden light fraction into an RG soft shadow map (r: nearest receiver,
        g: farthest). §3.4 on the GPU; precision and batching per appendix A."""
        ctx = frame.ctx
        size = (view.width, view.height)
        defines = {"SSM_WEIGHTED": int(frame.settings.option("ssm_weighting") == "IRRADIANCE")}
        uniforms = {"u_light_window_ssm": view.window, "u_ssm_size": size, "u_half": half,
                    "u_ortho": int(view.is_ortho), "u_bias_texels": bias}
        patches = frame._own(ctx.buffer(np.ascontiguousarray(rows, np.float32).tobytes()))
        patches.bind_to_storage_buffer(0)
        m = len(rows)
        if method == "COMPUTE":
            sums = []
            for binding in (1, 2):
                t = frame._own(ctx.texture(size, 1, dtype="u4"))
                t.write(np.zeros(size[0] * size[1], np.uint32).tobytes())
                t.bind_to_image(binding, read=True, write=True)
                sums.append(t)
            prog = program(frame.worker, compute="ssm/scatter.comp", defines=defines)
            bind_samplers(prog, {"u_receivers": maps["receivers"]})
            set_uniforms(prog, {**uniforms, "u_count": m})
            prog.run((m + 63) // 64, 1, 1)
            ctx.memory_barrier()
            ssm = frame.texture(size, 2)
            ssm.bind_to_image(3, read=False, write=True)
            resolve = program(frame.worker, compute="ssm/resolve.comp")
            set_uniforms(resolve, {"u_image_size": size})
            resolve.run((size[0] + 7) // 8, (size[1] + 7) // 8, 1)
            ctx.memory_barrier()
            return ssm

        dtype = "f4" if precision == "FLOAT32" else "f2"
        prog = program(frame.worker, "ssm/scatter.vert", "ssm/scatter.frag", defines=defines)
        bind_samplers(prog, {"u_receivers": maps["receivers"]})
        set_uniforms(prog, uniforms)
        vao = frame._own(ctx.vertex_array(prog, []))
        ssm = frame.texture(size, 2, dtype)
        fbo = frame._own(ctx.framebuffer(color_attachments=[ssm]))
        fbo.clear(0.0, 0.0, 0.0, 0.0)
        ctx.disable(ctx.DEPTH_TEST)
        ctx.disable(ctx.CULL_FACE)
        ctx.enable(ctx.BLEND)
        ctx.blend_func = ctx.ONE, ctx.ONE
        ctx.blend_equation = ctx.FUNC_ADD
        try:
            if precision != "HALF_BATCHED":
                fbo.use()
                set_uniforms(prog, {"u_first": 0})
                vao.render(ctx.TRIANGLE_STRIP, vertices=4, instances=m)
            else:
                # Appendix A: split the M micro-patches into ⌊√M⌋ batches, sum each in FP16, add the batch
                # sums into the total (also FP16): small values are added only to small or medium ones.
                batches = max(1, int(math.isqrt(m)))
                batch = frame.texture(size, 2, "f2")
                batch_fbo = frame._own(ctx.framebuffer(color_attachments=[batch]))
                add = program(frame.worker, "ssm/fullscreen.vert", "ssm/add.frag")
                add_vao = frame._own(ctx.vertex_array(add, []))
                edges = np.linspace(0, m, batches + 1).round().astype(int)
                for first, last in zip(edges[:-1], edges[1:]):
                    if last <= first:
                        continue
                    batch_fbo.use()
                    batch_fbo.clear(0.0, 0.0, 0.0, 0.0)
                    prog["u_first"].value = int(first)
                    bind_samplers(prog, {"u_receivers": maps["receivers"]})
                    vao.render(ctx.TRIANGLE_STRIP, vertices=4, instances=int(last - first))
                    fbo.use()
                    bind_samplers(add, {"u_batch": batch})
                    add_vao.render(ctx.TRIANGLES, vertices=3)
        finally:
            ctx.disable(ctx.BLEND)
        return ssm


# ----------------------------------------------------------------------------------------------------------
def _draw(frame, prog, role: str, objects) -> None:
    """Draw the triangles of `objects` that play `role` ("caster": casts shadows; "receiver": seen by the
    camera), positions only."""
    frame.geometry.render(frame.ctx, prog, role, frozenset(int(i) for i in objects), position_only=True)


