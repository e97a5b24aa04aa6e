"""The soft shadow map itself (Atty et al. 2006, §3.4, appendix A): every micro-patch of SSM's occluder maps
scattered over its penumbra extent, summing the fraction of the light it hides into an RG texture (r: for
the nearest receiver, g: for the farthest). One map per occluder map (front; back faces for two passes)."""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..gpu.frame import resource_bytes
from ..gpu.loops import chunk_count, chunk_uniforms
from ..gpu.programs import bind_samplers, program, set_uniforms
from ..gpu.state import gl_state
from . import structure
from ..core.light_shape import light_shape_uniforms, round_in_view
from ..core.snapshot import AREA, SUN
from .ssm_maps import FACET_SLOPE, SSM_MAPS

SOFT_SHADOW_MAP = "soft_shadow_map"


@dataclass
class SoftShadowMap:
    front: object               # RG texture: summed occlusion of the front occluder map
    back: object | None         # the back-face map's (two passes), or None

    @property
    def nbytes(self) -> int:
        return resource_bytes([self.front, self.back])


@structure(SOFT_SHADOW_MAP, requires=(SSM_MAPS,))
def build(frame, lc, precision: str, method: str, weighted: bool):
    """`precision`: FLOAT32, HALF or HALF_BATCHED blending (appendix A); `method`: RASTER (instanced quads,
    additive blending) or COMPUTE (fixed-point atomics); `weighted`: irradiance-weighted occlusion. Sloped
    facets or flat micro-patches as the maps were built (SsmMaps.facets). None when the maps were skipped."""
    maps = lc.structures[SSM_MAPS]
    if maps.skipped:
        return None
    frame.progress.check()
    with frame.timings.stage("ssm_scatter"):
        # The receiver's own normal in the weights for a planar emitter (an area light, a sun's directions);
        # a sphere light's rectangle stands for a ball, whose light is not a plane's (see weighted_fraction).
        planar = lc.light.kind in (AREA, SUN)
        # Shares clipped to a round light's disk where the view holds that disk (a sphere keeps its square: room
        # at 128², 0.0179 with the square, 0.0193 with the disk).
        round_ = round_in_view(lc.light, lc.view.face)
        # A spot whose cone is narrower than its ball: each receiver's shares of the part it sees
        # (glsl/ssm/patch.glsl spot_share), in the spot's own view only.
        shape = light_shape_uniforms(lc.light, maps.view)
        spot = shape if shape["u_spot_cone"][0] > 0.0 else None
        ssms = [scatter(frame, maps, patches, precision, method, weighted, occ if maps.facets else None, planar,
                        round_, spot)
                if patches.count else None for patches, occ in zip(maps.patches, maps.occluder_maps())]
    front = ssms[0] if ssms[0] is not None else _zero(frame, maps.view)
    back = ssms[1] if len(ssms) > 1 and ssms[1] is not None else None
    return SoftShadowMap(front, back)


def _vertexless(frame, prog):
    """The attribute-less vertex array of `prog` (its vertex shader builds corners from gl_VertexID), made
    once per program and kept with it on the worker, so a redraw allocates none."""
    key = f"__vertexless_vao__{prog.glo}"
    vao = frame.worker.cache.get(key)
    if vao is None:
        vao = frame.worker.cache[key] = frame.ctx.vertex_array(prog, [])
    return vao


def _zero(frame, view):
    return frame.texture((view.width, view.height), 2)     # zero-filled


