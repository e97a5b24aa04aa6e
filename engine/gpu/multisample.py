"""The multisampled camera G-buffer of the anti-aliased frame (Schwarz & Stamminger 2008, §7, "single
visibility sample"): the scene is drawn into MSAA_SAMPLES-sample targets that only the shading pass
(glsl/shading/accumulate_msaa.comp) reads: it shades every sample and averages. Visibility stays once per
pixel, computed by the technique on the per-pixel G-buffer, which is either

  CENTER  drawn as without anti-aliasing (one more raster of the scene): the techniques' input and the Depth
          and Visibility passes equal a frame without anti-aliasing, pixel centres as in Cycles' point-filtered
          reference; the default, because
  FIRST   each pixel's first multisample (the paper's choice) sits at a fixed offset from the centre in GL's
          4× pattern, so silhouettes in the Depth and Visibility passes move by up to 0.4 px: REFERENCE on
          `suzanne` at 128² went from mae_shadow 0.0075 to 0.0114 against point-filtered Cycles.

Multisampled rasterisation runs the fragment shader once per pixel and primitive, with the attributes at the
pixel centre (extrapolated where the primitive does not cover it), and writes that result to the samples the
primitive covers: samples of one primitive hold identical values, the camera depth in g_normal.w included."""
from __future__ import annotations

GBUFFER_NAMES = ("g_position", "g_normal", "g_geometric", "g_albedo")
MSAA_SAMPLES = 4
# Four RGBA32F targets and a 32-bit depth buffer, per sample.
MSAA_BYTES_PER_PIXEL = MSAA_SAMPLES * (len(GBUFFER_NAMES) * 16 + 4)


def multisampled_targets(frame, size) -> dict:
    """The G-buffer's targets with MSAA_SAMPLES samples, under the per-pixel names with an `ms_` prefix
    (the names accumulate_msaa.comp samples them by); owned by the frame."""
    return {"ms_" + name[2:]: frame.own(frame.ctx.texture(size, 4, samples=MSAA_SAMPLES, dtype="f4"))
            for name in GBUFFER_NAMES}


def resolve_first_sample(frame, samples: dict, gbuffer: dict) -> None:
    """Copy each pixel's first sample of the multisampled targets into the per-pixel G-buffer."""
    images = {binding: gbuffer[name] for binding, name in enumerate(GBUFFER_NAMES)}
    frame.dispatch("render/gbuffer_first_sample.comp", samplers=samples, images=images)
