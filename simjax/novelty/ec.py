"""Episodic Curiosity (EC; Savinov et al. 2019, "Episodic Curiosity through Reachability"), the
SIM paper's fourth baseline (appendix A.4), behind the same ``Novelty`` interface as SIM, RND, ICM.

A *reachability network* R says whether two frames are a few steps apart. Each environment keeps
an *episodic memory* of the frames of its current episode that R found novel; the bonus of a
frame is how unlike every remembered frame it is:

    C(M, e)  = the 90th percentile of R(e, m) over the memory's slots m
    bonus    = alpha * (beta - C(M, e))        (0 for an episode's first frame)
    the frame joins the memory when C(M, e) < threshold; at an episode's start the memory is
    emptied and the first frame stored.

The network, as the SIM paper states it (A.4): a ResNet-18 embedding with 512 outputs of each
frame, the two embeddings concatenated, fc 512 (ReLU), fc 2, softmax; P(class 1) is "reachable".
It is cheap to run against a memory because the first fc splits over the pair,
``W [e1; e2] + b = (W1 e1 + b) + W2 e2``: a slot stores its frame's ``W2 e`` once, and a new
frame costs one embedding, one ``W1 e`` and, per slot, an add, a ReLU and the 512x2 output layer.

Every value below that the SIM paper leaves open is the original code's
(google-research/episodic-curiosity, read at commit 2bdc10dd):

=====================================  =========  ==========================================
value                                  here       source
=====================================  =========  ==========================================
embedding size                         512        third_party/keras_resnet/models.py
                                                  (EMBEDDING_DIM); SIM paper A.4 ("512 outputs")
ResNet-18 layout                       64-128-    models.py ``build_resnet_18``: conv 7x7 s2 64,
                                       256-512    max-pool 3x3 s2, [2, 2, 2, 2] pre-activation
                                                  basic blocks, global average pool, fc 512
comparator                             fc 512,    SIM paper A.4 (the original's top network is
                                       fc 2       BN-ReLU then four fc 512, models.py
                                                  ``_top_network``; the paper's text is followed)
memory capacity per environment        200        scripts/launcher_script.py
                                                  (EpisodicMemory.capacity) and the
                                                  ``EpisodicMemory`` default
replacement when full                  random     launcher_script.py (EpisodicMemory.replacement
                                       slot       'random'; the class default is 'fifo')
similarity aggregation                 90th       launcher_script.py ('percentile');
                                       percentile episodic_memory.py ``similarity_to_memory``
                                                  (np.percentile(similarities, 90), linear)
empty memory's similarity              0          episodic_memory.py ``similarity_to_memory``
bonus offset beta                      0.5        curiosity_env_wrapper.py ``0.5 - s``; the EC
                                                  paper (sec. 2.2): 0.5 for fixed-duration
                                                  episodes, 1 where an episode can end early
                                                  (``--ec-beta``)
add-to-memory rule                     s < 0.5    curiosity_env_wrapper.py (similarity_threshold
                                                  0.5, strict ``<``); at ``done`` the memory is
                                                  reset and the first frame always added, bonus 0
bonus scale alpha                      0.01       SIM paper table B.2 (EC, ViZDoom: bonus reward
                                                  scale 0.01; ``PAPER_BONUS_SCALE``). The
                                                  original's DMLab value is 0.03017241379310345
                                                  (launcher_script.py, scale_surrogate_reward)
positive pairs: at most k steps apart  k = 5      constants.py (MAX_ACTION_DISTANCE)
negative pairs: more than m*k apart    m = 5      constants.py (NEGATIVE_SAMPLE_MULTIPLIER): the
                                                  sampler excludes [i - 25, i + 25]
                                                  (r_network_training.py
                                                  ``generate_negative_example``)
label balance, pair order              1:1,       r_network_training.py (``random.randint(0, 1)``
                                       random     label; positives swapped with p 0.5)
R training batch, optimiser            64, Adam   constants.py (BATCH_SIZE, ADAM_PARAMS: lr 1e-4,
                                       1e-4       betas 0.9 / 0.999, epsilon 1e-8)
pretraining budget                     0.6M env   SIM paper section 3.1 (curves shifted by it)
                                       steps
=====================================  =========  ==========================================

Differences from the original, and why:

* No batch normalisation: the network is stateless, the same at pretraining and inference, and
  trains inside one compiled function without a batch-statistics collection. In its place the
  last convolution of every residual branch starts at zero (the "zero-gamma" / SkipInit
  initialisation), so each block starts as its shortcut and the 18 layers train without it.
* Frames are read as pixels / 255 (the original fed raw pixels to a network that began with
  batch normalisation); EC ignores ``obs_norm``, whose running statistics would move under a
  network trained once and then fixed.
* ECO (online training, ``online=True``) trains R jointly with the policy, by the learner's one
  Adam, on pairs drawn from each environment's last ``window`` + T frames (the model's frame
  memory), one pair per 4 agent steps (the v2 sampler's rate), instead of the original's
  10 epochs over the last 60k observations every 60k steps. Memory slots keep the ``W2 e`` they
  were stored with while R moves (the original keeps the embedding, just as stale, and applies
  the current top network).
"""

