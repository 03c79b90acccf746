"""Layers shaped by what XLA:CPU runs fast.

``PatchConv`` is a 2-D convolution written as patch extraction + one matmul (im2col). On
XLA:CPU the gradient of ``lax.conv_general_dilated`` inside a ``while`` loop (which is what
every ``lax.scan`` over updates is) runs ~14x slower than outside one (measured: 4.4 s vs
0.31 s per step for conv 16 -> conv 32 over 1,344 frames); the im2col form's gradient is
slices, pads and matmuls, which stay fast in loops (0.25 s for the same step). Its parameters
have ``nn.Conv``'s names, shapes and initialisers, and its outputs match ``nn.Conv`` (tested).
``conv_stack`` runs its layers in the CHWN layout (channels, height, width, then the batch):
there every patch and its gradient move whole batch rows, not C-float pieces.

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

import contextlib
import contextvars
import functools
import itertools
import math
from collections.abc import Callable, Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp
import numpy as np


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


# The operand dtype of every network matmul (``--precision``): float32, or bfloat16 operands
# summed in float32. Read when a program is traced. jit's cache keys on JAX's own matmul
# precision, not on this setting, so ``matmul_operands`` sets that too: bfloat16 operands trace
# under JAX's "float32" (HIGHEST under a name of its own, for the float32 products outside the
# networks, such as the renderer's), float32 ones under "highest", and a program traced with one
# is not reused for the other. (The dot algorithm F32_F32_F32 would be a name no one else uses,
# but XLA:CPU runs products that name an algorithm off its fast path: SIM's loop at 1,118
# against 1,692 agent steps/s.)
_OPERANDS: contextvars.ContextVar = contextvars.ContextVar("simjax_matmul_operands", default=jnp.float32)
BFLOAT16_JAX_PRECISION = "float32"


@contextlib.contextmanager
def matmul_operands(dtype):
    """Within it, ``matmul`` (every Dense, PatchConv and LSTM product of simjax's networks) casts
    its operands to ``dtype`` (float32 or bfloat16) and sums in float32. JAX's matmul precision
    is "float32" with bfloat16 operands and "highest" with float32 ones, the same products under
    two names; ``simjax.runtime.matmul_precision`` sets its own on top of the latter."""
    if jnp.dtype(dtype) not in (jnp.dtype(jnp.float32), jnp.dtype(jnp.bfloat16)):
        raise ValueError(f"matmul operands must be float32 or bfloat16, got {dtype}")
    bf16 = jnp.dtype(dtype) == jnp.bfloat16
    token = _OPERANDS.set(jnp.dtype(dtype))
    try:
        with jax.default_matmul_precision(BFLOAT16_JAX_PRECISION if bf16 else "highest"):
            yield
    finally:
        _OPERANDS.reset(token)


def operand_dtype():
    """The operand dtype that ``matmul`` uses now (``matmul_operands``)."""
    return jnp.dtype(_OPERANDS.get())


def _row_major_transpose(x: jnp.ndarray) -> jnp.ndarray:
    """x.T as a row-major array. XLA:CPU's bfloat16 dot (its YNNPACK fusion, on AMX) is fast only
    when the contracted dimension of the left operand is its last in memory; a plain transpose
    is folded into the dot as a column-major layout, which falls back to a float32-speed path
    (BENCHMARKS: x^T @ g at 210 GFLOP/s against 1,094 for the same product on a copied x^T).
    Flattening behind an optimisation barrier forces the copy."""
    rows, cols = x.shape
    return jax.lax.optimization_barrier(x.T.reshape(-1)).reshape(cols, rows)


@functools.partial(jax.custom_vjp, nondiff_argnums=(0, 1))
def _bf16_matmul(a_dtype, b_dtype, a: jnp.ndarray, b: jnp.ndarray) -> jnp.ndarray:
    return jax.lax.dot(a.astype(jnp.bfloat16), b.astype(jnp.bfloat16), preferred_element_type=jnp.float32)


def _bf16_matmul_fwd(a_dtype, b_dtype, a, b):
    a16, b16 = a.astype(jnp.bfloat16), b.astype(jnp.bfloat16)
    return jax.lax.dot(a16, b16, preferred_element_type=jnp.float32), (a16, b16)


def _bf16_matmul_bwd(a_dtype, b_dtype, res, g):
    """The two products of the gradient, each with bfloat16 operands and float32 sums:
    da = g b^T (contracting both operands' last dimensions, a layout the fast path takes) and
    db = a^T g (a^T copied row-major first); each returned in its operand's dtype."""
    a16, b16 = res
    g16 = g.astype(jnp.bfloat16)
    da = jax.lax.dot_general(g16, b16, (((1,), (1,)), ((), ())), preferred_element_type=jnp.float32)
    db = jax.lax.dot(_row_major_transpose(a16), g16, preferred_element_type=jnp.float32)
    return da.astype(a_dtype), db.astype(b_dtype)


_bf16_matmul.defvjp(_bf16_matmul_fwd, _bf16_matmul_bwd)


def matmul(a: jnp.ndarray, b: jnp.ndarray) -> jnp.ndarray:
    """a (..., K) @ b (K, N) -> (..., N) in float32, with the operands ``matmul_operands`` sets:
    float32 (``a @ b``) or bfloat16 (cast, multiplied, summed in float32; the gradient's
    products likewise). The result is float32 either way. An operand that comes in bfloat16
    gets a bfloat16 gradient; params come in float32 and their gradients are float32."""
    if operand_dtype() == jnp.float32:
        return a @ b
    lead = a.shape[:-1]
    out = _bf16_matmul(jnp.dtype(a.dtype), jnp.dtype(b.dtype), a.reshape(-1, a.shape[-1]), b)
    return out.reshape(lead + (b.shape[-1],))


def dense_dot_general(lhs, rhs, dimension_numbers, precision=None, preferred_element_type=None):
    """``nn.Dense``'s product (lhs's last dimension against the kernel's first) through ``matmul``;
    pass as ``nn.Dense(..., dot_general=dense_dot_general)`` (``Dense``)."""
    (lhs_contract, rhs_contract), (lhs_batch, rhs_batch) = dimension_numbers
    if tuple(lhs_contract) != (lhs.ndim - 1,) or tuple(rhs_contract) != (0,) or lhs_batch or rhs_batch or rhs.ndim != 2:
        raise ValueError(f"dense_dot_general takes Dense's product only, got {dimension_numbers}")
    return matmul(lhs, rhs)


# flax's Dense (same parameters, names and initialisers) whose product is ``matmul``.
Dense = functools.partial(nn.Dense, dot_general=dense_dot_general)


def drawn_as_matrix(init: nn.initializers.Initializer) -> nn.initializers.Initializer:
    """``init`` for a (k, k, c_in, features) kernel, drawn as its (k*k*c_in, features) matrix and
    reshaped. The values are those of ``init`` on the kernel's own shape wherever ``init`` depends
    on the shape only through fan-in and the row-major order: the lecun and he initialisers,
    ``orthogonal`` (which draws that matrix itself) and zeros (checked in the tests); an
    initialiser that uses fan-out (glorot) sees fan-out = features. XLA:CPU compiles a random draw
    of rank 2 several times faster than one of rank 4 (0.2 s against 1 s for a 3x3x4x4 kernel);
    most of EC's init compile was the draws of its 21 conv kernels."""
    def draw(key, shape, dtype=jnp.float32):
        return init(key, (math.prod(shape[:-1]), shape[-1]), dtype).reshape(shape)

    return draw


def _same_or_valid(h: int, w: int, kernel: int, stride: int, padding: str):
    """Output size and the (before, after) pads of H and W, as ``nn.Conv`` pads."""
    if padding == "SAME":
        out_h, out_w = -(-h // stride), -(-w // stride)
        pad_h = max((out_h - 1) * stride + kernel - h, 0)
        pad_w = max((out_w - 1) * stride + kernel - w, 0)
        return out_h, out_w, (pad_h // 2, pad_h - pad_h // 2), (pad_w // 2, pad_w - pad_w // 2)
    if padding == "VALID":
        return (h - kernel) // stride + 1, (w - kernel) // stride + 1, (0, 0), (0, 0)
    raise ValueError(f"padding must be 'SAME' or 'VALID', got {padding!r}")


def _strided(x: jnp.ndarray, kernel: int, stride: int, out: int, axis: int) -> list[jnp.ndarray]:
    """The ``kernel`` strided views of x along ``axis`` alone, each ``out`` long."""
    index = [slice(None)] * x.ndim
    views = []
    for i in range(kernel):
        index[axis] = slice(i, i + stride * (out - 1) + 1, stride)
        views.append(x[tuple(index)])
    return views


def _windows(x: jnp.ndarray, kernel: int, stride: int, out_h: int, out_w: int, h_axis: int) -> list[jnp.ndarray]:
    """The kernel*kernel strided views of x, (ki, kj) row-major; H is ``h_axis``, W the next."""
    index = [slice(None)] * x.ndim
    views = []
    for i in range(kernel):
        for j in range(kernel):
            index[h_axis] = slice(i, i + stride * (out_h - 1) + 1, stride)
            index[h_axis + 1] = slice(j, j + stride * (out_w - 1) + 1, stride)
            views.append(x[tuple(index)])
    return views


def extract_patches(x: jnp.ndarray, kernel: int, stride: int, padding: str) -> jnp.ndarray:
    """(..., H, W, C) -> (..., H', W', kernel*kernel*C), patch features ordered (ki, kj, c).

    Gathered in two passes, along W (kernel pieces of C) and then along H (kernel pieces of
    kernel*C), not as one concatenation of kernel*kernel pieces of C: the same array, and XLA:CPU
    copies fewer, longer pieces faster (EC's 7x7 stem on RGB frames: see BENCHMARKS)."""
    out_h, out_w, pad_h, pad_w = _same_or_valid(x.shape[-3], x.shape[-2], kernel, stride, padding)
    x = jnp.pad(x, [(0, 0)] * (x.ndim - 3) + [pad_h, pad_w, (0, 0)])
    rows = jnp.concatenate(_strided(x, kernel, stride, out_w, x.ndim - 2), axis=-1)  # (..., H, W', kernel*C)
    return jnp.concatenate(_strided(rows, kernel, stride, out_h, x.ndim - 3), axis=-1)


def max_pool(x: jnp.ndarray, window: int = 3, stride: int = 2) -> jnp.ndarray:
    """SAME max pooling of non-negative (..., H, W, C): the elementwise maximum of the strided
    views, along W and then along H. SAME pads with zeros, which never change a max of inputs
    >= 0. Slices and ``jnp.maximum``, like ``extract_patches``, so the gradient is pads and
    selects; no window array is built (EC's pool of a rollout: 0.06 s, against 0.24 s as a max
    over the concatenated windows; BENCHMARKS)."""
    out_h, out_w, pad_h, pad_w = _same_or_valid(x.shape[-3], x.shape[-2], window, stride, "SAME")
    x = jnp.pad(x, [(0, 0)] * (x.ndim - 3) + [pad_h, pad_w, (0, 0)])
    x = functools.reduce(jnp.maximum, _strided(x, window, stride, out_w, x.ndim - 2))
    return functools.reduce(jnp.maximum, _strided(x, window, stride, out_h, x.ndim - 3))


def extract_patches_chwn(x: jnp.ndarray, kernel: int, stride: int, padding: str) -> jnp.ndarray:
    """(C, H, W, ...) -> (kernel*kernel, C, H', W', ...): the patch features (ki, kj, c) lead and
    the batch trails, so every strided slice and its gradient moves whole batch rows."""
    out_h, out_w, pad_h, pad_w = _same_or_valid(x.shape[1], x.shape[2], kernel, stride, padding)
    x = jnp.pad(x, [(0, 0), pad_h, pad_w] + [(0, 0)] * (x.ndim - 3))
    return jnp.stack(_windows(x, kernel, stride, out_h, out_w, 1), axis=0)


def to_chwn(x: jnp.ndarray) -> jnp.ndarray:
    """(..., H, W, C) -> (C, H, W, ...), the layout ``PatchConv(layout="CHWN")`` takes."""
    return jnp.moveaxis(x, (-1, -3, -2), (0, 1, 2))


def from_chwn(x: jnp.ndarray) -> jnp.ndarray:
    """(C, H, W, ...) -> (..., H, W, C)."""
    return jnp.moveaxis(x, (0, 1, 2), (-1, -3, -2))


def _taps(h: int, w: int, kernel: int, stride: int, padding: str) -> tuple[np.ndarray, int, int]:
    """(kernel*kernel, h*w, out_h*out_w) 0/1: tap t of output p reads input q; and out_h, out_w."""
    out_h, out_w, (pad_h, _), (pad_w, _) = _same_or_valid(h, w, kernel, stride, padding)
    taps = np.zeros((kernel * kernel, h * w, out_h * out_w), np.float32)
    for i, j, ki, kj in itertools.product(range(out_h), range(out_w), range(kernel), range(kernel)):
        r, c = i * stride + ki - pad_h, j * stride + kj - pad_w
        if 0 <= r < h and 0 <= c < w:
            taps[ki * kernel + kj, r * w + c, i * out_w + j] = 1.0
    return taps, out_h, out_w


def dense_conv(x: jnp.ndarray, kernel: jnp.ndarray, stride: int, padding: str) -> jnp.ndarray:
    """The convolution of (..., H, W, C) x with a (k, k, C, F) kernel as one dense map from the
    H*W*C inputs to the H'*W'*F outputs. Where H*W < k*k, most of a patch is padding: on EC's
    2x2 maps a 3x3 SAME patch holds 4 of its 9 taps, and the dense map multiplies 4/9 as much."""
    h, w, c = x.shape[-3:]
    taps, out_h, out_w = _taps(h, w, kernel.shape[0], stride, padding)
    dense = jnp.einsum("tqp,tcf->qcpf", taps, kernel.reshape(-1, c, kernel.shape[-1]))
    y = matmul(x.reshape(x.shape[:-3] + (h * w * c,)), dense.reshape(h * w * c, -1))
    return y.reshape(x.shape[:-3] + (out_h, out_w, kernel.shape[-1]))


class PatchConv(nn.Module):
    """A square-kernel convolution as im2col + matmul; drop-in for ``nn.Conv`` on (..., H, W, C).

    ``layout="CHWN"`` takes and returns (C, H, W, ...) instead, with the same parameters and
    outputs equal to float rounding (the matmul sums the same products in its own order).
    ``conv_stack`` runs in that layout, where the patches stack whole batch rows and the matmul
    is kernel^T @ patches, one (F, K) by (K, H'*W'*batch) product. In (..., H, W, C) the patches
    are C-float pieces, which XLA:CPU concatenates (and scatters back in the gradient) slowly
    when C is small. In NHWC a map smaller than the kernel (H*W < k*k) is convolved as one dense
    map (``dense_conv``), which skips the patches' padding."""

    features: int
    kernel: int = 3
    stride: int = 1
    padding: str = "SAME"
    kernel_init: nn.initializers.Initializer = nn.initializers.lecun_normal()
    bias_init: nn.initializers.Initializer = nn.initializers.zeros_init()
    layout: str = "NHWC"

    @nn.compact
    def __call__(self, x: jnp.ndarray) -> jnp.ndarray:
        if self.layout not in ("NHWC", "CHWN"):
            raise ValueError(f"layout must be 'NHWC' or 'CHWN', got {self.layout!r}")
        c_in = x.shape[0] if self.layout == "CHWN" else x.shape[-1]
        kernel = self.param("kernel", drawn_as_matrix(self.kernel_init), (self.kernel, self.kernel, c_in, self.features))
        bias = self.param("bias", self.bias_init, (self.features,))
        weights = kernel.reshape(-1, self.features)  # rows ordered (ki, kj, c)
        if self.layout == "NHWC" and x.shape[-3] * x.shape[-2] < self.kernel * self.kernel:
            return dense_conv(x, kernel, self.stride, self.padding) + bias
        if self.layout == "NHWC":
            return matmul(extract_patches(x, self.kernel, self.stride, self.padding), weights) + bias
        patches = extract_patches_chwn(x, self.kernel, self.stride, self.padding)
        if operand_dtype() == jnp.float32:
            out = weights.T @ patches.reshape(weights.shape[0], -1)
        else:  # the fast bfloat16 dot wants its left operand's contraction last in memory
            out = matmul(_row_major_transpose(weights), patches.reshape(weights.shape[0], -1))
        return out.reshape((self.features,) + patches.shape[2:]) + bias.reshape((-1,) + (1,) * (patches.ndim - 2))


def conv_stack(x: jnp.ndarray, features: Sequence[int], kernel: int | Sequence[int] = 3,
               stride: int | Sequence[int] = 2, padding: str = "SAME",
               activation: Callable[[jnp.ndarray], jnp.ndarray] = nn.relu,
               kernel_init: nn.initializers.Initializer = nn.initializers.lecun_normal()) -> jnp.ndarray:
    """activation(PatchConv) layers in sequence, as the paper's encoders use them, on (..., H, W, C).

    ``kernel`` and ``stride`` are one value for every layer or one per layer. The layers run
    in the CHWN layout (one transpose in, one out); the modules are named PatchConv_0, _1, ... in
    the calling module, as ``nn.Conv`` layers written out one by one would be."""
    n = len(features)
    kernels = [kernel] * n if isinstance(kernel, int) else list(kernel)
    strides = [stride] * n if isinstance(stride, int) else list(stride)
    x = to_chwn(x)
    for f, k, s in zip(features, kernels, strides, strict=True):
        x = activation(PatchConv(f, k, s, padding, kernel_init=kernel_init, layout="CHWN")(x))
    return from_chwn(x)
