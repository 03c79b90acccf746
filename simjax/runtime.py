"""JAX settings for the command lines, applied by their mains, never on import: the compilation
cache and the matmul precision a run was configured with.

XLA runs with its default flags: the XLA:CPU deadlock that once needed flags and a restarting
supervisor came from batched LAPACK QRs in the seed-vmapped ``init`` and is gone at its source
(``simjax.networks.layers.orthogonal``; docs/troubleshooting.md).
"""

from __future__ import annotations

import contextlib
import os
from pathlib import Path


def enable_compilation_cache() -> None:
    """Keep compiled programs on disk (SIMJAX_CACHE_DIR, default ~/.cache/simjax/jax), so a
    resumed or repeated run skips most of its compile time."""
    import jax

    cache = os.environ.get("SIMJAX_CACHE_DIR", str(Path.home() / ".cache" / "simjax" / "jax"))
    jax.config.update("jax_compilation_cache_dir", cache)
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)


# --precision -> JAX's jax_default_matmul_precision for every float32 product, and the operand
# dtype of the networks' products (simjax.networks.layers.matmul_operands). bfloat16 is
# bfloat16 operands summed in float32 in the networks (the CPU's AMX units and a GPU's tensor
# cores take them as they are; JAX's dot-algorithm setting does not reach AMX) and float32
# products everywhere else (the renderer's geometry), under a JAX setting of its own that keeps
# jit's cache apart (layers.BFLOAT16_JAX_PRECISION).
MATMUL_PRECISIONS = {"highest": "highest", "high": "high", "default": "default", "bfloat16": "float32"}  # = BFLOAT16_JAX_PRECISION


def matmul_precision(name: str):
    """A context in which JAX traces every float32 matmul and convolution at ``--precision``
    ``name`` (``MATMUL_PRECISIONS``) and the networks' products with bfloat16 operands where
    ``name`` is bfloat16: thread-local settings, so they win over JAX_DEFAULT_MATMUL_PRECISION
    and ``jax.config``'s global value, and leave both as they were when it ends. Programs
    compiled inside it keep the precision they were traced with."""
    import jax
    import jax.numpy as jnp

    from simjax.networks.layers import matmul_operands

    if name not in MATMUL_PRECISIONS:
        raise ValueError(f"--precision must be one of {', '.join(MATMUL_PRECISIONS)}, got {name!r}")
    stack = contextlib.ExitStack()
    stack.enter_context(matmul_operands(jnp.bfloat16 if name == "bfloat16" else jnp.float32))
    stack.enter_context(jax.default_matmul_precision(MATMUL_PRECISIONS[name]))
    return stack
