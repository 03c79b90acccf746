"""Timing helpers shared by the benchmarks: compile once, run several times, report the median."""

from __future__ import annotations

import statistics
import time

import jax


def time_call(fn, *args, repeats: int = 5):
    """(compile seconds, median seconds per call, all timings) of a jitted ``fn(*args)``."""
    t0 = time.perf_counter()
    compiled = jax.jit(fn).lower(*args).compile()
    compile_s = time.perf_counter() - t0
    jax.block_until_ready(compiled(*args))  # warm-up
    times = []
    for _ in range(repeats):
        t0 = time.perf_counter()
        jax.block_until_ready(compiled(*args))
        times.append(time.perf_counter() - t0)
    return compile_s, statistics.median(times), times