from __future__ import annotations

import dataclasses
from typing import ClassVar, NamedTuple

import flax.linen as nn
import jax
import jax.numpy as jnp

from simjax.networks.layers import Dense, PatchConv, max_pool
from simjax.novelty.base import Timeline, masked_mean, to_unit

# the original code's values (see the table above)
CAPACITY = 200
PERCENTILE = 90.0
BETA = 0.5
THRESHOLD = 0.5
MAX_ACTION_DISTANCE = 5  # k
NEGATIVE_MULTIPLIER = 5  # negatives are more than k * m steps apart
BATCH_SIZE = 64
LEARNING_RATE = 1e-4
ADAM_EPS = 1e-8
EMBEDDING = 512
WIDTH = 64  # filters of the first ResNet stage (64, 128, 256, 512)


# ------------------------------------------------------------------------------------- networks

class BasicBlock(nn.Module):
    """A pre-activation basic block (He et al. 2016b, as EC's keras_resnet): relu-conv 3x3 (stride)
    -> relu-conv 3x3, plus the shortcut (1x1 conv where the shape changes)."""

    features: int
    stride: int = 1
    first: bool = False  # the network's first block: its input was just activated and pooled

    @nn.compact
    def __call__(self, x):
        he = nn.initializers.he_normal()
        h = x if self.first else nn.relu(x)
        h = PatchConv(self.features, 3, self.stride, kernel_init=he)(h)
        h = PatchConv(self.features, 3, 1, kernel_init=nn.initializers.zeros_init())(nn.relu(h))
        if self.stride > 1 or x.shape[-1] != self.features:
            x = PatchConv(self.features, 1, self.stride, "VALID", kernel_init=he)(x)
        return x + h


class ResNet18(nn.Module):
    """EC's ResNet-18 embedding: conv 7x7 s2 -> max-pool 3x3 s2 -> [2, 2, 2, 2] basic blocks of
    width, 2 width, 4 width, 8 width (stride 2 from the second stage) -> relu -> global average
    pool -> fc ``features`` (linear). 42x42 frames: 21, 11, 11, 6, 3, 2 pixels across."""

    width: int = WIDTH
    features: int = EMBEDDING

    @nn.compact
    def __call__(self, x):
        x = nn.relu(PatchConv(self.width, 7, 2, kernel_init=nn.initializers.he_normal())(x))
        x = max_pool(x)
        for stage in range(4):
            for block in range(2):
                stride = 2 if (stage > 0 and block == 0) else 1
                x = BasicBlock(self.width * 2**stage, stride, first=(stage == 0 and block == 0))(x)
        x = jnp.mean(nn.relu(x), axis=(-3, -2))
        return Dense(self.features, kernel_init=nn.initializers.he_normal())(x)


