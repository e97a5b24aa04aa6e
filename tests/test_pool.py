"""The GPU resource pool (engine/gpu/pool.py): reuse, zero-filled reuse, trimming."""
import numpy as np

from penumbra.engine.gpu.context import GpuWorker
from penumbra.engine.gpu.pool import KEEP_FRAMES, ResourcePool


def _on_gpu(fn):
    return GpuWorker.get().submit(lambda worker: fn(worker.ctx)).result()


def test_a_reused_texture_is_the_same_object_and_reads_zero():
    def job(ctx):
        pool = ResourcePool(ctx)
        a = pool.texture((6, 5), 2)
        a.write(np.full((5, 6, 2), 7.0, np.float32).tobytes())
        pool.give_back(a)
        pool.end_frame()
        b = pool.texture((6, 5), 2)
        other = pool.texture((6, 5), 2)         # the free one is taken: a second one is made
        return a is b, other is not b, np.frombuffer(b.read(), np.float32), dict(pool.created)
    same, distinct, texels, created = _on_gpu(job)
    assert same and distinct
    assert np.all(texels == 0.0)
    assert created == {"texture": 2}


def test_free_objects_unused_for_a_few_frames_are_released():
    def job(ctx):
        pool = ResourcePool(ctx)
        tex, buf = pool.texture((4, 4), 1), pool.buffer(bytes(16))
        pool.framebuffer([tex])
        pool.give_back(tex)
        pool.give_back(buf)
        for _ in range(KEEP_FRAMES):
            pool.end_frame()
        kept = pool.texture((4, 4), 1) is tex
        pool.give_back(tex)
        for _ in range(KEEP_FRAMES + 1):
            pool.end_frame()
        return kept, pool._free, pool._framebuffers
    kept, free, framebuffers = _on_gpu(job)
    assert kept
    assert free == {} and framebuffers == {}
