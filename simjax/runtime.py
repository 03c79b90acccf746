"""JAX settings for the command lines, applied by their mains, never on import: the compilation
cache and the matmul precision a run was configured with.

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


# --precision -> JAX's jax_default_matmul_precision. JAX's own "bfloat16" is an alias of
# "default" (TF32 on NVIDIA GPUs), so bfloat16 is the dot algorithm that says so.
MATMUL_PRECISIONS = {"highest": "highest", "high": "high", "default": "default", "bfloat16": "BF16_BF16_F32"}


def matmul_precision(name: str):
    """A context in which JAX traces every float32 matmul and convolution at ``--precision``
    ``name`` (``MATMUL_PRECISIONS``): a thread-local setting, so it wins over
    JAX_DEFAULT_MATMUL_PRECISION and ``jax.config``'s global value, and leaves both as they
    were when it ends. Programs compiled inside it keep the precision they were traced with."""
    import jax

    if name not in MATMUL_PRECISIONS:
        raise ValueError(f"--precision must be one of {', '.join(MATMUL_PRECISIONS)}, got {name!r}")
    return jax.default_matmul_precision(MATMUL_PRECISIONS[name])
