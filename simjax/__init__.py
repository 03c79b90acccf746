"""simjax: curiosity-driven exploration for partially observable worlds, end to end in JAX.

Importing simjax configures the XLA:CPU runtime before any computation runs. jaxlib 0.10.2's
XLA:CPU sometimes never signals that a finished computation is done: the caller waits in
BlockUntilReady forever while every worker thread idles (gdb). On this 2-core VM the trigger
is the concurrency-optimised HLO scheduler: a jitted, seed-vmapped ``init`` hung in 12 of 13
runs with it and in 0 of 8 with ``--xla_cpu_enable_concurrency_optimized_scheduler=false``
(2026-11-24). The multi-threaded Eigen pool and asynchronous dispatch (public reports:
jax-ml/jax#25861, PyAutoFit#1530) are off too; they made the hang rarer but not gone.
``make train`` also restarts a stalled run from its checkpoint (simjax/train.py).
Set SIMJAX_KEEP_XLA_DEFAULTS=1 to leave all three alone.
"""

import os as _os

_XLA_FLAGS = (
    "--xla_cpu_enable_concurrency_optimized_scheduler=false",
    "--xla_cpu_multi_thread_eigen=false",
)

if not _os.environ.get("SIMJAX_KEEP_XLA_DEFAULTS"):
    _flags = _os.environ.get("XLA_FLAGS", "")
    for _flag in _XLA_FLAGS:
        if _flag.split("=")[0] not in _flags:
            _flags = (_flags + " " + _flag).strip()
    _os.environ["XLA_FLAGS"] = _flags
    import jax as _jax

    _jax.config.update("jax_cpu_enable_async_dispatch", False)

__version__ = "0.1.0"
