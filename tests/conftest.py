"""One persistent compilation cache per test session, shared by the xdist workers.

Some tests compile a program another has compiled (a module's fixture in both workers, a run
and its resume, a trainer whose only change is a traced hyperparameter); with the cache on from
the first compile, the later one can load it. The folder is temporary and removed at the end,
so every session compiles from scratch as CI does, and the tests never write the user's cache
(~/.cache/simjax; a SIMJAX_CACHE_DIR set by the caller is used as given and kept). JAX decides
whether a process uses a cache at its first compile, so this runs before any test compiles.
"""

import os
import shutil
import tempfile

import pytest

_OWNER = "SIMJAX_TEST_CACHE_OWNER"


def pytest_configure(config):
    _check_loadgroup(config)
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


def _check_loadgroup(config):
    """Tests marked xdist_group share a worker so that one compiles what the others load from
    the cache. pytest-xdist groups them by appending the group to ``item._nodeid``; a pytest
    whose ``nodeid`` is read from elsewhere (9.2) would spread them silently."""
    if hasattr(config, "workerinput") or config.getoption("dist", default=None) != "loadgroup":
        return
    probe = type("Probe", (), {"_nodeid": "test@group"})()
    try:
        grouped = pytest.Item.nodeid.fget(probe) == "test@group"
    except AttributeError:
        grouped = False
    if not grouped:
        raise pytest.UsageError(f"--dist loadgroup cannot group tests with this pytest ({pytest.__version__}): "
                                "pytest-xdist tags a test's group in item._nodeid; see pyproject.toml's pin")