class ReachabilityNet(nn.Module):
    """R(x1, x2): the embedding of both frames, concatenated, fc ``hidden`` (ReLU), fc 2. The
    first fc is kept as its two halves (``first`` on e1 with the bias, ``second`` on e2)."""

    width: int = WIDTH
    features: int = EMBEDDING
    hidden: int = EMBEDDING

    def setup(self):
        self.embedding = ResNet18(self.width, self.features)
        self.first = Dense(self.hidden, name="first")
        self.second = Dense(self.hidden, use_bias=False, name="second")
        self.out = Dense(2, name="out")

    def embed(self, frames):
        """(..., h, w, c) frames in [0, 1] -> (..., features)."""
        return self.embedding(frames)

    def halves(self, e):
        """The first fc's two halves of embeddings e: (W1 e + b, W2 e)."""
        return self.first(e), self.second(e)

    def head(self, a, b):
        """Logits (..., 2) of a pair from its halves: a = W1 e1 + b, b = W2 e2 (broadcast)."""
        return self.out(nn.relu(a + b))

    def __call__(self, x1, x2):
        """Logits (B, 2) of frame pairs (B, h, w, c) each; both embedded in one batch."""
        e = self.embed(jnp.concatenate([x1, x2], axis=0))
        e1, e2 = jnp.split(e, 2, axis=0)
        return self.head(self.first(e1), self.second(e2))


def similarity(logits: jnp.ndarray) -> jnp.ndarray:
    """P(reachable) = softmax(logits)[..., 1]."""
    return jax.nn.softmax(logits, axis=-1)[..., 1]


def pair_loss(logits, labels, mask):
    """Cross-entropy of the pair classifier and its accuracy, over the pairs where ``mask``."""
    ce = -jnp.take_along_axis(jax.nn.log_softmax(logits), labels[..., None].astype(jnp.int32), axis=-1)[..., 0]
    correct = (jnp.argmax(logits, axis=-1) == labels).astype(jnp.float32)
    return masked_mean(ce, mask), masked_mean(correct, mask)


# -------------------------------------------------------------------------------- pair sampling

def episode_bounds(segment: jnp.ndarray, valid: jnp.ndarray):
    """(L,) first and last index of each position's run of equal ``segment`` (its episode, as far
    as the sequence shows it); invalid positions are their own one-frame runs."""
    L = segment.shape[0]
    idx = jnp.arange(L)
    prev_differs = jnp.concatenate([jnp.ones((1,), bool), segment[1:] != segment[:-1]]) | ~valid
    prev_differs = prev_differs | jnp.concatenate([jnp.ones((1,), bool), ~valid[:-1]])
    next_differs = jnp.concatenate([prev_differs[1:], jnp.ones((1,), bool)])
    start = jax.lax.cummax(jnp.where(prev_differs, idx, 0))
    end = jax.lax.cummin(jnp.where(next_differs, idx, L - 1), reverse=True)
    return start, end


def sample_pair(key, start, end, valid, k: int = MAX_ACTION_DISTANCE, multiplier: int = NEGATIVE_MULTIPLIER):
    """One training pair (i, j, label, ok) from a sequence of L frames with episode bounds
    ``start``/``end`` (``episode_bounds``), as EC's R-network training samples them
    (r_network_training.py): an anchor i anywhere, label 1 or 0 with probability 1/2; a positive
    j = i +- d, d uniform in 1..k, within the episode; a negative j uniform over the episode's
    frames outside [i - m k, i + m k]; the pair's order random. ``ok`` is false where the anchor's
    episode has no such j (or the anchor is no real frame): such pairs are masked out."""
    L = start.shape[0]
    k_i, k_label, k_d, k_sign, k_neg, k_swap = jax.random.split(key, 6)
    i = jax.random.randint(k_i, (), 0, L)
    lo, hi = start[i], end[i]
    label = jax.random.bernoulli(k_label).astype(jnp.int32)
    # positive: one side, else the other
    d = jax.random.randint(k_d, (), 1, k + 1)
    sign = jnp.where(jax.random.bernoulli(k_sign), 1, -1)
    j1, j2 = i + sign * d, i - sign * d
    ok1, ok2 = (j1 >= lo) & (j1 <= hi), (j2 >= lo) & (j2 <= hi)
    j_pos, ok_pos = jnp.where(ok1, j1, j2), ok1 | ok2
    # negative: uniform over the episode minus the excluded interval around i
    gap = multiplier * k
    ex_lo, ex_hi = jnp.maximum(i - gap, lo), jnp.minimum(i + gap, hi)
    left, right = ex_lo - lo, hi - ex_hi  # frames on either side of the excluded interval
    total = left + right
    r = jax.random.randint(k_neg, (), 0, jnp.maximum(total, 1))
    j_neg, ok_neg = jnp.where(r < left, lo + r, ex_hi + 1 + (r - left)), total > 0
    j = jnp.where(label == 1, j_pos, j_neg)
    ok = jnp.where(label == 1, ok_pos, ok_neg) & valid[i]
    j = jnp.clip(j, 0, L - 1)
    swap = jax.random.bernoulli(k_swap)
    return jnp.where(swap, j, i), jnp.where(swap, i, j), label, ok


