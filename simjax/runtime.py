"""Process-wide JAX settings for the command lines, applied by their mains, never on import.

XLA runs with its default flags. An XLA:CPU hang that once made simjax turn off XLA's
multi-threaded Eigen pool, its concurrency-optimised scheduler and asynchronous dispatch, and
guard every run with a restarting supervisor, was a deadlock in jaxlib 0.10.2's batched LAPACK
QR under a seed-vmapped ``init``; the members are now initialised one at a time
(``simjax.agents.init_members``), and the hang experiment of docs/troubleshooting.md saw no
hang with the defaults since.
"""

from __future__ import annotations

import os
from pathlib import Path


def enable_compilation_cache() -> None:
    """Keep compiled programs on disk (SIMJAX_CACHE_DIR, default ~/.cache/simjax/jax), so a
    resumed or repeated run skips most of its compile time."""
    import jax

    cache = os.environ.get("SIMJAX_CACHE_DIR", str(Path.home() / ".cache" / "simjax" / "jax"))
    jax.config.update("jax_compilation_cache_dir", cache)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)
