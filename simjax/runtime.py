"""Process-wide JAX settings for the command lines, applied by their mains, never on import.

XLA runs with its default flags: the XLA:CPU deadlock that once needed flags and a restarting
supervisor came from batched LAPACK QRs in the seed-vmapped ``init`` and is gone at its source
(``simjax.networks.layers.orthogonal``; docs/troubleshooting.md).
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
