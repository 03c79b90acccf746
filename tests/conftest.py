"""One persistent compilation cache per test session, shared by the xdist workers.

Many tests compile the same program (a module's fixture in both workers, a run and its resume,
a trainer whose only change is a traced hyperparameter); with the cache on from the first
compile each is built once per session. It lives in a temporary folder, removed at the end, so
every session compiles from scratch as CI does and the user's own cache (~/.cache/simjax) is
never written by the tests. JAX decides whether a process uses the cache at its first compile,
so this runs before any test imports compile anything.
"""

import os
import shutil
import tempfile

_OWNER = "SIMJAX_TEST_CACHE_OWNER"


def pytest_configure(config):
    # the controller (or a plain run) makes the folder; xdist workers inherit its environment
    if not hasattr(config, "workerinput") and "SIMJAX_CACHE_DIR" not in os.environ:
        os.environ["SIMJAX_CACHE_DIR"] = tempfile.mkdtemp(prefix="simjax-test-jax-cache-")
        os.environ[_OWNER] = str(os.getpid())
    import jax

    jax.config.update("jax_compilation_cache_dir", os.environ["SIMJAX_CACHE_DIR"])
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 1.0)


def pytest_unconfigure(config):
    if os.environ.get(_OWNER) == str(os.getpid()):
        shutil.rmtree(os.environ.pop("SIMJAX_CACHE_DIR"), ignore_errors=True)
        del os.environ[_OWNER]
