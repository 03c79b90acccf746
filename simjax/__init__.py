"""simjax: curiosity-driven exploration for partially observable worlds, end to end in JAX.

Importing simjax changes nothing global: no XLA flags, no ``jax.config`` setting, no
computation (tested).
"""

__version__ = "0.1.0"
