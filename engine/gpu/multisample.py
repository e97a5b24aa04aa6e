"""The multisampled camera G-buffer of the anti-aliased frame (Schwarz & Stamminger 2008, §7, "single
visibility sample"): the scene is drawn into MSAA_SAMPLES-sample targets that only the shading reads. Once
per frame the pixels whose samples are not all their own fragment's are listed (EdgeList); per light,
accumulate.comp shades every pixel's own sample as without anti-aliasing, and at the listed pixels
(shade_edges) every sample is shaded and the mean replaces it. Visibility stays once per pixel, computed by
the technique on the per-pixel G-buffer, which is either

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

import numpy as np

from ..core.matrices import mat_uniform
from ..core.shading import light_defines, light_uniforms

GBUFFER_NAMES = ("g_position", "g_normal", "g_geometric", "g_albedo")
MSAA_SAMPLES = 4
# Per-sample formats: (components, dtype). Shading reads the normal + camera depth and the albedo as float32.
# Position it rebuilds from the depth (attributes are at the pixel centre, so a sample lies on the centre's
# camera ray), and the geometric normal only the per-pixel G-buffer needs (biases): with a pixel-centre
# visibility sample, both are one-byte placeholders that keep the shader's output locations (about half the
# bytes to write); the first-sample resolve copies every target, so there they stay RGBA32F.
_FORMATS = {"g_position": (1, "f1"), "g_normal": (4, "f4"), "g_geometric": (1, "f1"), "g_albedo": (4, "f4")}
# The targets and a 32-bit depth buffer, per sample (the larger, first-sample layout), and the edge list.
MSAA_BYTES_PER_PIXEL = MSAA_SAMPLES * (len(GBUFFER_NAMES) * 16 + 4) + 8


def multisampled_targets(frame, size, full: bool = False) -> dict:
    """The G-buffer's targets with MSAA_SAMPLES samples, under the per-pixel names with an `ms_` prefix
    (the names accumulate_msaa.comp samples them by); from the frame's pool. `full`: every target RGBA32F."""
    def target(name):
        components, dtype = (4, "f4") if full else _FORMATS[name]
        return frame.multisample_texture(size, components, MSAA_SAMPLES, dtype)
    return {"ms_" + name[2:]: target(name) for name in GBUFFER_NAMES}


class EdgeList:
    """The pixels of an anti-aliased frame whose multisamples do not all repeat the pixel's own fragment
    (silhouettes and creases; glsl/render/msaa_classify.comp), as a storage buffer of pixel coordinates.
    Everywhere else shading one sample is shading them all, so the per-light shading is accumulate.comp's,
    and only these pixels get the per-sample correction (shade_edges): work in proportion to the edges."""

    def __init__(self, frame, samples: dict):
        cam = frame.snap.camera
        inv_view = np.linalg.inv(cam.view)
        # glsl/render/msaa_samples.glsl's sample_position: the camera rays through the pixel centres
        self.uniforms = {"u_msaa_inv_view_proj": mat_uniform(np.linalg.inv(cam.projection @ cam.view)),
                         "u_msaa_camera_position": tuple(inv_view[:3, 3]),
                         "u_msaa_camera_forward": tuple(-inv_view[:3, 2])}
        self.buffer = frame.reserved_buffer(16 + 8 * frame.width * frame.height)
        self.buffer.write(np.zeros(4, np.uint32).tobytes())
        frame.dispatch("render/msaa_classify.comp", samplers=samples, buffers={0: self.buffer})
        self.count = int(np.frombuffer(self.buffer.read(4), np.uint32)[0])
        self.nbytes = self.buffer.size



def shade_edges(frame, light, tau: float, samplers: dict, images: dict, *, has_rgb: bool,
                sheets: bool = False) -> None:
    """After accumulate.comp added each pixel's own sample for `light`, replace that at the edge pixels by
    the mean over their samples (glsl/shading/accumulate_msaa.comp). `sheets`: samplers' u_sheet_light is
    accumulate.comp's. Timed as the stage `accumulate_msaa`."""
    edges = frame.msaa_edges
    if not edges.count:
        return
    with frame.timings.stage("accumulate_msaa"):
        frame.dispatch("shading/accumulate_msaa.comp",
                       {"u_has_rgb": int(has_rgb), "u_aa_depth_threshold": float(tau), "u_sheets": int(sheets),
                        "u_edge_count": edges.count, **edges.uniforms, **light_uniforms(light, frame.snap.lights)},
                       samplers={**samplers, **frame.gbuffer_samples}, images=images, buffers={0: edges.buffer},
                       defines=light_defines(light), groups=((edges.count + 63) // 64, 1, 1))


def resolve_first_sample(frame, samples: dict, gbuffer: dict) -> None:
    """Copy each pixel's first sample of the multisampled targets into the per-pixel G-buffer."""
    images = {binding: gbuffer[name] for binding, name in enumerate(GBUFFER_NAMES)}
    frame.dispatch("render/gbuffer_first_sample.comp", samplers=samples, images=images)