# ------------------------------------------------------------------------------- episodic memory

class ECState(NamedTuple):
    """Each environment's episodic memory (leading axis: environment)."""

    slots: jnp.ndarray  # (N, capacity, hidden) float32: W2 e of each stored frame
    count: jnp.ndarray  # (N,) int32: slots in use (the first ``count``), at most capacity
    key: jnp.ndarray  # (N, 2) uint32: draws the slot a full memory replaces


def percentile(values: jnp.ndarray, count: jnp.ndarray, q: float = PERCENTILE) -> jnp.ndarray:
    """``np.percentile(values[:count], q)`` (linear interpolation) of a (C,) buffer whose first
    ``count`` entries are in use; 0 for an empty one (EC's similarity to an empty memory)."""
    C = values.shape[-1]
    n = jnp.clip(count, 1, C)
    ordered = jnp.sort(jnp.where(jnp.arange(C) < n, values, jnp.inf))
    pos = (q / 100.0) * (n - 1).astype(jnp.float32)
    lo = jnp.floor(pos).astype(jnp.int32)
    hi = jnp.minimum(lo + 1, n - 1)
    v_lo, v_hi = ordered[lo], ordered[hi]
    return jnp.where(count > 0, v_lo + (pos - lo) * (v_hi - v_lo), 0.0)


def memory_step(slots, count, key, a, b, start, head, beta: float = BETA, threshold: float = THRESHOLD):
    """One frame of one environment against its memory. ``a``/``b``: the frame's halves (hidden,);
    ``head(a, slots)`` -> logits (C, 2); ``start``: the frame begins an episode.
    Returns (slots, count, key, novelty beta - C(M, e) (0 at a start), similarity C(M, e))."""
    C = slots.shape[0]
    s = percentile(similarity(head(a[None], slots)), count)
    novelty = jnp.where(start, 0.0, beta - s)
    add = start | (s < threshold)
    count = jnp.where(start, 0, count)
    key, sub = jax.random.split(key)
    index = jnp.where(count < C, count, jax.random.randint(sub, (), 0, C))
    slots = slots.at[index].set(jnp.where(add, b, slots[index]))
    count = jnp.where(add, jnp.minimum(count + 1, C), count)
    return slots, count, key, novelty, s


def scan_memory(state: ECState, a, b, starts, head, beta: float = BETA):
    """A rollout's frames against the memories, one step after another (``lax.scan`` over T,
    ``vmap`` over the N environments). ``a``/``b``: the frames' halves (T, N, hidden); ``starts``
    (T, N): the frame begins an episode. Returns (state, novelty (T, N), similarity (T, N))."""
    step_env = jax.vmap(lambda sl, c, k, a_, b_, st: memory_step(sl, c, k, a_, b_, st, head, beta))

    def step(carry, xs):
        slots, count, key, novelty, s = step_env(*carry, *xs)
        return (slots, count, key), (novelty, s)

    carry, (novelty, sims) = jax.lax.scan(step, tuple(state), (a, b, starts))
    return ECState(*carry), novelty, sims


# ----------------------------------------------------------------------------------- the model

