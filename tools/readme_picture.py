"""Makes docs/suzanne.png for the README: the built-in `suzanne` scene with every technique next to Cycles,
each with its time. Run: .venv/bin/python tools/readme_picture.py"""
import os
import time

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import penumbra  # noqa: E402
import bpy  # noqa: E402

penumbra.register()
from penumbra.engine.core import exr  # noqa: E402
from penumbra.engine.render import pipeline
from penumbra.engine.measure import scenes
from penumbra.engine.blender.extract import extract  # noqa: E402
from penumbra.engine.core.settings import RenderSettings  # noqa: E402

sc = scenes.build("suzanne", resolution=(256, 256))
snap = extract(bpy.context.evaluated_depsgraph_get(), sc)
panels = []
for technique, extra in (("HARD", {}), ("PCSS", {}), ("BACKPROJECTION", {}), ("SSM", {}),
                         ("REFERENCE", {"averaged_light_samples": 256})):
    settings = RenderSettings(technique=technique).with_(**extra)
    pipeline.render(snap, settings)                       # compile shaders first
    start = time.perf_counter()
    result = pipeline.render(snap, settings)
    ms = (time.perf_counter() - start) * 1000
    panels.append((f"{technique} — {ms:.0f} ms", result.passes["Combined"]))
# Cycles itself, direct light only (what Penumbra computes), same scene and materials.
sc.render.engine = "CYCLES"
sc.cycles.samples, sc.cycles.max_bounces, sc.cycles.use_denoising = 256, 0, False
sc.cycles.pixel_filter_type, sc.cycles.filter_width = "GAUSSIAN", 0.01
sc.render.image_settings.media_type = "MULTI_LAYER_IMAGE"
sc.render.image_settings.file_format = "OPEN_EXR_MULTILAYER"
sc.render.filepath = "/tmp/penumbra_readme_cycles.exr"
start = time.perf_counter()
bpy.ops.render.render(write_still=True)
seconds = time.perf_counter() - start
panels.append((f"Cycles 256 spp — {seconds:.1f} s", exr.read(sc.render.filepath)["Combined"]))
fig, axes = plt.subplots(2, 3, figsize=(12, 8.6))
for ax, (title, image) in zip(axes.ravel(), panels):
    ax.imshow(exr.to_srgb8(image))
    ax.set_title(title)
    ax.axis("off")
fig.suptitle("Penumbra on the built-in `suzanne` scene (256², llvmpipe software GL, 2 CPU cores)")
fig.tight_layout()
os.makedirs("docs", exist_ok=True)
fig.savefig("docs/suzanne.png", dpi=80)
print("wrote docs/suzanne.png")
