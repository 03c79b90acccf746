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


def enable_compilation_cache() -> None:
    """Keep compiled programs on disk (SIMJAX_CACHE_DIR, default ~/.cache/simjax/jax), so a
    resumed or repeated run skips most of its compile time."""
    import jax

    cache = os.environ.get("SIMJAX_CACHE_DIR", str(Path.home() / ".cache" / "simjax" / "jax"))
    jax.config.update("jax_compilation_cache_dir", cache)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
