"""Flax modules: the observation encoder and the LSTM actor-critic (paper A.5)."""

from simjax.networks.actor_critic import ActorCritic, Encoder, ResetLSTM

__all__ = ["ActorCritic", "Encoder", "ResetLSTM"]
