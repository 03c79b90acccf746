"""simjax: curiosity-driven exploration for partially observable worlds, end to end in JAX.

Importing simjax configures the XLA:CPU runtime before any computation runs: XLA:CPU's
multi-threaded Eigen pool and its asynchronous dispatch can each leave a vmapped training
step waiting forever for its result (seen here: 2 hangs in 6 runs of the same program;
0 in 26 with them off; public reports: jax-ml/jax#25861, PyAutoFit#1530). Turning them off
makes the hang rarer, not impossible (README, "Known problem"). Neither costs measurable
speed here (training loop: 4,165 vs 4,265 agent steps/s).
Set SIMJAX_KEEP_XLA_DEFAULTS=1 to leave both alone.
"""

import os as _os

if not _os.environ.get("SIMJAX_KEEP_XLA_DEFAULTS"):
    _flags = _os.environ.get("XLA_FLAGS", "")
    if "xla_cpu_multi_thread_eigen" not in _flags:
        _os.environ["XLA_FLAGS"] = (_flags + " --xla_cpu_multi_thread_eigen=false").strip()
    import jax as _jax

    _jax.config.update("jax_cpu_enable_async_dispatch", False)

__version__ = "0.1.0"
