"""A counter-based generator in tensor integer operations: every draw is a hash of its coordinates.

Draw ``j`` of stream ``s`` at reading ``t`` of episode ``e`` of the env with key ``(k0, k1)`` is
``H(k0, k1, e, t, s, j)``: the value does not depend on how many envs are stepped together, on their
order or on the device — only on the env's seed and on the actions it was given (which decide when an
episode ends). Nothing is stored between draws (no generator state to advance or to split).

``H`` chains Wellons' ``lowbias32`` 32-bit integer hash (xor-shift, multiply, xor-shift, multiply,
xor-shift; a splitmix-style finaliser) over the coordinates. It is computed in int64 tensors holding
values in [0, 2³²): the products are split into 16-bit halves so that no intermediate leaves int64 (no
signed overflow, the same bits in eager, compiled and CUDA code). torch's own Philox is a stateful
generator per device (its stream depends on the launch configuration), so it gives no per-env
guarantee; numpy's counter-based ``Philox`` runs on the host only — hence this hand-written hash.
It is a simulation generator, not a cryptographic one.

Normal draws index the 65536-entry quantile table of :func:`electroloc_gym.kernels.streams.normal_table` with 16
bits (two per hash), as the numba core's jitter does; uniforms take 24 bits (float32 quantities) or
two hashes' 53 bits (float64).
"""

from __future__ import annotations

import torch

__all__ = [
    "CPU_BLOCK_WORDS",
    "mix32",
    "hash32",
    "stream_key",
    "bits32",
    "uniform53",
    "uniform24",
    "normal_pair_indices",
    "lookup",
    "STREAMS",
]

_MASK32 = 0xFFFFFFFF
_MASK16 = 0xFFFF
_GOLDEN = 0x9E3779B9
#: The streams of one reading or one reset, each with its own draws.
STREAMS = {
    "noise": 0,
    "resample": 1,
    "jitter": 2,
    "condition": 3,
    "target": 4,
    "start": 5,
    "particles": 6,
    "calibration": 7,
}


def _mul32(x: torch.Tensor, c: int) -> torch.Tensor:
    """``x · c mod 2³²`` for int64 ``x`` in [0, 2³²) and a constant ``c`` < 2³² (16-bit halves: no overflow)."""
    return (x * (c & _MASK16) + (((x * (c >> 16)) & _MASK16) << 16)) & _MASK32


def mix32(x: torch.Tensor) -> torch.Tensor:
    """Wellons' ``lowbias32`` of int64 ``x`` in [0, 2³²): a bijection of 32-bit words with strong avalanche."""
    x = x ^ (x >> 16)
    x = _mul32(x, 0x7FEB352D)
    x = x ^ (x >> 15)
    x = _mul32(x, 0x846CA68B)
    return x ^ (x >> 16)


def hash32(a: torch.Tensor, b: torch.Tensor) -> torch.Tensor:
    """One link of the chain: ``mix32(a xor mix32(b + golden mod 2³²))`` (int64 words in [0, 2³²))."""
    return mix32(a ^ mix32((b + _GOLDEN) & _MASK32))


def stream_key(
    k0: torch.Tensor, k1: torch.Tensor, episode: torch.Tensor, reading: torch.Tensor, stream: int
) -> torch.Tensor:
    """(N,) the key of one stream of each env: its seed words ``k0``, ``k1`` (N,), episode and reading
    index (N,) int64, and the stream's number (:data:`STREAMS`).
    """
    h = hash32(k1, episode & _MASK32)
    h = hash32(h, reading & _MASK32)
    h = hash32(h, torch.full_like(h, stream))
    return mix32(h ^ k0)


#: Words per block when the hash runs eagerly on the CPU: each of its ~40 elementwise passes then stays in
#: the cache instead of streaming the whole (N, count) int64 array through memory (the same bits).
CPU_BLOCK_WORDS = 1 << 16


def _words(key: torch.Tensor, j: torch.Tensor) -> torch.Tensor:
    k = key[:, None]
    return mix32(mix32(k ^ j) ^ k)


def bits32(key: torch.Tensor, count: int, start: int = 0) -> torch.Tensor:
    """(N, count) 32-bit words (int64) of each env's stream ``key`` (N,): word j (from ``start``) is
    ``mix32(mix32(key ⊕ j·φ mod 2³²) ⊕ key)``.

    Eager on the CPU, large requests are hashed in blocks of envs (:data:`CPU_BLOCK_WORDS` words: a
    loop over cache-sized blocks, not over envs); compiled or on an accelerator, in one pass.
    """
    j = _mul32(torch.arange(start, start + count, device=key.device, dtype=torch.int64), _GOLDEN)
    n = key.shape[0]
    if key.device.type == "cpu" and n * count > CPU_BLOCK_WORDS and not torch.compiler.is_compiling():
        rows = max(1, CPU_BLOCK_WORDS // count)
        return torch.cat([_words(key[i : i + rows], j) for i in range(0, n, rows)])
    return _words(key, j)


def uniform53(key: torch.Tensor, count: int) -> torch.Tensor:
    """(N, count) float64 uniforms in [0, 1): 53 bits from two words (numpy's ``random()`` construction)."""
    w = bits32(key, 2 * count)
    a, b = w[:, 0::2] >> 5, w[:, 1::2] >> 6
    return (a * 67108864 + b).to(torch.float64) * (1.0 / 9007199254740992.0)


def uniform24(key: torch.Tensor, count: int) -> torch.Tensor:
    """(N, count) float64 uniforms in [0, 1) on a 2⁻²⁴ grid (one word each: float32 quantities)."""
    return (bits32(key, count) >> 8).to(torch.float64) * (1.0 / 16777216.0)


def normal_pair_indices(key: torch.Tensor, count: int) -> tuple[torch.Tensor, torch.Tensor]:
    """Two (N, count) int64 indices into the 65536-entry normal table: the low and high 16 bits of each word."""
    w = bits32(key, count)
    return w & _MASK16, w >> 16


def lookup(table: torch.Tensor, index: torch.Tensor) -> torch.Tensor:
    """``table[index]`` for a 1-D ``table`` and int64 ``index`` of any shape, as one ``index_select`` of the
    flattened indices (the same values; on the CPU several times faster than advanced indexing).
    """
    return torch.index_select(table, 0, index.reshape(-1)).reshape(index.shape)
