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


BFLOAT16_DOT_FLAGS = ("amx_bf16", "avx512_bf16")  # /proc/cpuinfo's names


def cpu_has_bfloat16_dots(cpuinfo: str = "/proc/cpuinfo") -> bool:
    """Whether this CPU multiplies bfloat16 in hardware: AMX's tiles (``amx_bf16``: Intel Sapphire
    Rapids and later) or AVX-512's bfloat16 dot products (``avx512_bf16``: also AMD Zen 4), as
    ``cpuinfo``'s flags say; False where they do not, or where there is no such file."""
    try:
        with open(cpuinfo) as f:
            return any(line.startswith("flags") and not set(BFLOAT16_DOT_FLAGS).isdisjoint(line.split())
                       for line in f)
    except OSError:
        return False


def command_default_precision() -> str:
    """``--precision`` where the training and sweep commands are given none: bfloat16 on a CPU
    that multiplies bfloat16 in hardware (SIM's training command ran 1.35x as fast on AMX, 1.30x
    on AVX-512 BF16, and the learning check (experiments/results/precision-check) found no change in what SIM learns:
    docs/usage.md#precision); highest (float32) elsewhere: a CPU without them converts bfloat16
    to float32 to multiply, and on a GPU bfloat16 has not been checked. ``TrainConfig``'s own
    default stays highest."""
    import jax

    return "bfloat16" if jax.default_backend() == "cpu" and cpu_has_bfloat16_dots() else "highest"


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
