"""Splitting a long per-invocation loop over several dispatches.

Mesa's llvmpipe (the GL of CI and of every test here) ends a shader invocation's loops once they have run
LOOP_LIMIT iterations in all (LP_MAX_TGSI_LOOP_ITERATIONS in gallivm's lp_exec_endloop): one counter per SIMD
group of 8 invocations, shared by every loop not unrolled, in compute and fragment shaders alike. Past it
every loop runs at most once, silently. A shader whose loop can run longer numbers its iterations with one
flat index and runs only the share [u_chunk · u_chunk_size, (u_chunk + 1) · u_chunk_size) per dispatch;
these helpers size the split. Loops of constant length are unrolled by the compiler and do not count.
"""
from __future__ import annotations

LOOP_LIMIT = 65535
# Iterations one dispatch gives an invocation's split loop: a quarter of the limit, leaving room for the
# shader's other loops and for a SIMD group whose lanes run different loops back to back.
CHUNK = 16384


def chunk_count(worst: int, chunk: int = CHUNK) -> int:
    """Dispatches needed so that no invocation runs more than `chunk` of its `worst` iterations in one."""
    return max(1, -(-int(worst) // int(chunk)))


def chunk_uniforms(k: int, chunks: int, chunk: int = CHUNK) -> dict:
    """The uniforms of dispatch k of `chunks` (see the module docstring)."""
    return {"u_chunk": int(k), "u_chunks": int(chunks), "u_chunk_size": int(chunk)}
