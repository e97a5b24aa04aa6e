"""The loop limit engine/gpu/loops.py works around, and its split: llvmpipe stops a long loop silently; the
same loop numbered flat and run in chunk_count shares runs every iteration."""
import numpy as np

from penumbra.engine.gpu import loops
from penumbra.engine.gpu.context import GpuWorker

COUNT = """#version 430
layout(local_size_x = 8) in;
layout(std430, binding = 0) buffer Counts { uint counts[]; };
uniform int u_n;
uniform int u_chunk;
uniform int u_chunk_size;
void main() {
    uint i = gl_GlobalInvocationID.x;
    int n = u_n - int(i) * 1000;              // lanes of one SIMD group with different lengths
    int k0 = min(u_chunk * u_chunk_size, n), k1 = min(k0 + u_chunk_size, n);
    uint c = 0u;
    for (int k = k0; k < k1; ++k) c += 1u;
    counts[i] += c;
}
"""


def _run(n: int, chunk: int):
    def job(worker, _job):
        ctx = worker.ctx
        prog = ctx.compute_shader(COUNT)
        buf = ctx.buffer(reserve=8 * 4)
        try:
            buf.write(np.zeros(8, np.uint32).tobytes())
            buf.bind_to_storage_buffer(0)
            chunks = loops.chunk_count(n, chunk)
            for k in range(chunks):
                for name, value in {"u_n": n, **loops.chunk_uniforms(k, chunks, chunk)}.items():
                    if name != "u_chunks":              # unused here
                        prog[name].value = value
                prog.run(1)
                ctx.memory_barrier()
            return np.frombuffer(buf.read(), np.uint32).copy(), ctx.info["GL_RENDERER"]
        finally:
            buf.release()
            prog.release()
    return GpuWorker.get().run(job)


def test_one_loop_past_the_limit_stops_there_on_llvmpipe_and_the_split_runs_it_all():
    n = 200_000
    expected = n - 1000 * np.arange(8)
    whole, renderer = _run(n, n)
    if "llvmpipe" in renderer:
        assert whole.max() <= loops.LOOP_LIMIT, whole          # the silent limit the split exists for
    split, _ = _run(n, loops.CHUNK)
    assert loops.chunk_count(n) == 13 and split.tolist() == expected.tolist()
