"""simjax: curiosity-driven exploration for partially observable worlds, end to end in JAX.

Importing simjax changes nothing global; the command lines apply the process-wide JAX
settings they need with ``simjax.runtime.configure()``.
"""

__version__ = "0.1.0"