@dataclasses.dataclass(frozen=True)
class EC:
    """EC as a ``Novelty`` model with a per-environment state (``stateful``): ``init_state``
    starts each environment's memory with its first frame, ``apply_with_state`` scores a rollout's
    frames one after another (``lax.scan`` over T, the memory changing within the rollout).

    R is trained before the run (``simjax.novelty.ec_pretrain``) and then fixed (EC): its loss
    is 0. With ``online`` (ECO) it also trains on pairs from each environment's recent frames.
    """

    num_actions: int
    capacity: int = CAPACITY
    width: int = WIDTH
    features: int = EMBEDDING
    online: bool = False
    beta: float = BETA  # the bonus's offset: alpha * (beta - similarity)
    window: int = 64  # ECO: frames each environment keeps across rollouts to draw pairs from

    stateful: ClassVar[bool] = True

    @property
    def history(self) -> int:
        return self.window if self.online else 0

    @property
    def trainable(self) -> bool:
        """EC's network is fixed after pretraining; ECO's trains with the policy."""
        return self.online

    def net(self) -> ReachabilityNet:
        return ReachabilityNet(self.width, self.features, self.features)

    def init(self, key, tl: Timeline, x=None):
        frames = to_unit(tl.frames[-1])  # (N, h, w, c)
        return {"r": self.net().init(key, frames[:1], frames[:1])}

    def embed_halves(self, params, frames):
        """uint8 (or float) frames (..., h, w, c) -> the halves (W1 e + b, W2 e), each (..., hidden)."""
        net = self.net()
        e = net.apply(params["r"], to_unit(frames), method=ReachabilityNet.embed)
        return net.apply(params["r"], e, method=ReachabilityNet.halves)

    def init_state(self, params, obs, key) -> ECState:
        """Every environment's memory holding its first frame ``obs`` (N, h, w, c)."""
        n = obs.shape[0]
        _, b = self.embed_halves(params, obs)
        slots = jnp.zeros((n, self.capacity, b.shape[-1]), jnp.float32).at[:, 0].set(b)
        return ECState(slots, jnp.ones((n,), jnp.int32), jax.random.split(key, n))

    def restart(self, params, state: ECState, obs) -> ECState:
        """The memories emptied and started again from ``obs`` with ``params`` (after pretraining)."""
        return self.init_state(params, obs, state.key[0])._replace(key=state.key)

    def apply(self, params, tl: Timeline, x=None, hyper=None):
        raise TypeError("EC keeps an episodic memory per environment: call apply_with_state")

    def apply_with_state(self, params, state: ECState, tl: Timeline, x=None, hyper=None):
        """(error (T, N), scored (T, N), loss, metrics, state): error is beta - C(M, e) of each
        target frame o_{t+1}, free of gradients; scored is false where o_{t+1} starts an episode.
        ``hyper`` (a ``NoveltyHyper``) is not read here: alpha, EC's bonus scale, is its
        ``bonus_scale``, which ``Novelty`` applies as every model's beta (so a sweep varies it);
        lambda, H and L mean nothing for EC."""
        m = tl.history
        fixed = jax.lax.stop_gradient(params)
        net = self.net()
        frames = tl.frames[m + 1 :]  # o_1 ... o_T, (T, N, h, w, c): each embedded once
        a, b = self.embed_halves(fixed, frames)
        starts = tl.segment[m + 1 :] != tl.segment[m:-1]  # (T, N)

        def head(a_, slots):
            return net.apply(fixed["r"], a_, slots, method=ReachabilityNet.head)

        state, novelty, _ = scan_memory(state, a, b, starts, head, self.beta)
        scored = ~starts
        loss = jnp.zeros(())
        if self.online:
            loss, _, key = self.online_loss(params, tl, state.key)
            state = state._replace(key=key)
        metrics = {"forward_loss": loss, "inverse_loss": jnp.zeros(())}
        return jax.lax.stop_gradient(novelty), scored, loss, metrics, state

    def online_loss(self, params, tl: Timeline, keys):
        """ECO: R's cross-entropy on pairs drawn from each environment's timeline (its last
        ``window`` frames and this rollout's), one pair per 4 agent steps."""
        T, N = tl.num_targets, tl.frames.shape[1]
        per_env = max(1, T // 4)
        split = jax.vmap(lambda k: jax.random.split(k, per_env + 1))(keys)  # (N, P+1, 2)
        new_keys, pair_keys = split[:, 0], split[:, 1:]

        def env_pairs(keys_n, segment, valid):
            start, end = episode_bounds(segment, valid)
            return jax.vmap(lambda k: sample_pair(k, start, end, valid))(keys_n)

        i, j, label, ok = jax.vmap(env_pairs)(pair_keys, tl.segment.T, tl.valid.T)  # (N, P)
        env = jnp.broadcast_to(jnp.arange(N)[:, None], i.shape)
        x1 = to_unit(tl.frames[i.reshape(-1), env.reshape(-1)])
        x2 = to_unit(tl.frames[j.reshape(-1), env.reshape(-1)])
        logits = self.net().apply(params["r"], x1, x2)
        loss, accuracy = pair_loss(logits, label.reshape(-1), ok.reshape(-1))
        return loss, accuracy, new_keys