def scatter(frame, maps, patches, precision: str, method: str, weighted: bool, occluders=None,
            planar: bool = True, round_: bool = False, spot: dict | None = None):
    """Sum the hidden light fraction of every micro-patch in `patches` (a PatchList, built on the GPU) into
    an RG soft shadow map (r: nearest receiver, g: farthest). §3.4 on the GPU; precision and batching per
    appendix A. The instance count and the batches come from the count the patch list read back.
    `occluders`: the occluder map the patches come from, for sloped facets (glsl/ssm/patch.glsl), or None
    for the paper's flat micro-patches. `planar`: a planar emitter, whose weights take the receiver's normal.
    `round_`: shares of the ellipse inscribed in the light's rectangle (glsl/ssm/patch.glsl light_share).
    `spot`: the light's shape uniforms (light_shape_uniforms) where a spot's cone clips its ball (spot_share)."""
    ctx, view = frame.ctx, maps.view
    size = (view.width, view.height)
    # The clipped weights only where some receiver's horizon cuts the light: they cost the scatter twice the
    # time on llvmpipe even where no receiver takes them (plane 6.1 -> 13.6 s at 128²).
    defines = {"SSM_WEIGHTED": int(weighted), "SSM_FACETS": int(occluders is not None),
               "SSM_HORIZON_CUT": int(weighted and planar and maps.horizon_cut), "SSM_ROUND": int(round_),
               "SSM_SPOT_CLIP": int(spot is not None)}
    uniforms = {**view.uniforms(), **frame.bias_uniforms, "u_half": maps.half, "u_ortho": int(view.is_ortho),
                "u_bias_texels": maps.bias, "u_facet_slope": FACET_SLOPE,
                "u_receiver_normal": int(planar), **(spot or {})}
    patches.buffer.bind_to_storage_buffer(0)
    m = patches.count
    receivers = {name: maps.maps[key] for name, key in (("u_near_a", "near"), ("u_near_b", "near_n"),
                                                         ("u_near_c", "near_c"), ("u_far_a", "far"),
                                                         ("u_far_b", "far_n"), ("u_far_c", "far_c"))}
    if occluders is not None:
        receivers["u_occluders"] = occluders
    if method == "COMPUTE":
        for binding in (1, 2):
            t = frame.texture(size, 1, dtype="u4")     # zero-filled
            t.bind_to_image(binding, read=True, write=True)
        prog = program(frame.worker, compute="ssm/scatter.comp", defines=defines)
        bind_samplers(prog, receivers)
        set_uniforms(prog, {**uniforms, "u_count": m})
        # the patch rows stay on the GPU: a rectangle holds at most the whole map's texels
        chunks = chunk_count(size[0] * size[1])
        for k in range(chunks):             # each dispatch a share of every patch's texels (atomics add up)
            frame.progress.check()
            set_uniforms(prog, chunk_uniforms(k, chunks))
            prog.run((m + 63) // 64, 1, 1)
            ctx.memory_barrier()
        frame.count(ssm_scatter_dispatches=chunks)
        ssm = frame.texture(size, 2)
        ssm.bind_to_image(3, read=False, write=True)
        resolve = program(frame.worker, compute="ssm/resolve.comp", defines=defines)
        set_uniforms(resolve, {"u_image_size": size})
        resolve.run((size[0] + 7) // 8, (size[1] + 7) // 8, 1)
        ctx.memory_barrier()
        return ssm

    dtype = "f4" if precision == "FLOAT32" else "f2"
    prog = program(frame.worker, "ssm/scatter.vert", "ssm/scatter.frag", defines=defines)
    bind_samplers(prog, receivers)
    set_uniforms(prog, uniforms)
    vao = _vertexless(frame, prog)
    ssm = frame.texture(size, 2, dtype)
    fbo = frame.framebuffer([ssm])
    fbo.clear(0.0, 0.0, 0.0, 0.0)
    with gl_state(ctx, depth_test=False, cull=False, additive=True):
        if precision != "HALF_BATCHED":
            fbo.use()
            set_uniforms(prog, {"u_first": 0})
            vao.render(ctx.TRIANGLE_STRIP, vertices=4, instances=m)
        else:
            # Appendix A: split the M micro-patches into ⌊√M⌋ batches, sum each in FP16, add the batch
            # sums into the total (also FP16): small values are added only to small or medium ones.
            batches = max(1, int(math.isqrt(m)))
            batch = frame.texture(size, 2, "f2")
            batch_fbo = frame.framebuffer([batch])
            add = program(frame.worker, "ssm/fullscreen.vert", "ssm/add.frag")
            add_vao = _vertexless(frame, add)
            edges = np.linspace(0, m, batches + 1).round().astype(int)
            for first, last in zip(edges[:-1], edges[1:]):
                if last <= first:
                    continue
                batch_fbo.use()
                batch_fbo.clear(0.0, 0.0, 0.0, 0.0)
                prog["u_first"].value = int(first)
                bind_samplers(prog, receivers)
                vao.render(ctx.TRIANGLE_STRIP, vertices=4, instances=int(last - first))
                fbo.use()
                bind_samplers(add, {"u_batch": batch})
                add_vao.render(ctx.TRIANGLES, vertices=3)
    return ssm
