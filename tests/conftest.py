"""The test process gets the XLA:CPU settings the command lines apply (``simjax.runtime``):
pytest imports this file before any test module, so before anything is computed."""

from simjax import runtime

runtime.configure()
