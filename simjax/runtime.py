"""Process-wide JAX settings, applied by the entry points (commands, experiments, tests), never
on import: a library that changed ``XLA_FLAGS`` or ``jax.config`` when imported would change
the programs of whoever imports it.

``configure()`` works around an XLA:CPU hang in jaxlib 0.10.2: now and then it never signals
that a finished computation is done, and the caller waits in BlockUntilReady forever while
every worker thread idles (gdb). On a 2-core VM the trigger is the concurrency-optimised HLO
scheduler: a jitted, seed-vmapped ``init`` hung in 12 of 13 runs with it and in 0 of 8 with
``--xla_cpu_enable_concurrency_optimized_scheduler=false``. The multi-threaded Eigen pool and
asynchronous dispatch (public reports: jax-ml/jax#25861, PyAutoFit#1530) are turned off too;
that made the hang rarer but not gone, so ``python -m simjax.train`` also restarts a stalled
run from its checkpoint (``simjax.runs.stall``). Set SIMJAX_KEEP_XLA_DEFAULTS=1 to leave all
three alone.

``split_cpu()`` (called by the commands, ``simjax.train`` and ``simjax.sweep``) makes one XLA
CPU device per core, over which a run's members are sharded; 2 seeds of SIM trained 1.06x as
fast on two devices as on one here (BENCHMARKS.md, 2026-11-27).
"""

from __future__ import annotations

import os
from pathlib import Path

XLA_FLAGS = (
    "--xla_cpu_enable_concurrency_optimized_scheduler=false",
    "--xla_cpu_multi_thread_eigen=false",
)


def configure() -> None:
    """Apply the XLA:CPU workaround to this process (unless SIMJAX_KEEP_XLA_DEFAULTS is set).

    Call it before the first computation: XLA reads ``XLA_FLAGS`` when its CPU backend starts.
    Flags already in ``XLA_FLAGS`` keep the value given there."""
    if os.environ.get("SIMJAX_KEEP_XLA_DEFAULTS"):
        return
    flags = os.environ.get("XLA_FLAGS", "")
    for flag in XLA_FLAGS:
        if flag.split("=")[0] not in flags:
            flags = (flags + " " + flag).strip()
    os.environ["XLA_FLAGS"] = flags
    import jax

    jax.config.update("jax_cpu_enable_async_dispatch", False)


def split_cpu(devices: int | None = None) -> None:
    """Make this machine's CPU ``devices`` XLA devices (default: SIMJAX_CPU_DEVICES, else one
    per core), so that a run's members (seeds, sweep points) shard over the cores
    (``simjax.runs.training``). With the single-threaded Eigen pool above, one device computes
    on one core. Call it before the first computation; a device count already in
    ``XLA_FLAGS`` is kept. Other platforms (GPUs) are not affected."""
    flags = os.environ.get("XLA_FLAGS", "")
    if "--xla_force_host_platform_device_count" in flags:
        return
    count = devices or int(os.environ.get("SIMJAX_CPU_DEVICES", os.cpu_count() or 1))
    os.environ["XLA_FLAGS"] = (flags + f" --xla_force_host_platform_device_count={count}").strip()


def enable_compilation_cache() -> None:
    """Keep compiled programs on disk (SIMJAX_CACHE_DIR, default ~/.cache/simjax/jax), so a
    resumed or repeated run skips most of its compile time."""
    import jax

    cache = os.environ.get("SIMJAX_CACHE_DIR", str(Path.home() / ".cache" / "simjax" / "jax"))
    jax.config.update("jax_compilation_cache_dir", cache)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
