"""Layers shaped by what XLA:CPU runs fast.

``PatchConv`` is a 2-D convolution written as patch extraction + one matmul (im2col). On
XLA:CPU the gradient of ``lax.conv_general_dilated`` inside a ``while`` loop (which is what
every ``lax.scan`` over updates is) runs ~14x slower than outside one (measured: 4.4 s vs
0.31 s per step for conv 16 -> conv 32 over 1,344 frames); the im2col form's gradient is
slices, pads and matmuls, which stay fast in loops (0.25 s for the same step). Its parameters
have ``nn.Conv``'s names, shapes and initialisers, and its outputs match ``nn.Conv`` (tested).

``orthogonal`` is flax's orthogonal initialiser, drawn one member at a time under ``jax.vmap``.
Vmapped (over seeds, as every run initialises), flax's draws one batched LAPACK QR, and
jaxlib 0.10.2's batched QR splits its batch over XLA:CPU's intra-op thread pool and blocks a
pool thread until the parts are done: two such QRs side by side took both threads of a 2-core
machine and waited on each other forever, the XLA:CPU hang of docs/troubleshooting.md (a
seed-vmapped SIM ``init`` hung 4 times in 4 fresh processes with XLA's default flags). Drawn
member by member (a ``lax.map`` over the keys), each QR has a batch of one; the values are
flax's, bit for bit (tested).
"""

from __future__ import annotations

from collections.abc import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp


def orthogonal(scale: float = 1.0) -> nn.initializers.Initializer:
    """``nn.initializers.orthogonal(scale)``, whose vmapped calls draw member by member."""
    draw_one = nn.initializers.orthogonal(scale)

    def init(key, shape, dtype=jnp.float32):
        @jax.custom_batching.custom_vmap
        def draw(k):
            return draw_one(k, shape, dtype)

        @draw.def_vmap
        def draw_each(axis_size, in_batched, keys):  # the key is the only input, so it is the batched one
            return jax.lax.map(draw, keys), True

        return draw(key)

    return init


def extract_patches(x: jnp.ndarray, kernel: int, stride: int, padding: str) -> jnp.ndarray:
    """(..., H, W, C) -> (..., H', W', kernel*kernel*C), patch features ordered (ki, kj, c)."""
    h, w = x.shape[-3], x.shape[-2]
    if padding == "SAME":
        out_h, out_w = -(-h // stride), -(-w // stride)
        pad_h = max((out_h - 1) * stride + kernel - h, 0)
        pad_w = max((out_w - 1) * stride + kernel - w, 0)
        widths = [(0, 0)] * (x.ndim - 3) + [(pad_h // 2, pad_h - pad_h // 2), (pad_w // 2, pad_w - pad_w // 2), (0, 0)]
        x = jnp.pad(x, widths)
    elif padding == "VALID":
        out_h, out_w = (h - kernel) // stride + 1, (w - kernel) // stride + 1
    else:
        raise ValueError(f"padding must be 'SAME' or 'VALID', got {padding!r}")
    cols = [
        x[..., i : i + stride * (out_h - 1) + 1 : stride, j : j + stride * (out_w - 1) + 1 : stride, :]
        for i in range(kernel)
        for j in range(kernel)
    ]
    return jnp.concatenate(cols, axis=-1)


class PatchConv(nn.Module):
    """A square-kernel convolution as im2col + matmul; drop-in for ``nn.Conv`` on (..., H, W, C)."""

    features: int
    kernel: int = 3
    stride: int = 1
    padding: str = "SAME"
    kernel_init: nn.initializers.Initializer = nn.initializers.lecun_normal()
    bias_init: nn.initializers.Initializer = nn.initializers.zeros_init()

    @nn.compact
    def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
        c_in = x.shape[-1]
        kernel = self.param("kernel", self.kernel_init, (self.kernel, self.kernel, c_in, self.features))
        bias = self.param("bias", self.bias_init, (self.features,))
        patches = extract_patches(x, self.kernel, self.stride, self.padding)
        return patches @ kernel.reshape(-1, self.features) + bias


def conv_stack(x: jnp.ndarray, features: Sequence[int], kernel: int = 3, stride: int = 2) -> jnp.ndarray:
    """ReLU(PatchConv) layers in sequence, as the paper's encoders use them."""
    for f in features:
        x = nn.relu(PatchConv(f, kernel, stride)(x))
    return x
