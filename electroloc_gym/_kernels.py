"""Compiled (numba) loops of the particle filter's hot path, shared by the single and the vector env.

Why compiled loops: at M = 2500 particles a numpy step is ~25 elementwise passes, each a separate
C call with its own temporary; the batched env spends most of its time there. The vector env's whole
calibrated update (:func:`calibrated_assimilate`: likelihood, weights, resampling, jitter, statistics,
histogram) is one kernel call that takes one env at a time through a few passes over its particles,
so that each cloud stays in cache.

Why the single and the vector env compute *identical* results (tested bit for bit): each kernel
performs the same IEEE operations, in the same dtype and order, as the numpy expression it stands for
(quoted beside it), and where the two envs would otherwise depend on how numpy evaluates something,
both call the same kernel:

* numba compiles without ``fastmath``, so LLVM neither reassociates nor contracts ``a*b + c`` into an
  FMA; float32 constants are written as ``np.float32`` so no operation is promoted to float64;
* ``exp`` and ``log`` of the weights are :func:`exp32`/:func:`log32` (Cephes' polynomials, within
  1 ulp, vectorisable) in both envs — numpy's SIMD ``exp``/``log`` differ between CPUs and from libm's
  in the last bit, and were ≈3× slower here;
* sums whose order numpy leaves open are fixed: the weights' total (:func:`row_sums`) and the belief's
  mean and covariance (:func:`mean_cov_rows`);
* the histogram, the observation's assembly and the calibration tables are kernels both envs call.

Compiled on first use and cached on disk (``cache=True``: a few seconds once per machine).
"""

from __future__ import annotations

import numpy as np
from llvmlite import ir
from numba import njit
from numba.core import types
from numba.extending import intrinsic

__all__ = [
    "exp32",
    "log32",
    "exp_f32",
    "log_f32",
    "row_sums",
    "calibrated_log_likelihood",
    "calibrated_assimilate",
    "resample_jitter_clip",
    "table_gather",
    "box_affine",
    "noisy_saturated",
    "mean_cov_rows",
    "egocentric_counts",
    "belief_observation_rows",
    "calibration_tables",
    "bilinear_coefficients",
]

_F32_HALF_NEG = np.float32(-0.5)
_F32_HALF = np.float32(0.5)

_JIT = {"cache": True, "nogil": True, "error_model": "numpy"}


# --------------------------------------------------------------------------------------------
# float32 exp and log of the filter's weights (Cephes' expf/logf polynomials, no FMA)
# --------------------------------------------------------------------------------------------
@intrinsic
def _pow2(typingctx, n):  # pragma: no cover - compiled
    """2**n as float32 for a float32 integer value n in [−126, 127] (built from the exponent bits)."""
    if n != types.float32:
        return None

    def codegen(context, builder, signature, args):
        i32 = ir.IntType(32)
        e = builder.add(builder.fptosi(args[0], i32), ir.Constant(i32, 127))
        return builder.bitcast(builder.shl(e, ir.Constant(i32, 23)), ir.FloatType())

    return types.float32(types.float32), codegen


@intrinsic
def _frexp32(typingctx, x):  # pragma: no cover - compiled
    """(f, e), both float32, with x = f·2**e and f in [0.5, 1), for a normal float32 x > 0 (bit fields)."""
    if x != types.float32:
        return None
    sig = types.UniTuple(types.float32, 2)(types.float32)

    def codegen(context, builder, signature, args):
        i32 = ir.IntType(32)
        bits = builder.bitcast(args[0], i32)
        f = builder.or_(builder.and_(bits, ir.Constant(i32, 0x007FFFFF)), ir.Constant(i32, 0x3F000000))
        e = builder.and_(builder.lshr(bits, ir.Constant(i32, 23)), ir.Constant(i32, 0xFF))
        return context.make_tuple(builder, signature.return_type,
                                  (builder.bitcast(f, ir.FloatType()),
                                   builder.sitofp(builder.sub(e, ir.Constant(i32, 126)), ir.FloatType())))

    return sig, codegen


_F = np.float32
_ONE = _F(1.0)
_ZERO = _F(0.0)
_INF = _F(np.inf)
_NAN = _F(np.nan)
_LN2_HI = _F(0.693359375)  # ln 2 = _LN2_HI + _LN2_LO (Cody–Waite)
_LN2_LO = _F(-2.12194440e-4)
_LOG2E = _F(1.44269504088896341)
_EXP_MAX = _F(88.72283)  # exp(x) overflows above
_EXP_MIN = _F(-103.972084)  # exp(x) < 2**−150 below: 0
_E0, _E1, _E2, _E3, _E4, _E5 = (_F(1.9875691500e-4), _F(1.3981999507e-3), _F(8.3334519073e-3),
                                _F(4.1665795894e-2), _F(1.6666665459e-1), _F(5.0000001201e-1))
_SQRT_HALF = _F(0.707106781186547524)
_L0, _L1, _L2, _L3, _L4, _L5, _L6, _L7, _L8 = (
    _F(7.0376836292e-2), _F(-1.1514610310e-1), _F(1.1676998740e-1), _F(-1.2420140846e-1), _F(1.4249322787e-1),
    _F(-1.6668057665e-1), _F(2.0000714765e-1), _F(-2.4999993993e-1), _F(3.3333331174e-1))
_F32_MIN_NORMAL = _F(1.17549435e-38)
_TWO23 = _F(8388608.0)
_TWENTY3 = _F(23.0)


@njit(inline="always")
def exp32(x):  # pragma: no cover - compiled
    """The exponential of a float32, within 1 ulp; exact 1 at 0, 0 below −103.97, inf above 88.72, NaN for NaN.

    Cephes' ``expf``: x = n·ln 2 + r (|r| ≤ ½ ln 2, Cody–Waite), a degree-6 polynomial in r, times
    2**n applied as two exactly representable factors (so the subnormal range rounds once). Branch
    free, so loops over it vectorise.
    """
    xc = x if x > _EXP_MIN else _EXP_MIN
    xc = xc if xc < _EXP_MAX else _EXP_MAX
    n = np.floor(_LOG2E * xc + _F32_HALF)
    r = (xc - n * _LN2_HI) - n * _LN2_LO
    p = (((((_E0 * r + _E1) * r + _E2) * r + _E3) * r + _E4) * r + _E5) * (r * r) + r + _ONE
    n1 = np.floor(n * _F32_HALF)
    y = (p * _pow2(n1)) * _pow2(n - n1)
    y = y if x > _EXP_MIN else _ZERO
    y = y if x < _EXP_MAX else _INF
    return y if x == x else x


@njit(inline="always")
def log32(x):  # pragma: no cover - compiled
    """Natural log of a float32, within 1 ulp; −inf at 0, NaN below 0 or for NaN, inf at inf.

    Cephes' ``logf``: x = f·2**e with f in [√½, √2), a degree-9 polynomial in f − 1, plus e·ln 2
    (Cody–Waite). Subnormals are scaled by 2**23 first. Branch free, so loops over it vectorise.
    """
    small = x < _F32_MIN_NORMAL
    xs = x * _TWO23 if small else x
    f, e = _frexp32(xs)
    e = e - (_TWENTY3 if small else _ZERO)
    low = f < _SQRT_HALF
    e = e - _ONE if low else e
    f = (f + f - _ONE) if low else (f - _ONE)
    z = f * f
    y = ((((((((_L0 * f + _L1) * f + _L2) * f + _L3) * f + _L4) * f + _L5) * f + _L6) * f + _L7) * f + _L8) * f * z
    y = y + _LN2_LO * e
    y = y - _F32_HALF * z
    r = (f + y) + _LN2_HI * e
    r = r if x > _ZERO else (-_INF if x == _ZERO else _NAN)
    return r if x < _INF else x


@njit(**_JIT)
def exp_f32(x, out):  # pragma: no cover - compiled
    """``out[i] = exp32(x[i])`` over 1-D float32 arrays (in place works, but only a separate ``out`` vectorises)."""
    for i in range(x.shape[0]):
        out[i] = exp32(x[i])


@njit(**_JIT)
def log_f32(x, out):  # pragma: no cover - compiled
    """``out[i] = log32(x[i])`` over 1-D float32 arrays (in place works, but only a separate ``out`` vectorises)."""
    for i in range(x.shape[0]):
        out[i] = log32(x[i])


@njit(inline="always")
def _sum8(x):  # pragma: no cover - compiled
    """Sum of a 1-D float64 array in a fixed order: eight interleaved partial sums, combined pairwise,
    then the remainder — the same bits on every machine, and ~4× faster than one running sum.
    """
    m = x.shape[0]
    m8 = m - m % 8
    a0 = a1 = a2 = a3 = a4 = a5 = a6 = a7 = 0.0
    for i in range(0, m8, 8):
        a0 += x[i]
        a1 += x[i + 1]
        a2 += x[i + 2]
        a3 += x[i + 3]
        a4 += x[i + 4]
        a5 += x[i + 5]
        a6 += x[i + 6]
        a7 += x[i + 7]
    s = ((a0 + a1) + (a2 + a3)) + ((a4 + a5) + (a6 + a7))
    for i in range(m8, m):
        s += x[i]
    return s


@njit(**_JIT)
def row_sums(w, out):  # pragma: no cover - compiled
    """``out[e] = _sum8(w[e])`` for a (k, M) float64 array: the weights' normalising sums."""
    for e in range(w.shape[0]):
        out[e] = _sum8(w[e])


@njit(**_JIT)
def _calibrated_ll_one(px, py, ox0, oy0, sign, lo, inv, n1, base, table, reading, ll, sd, rows,  # pragma: no cover
                       txs, tys):
    """One env's calibrated log-likelihoods into ``ll`` (M,) float32 (see :func:`calibrated_log_likelihood`)
    at the offsets ``sign·(p − o)`` of the particles ``px``, ``py`` (M,) from the origin (ox0, oy0),
    all float32 (sign ±1: exact).

    ``sd`` (M,) float32, ``rows`` (M,) int32, ``txs``/``tys`` (M,) float32 are scratch.
    """
    m = px.shape[0]
    n1i = np.int32(n1)
    n1f = np.float32(n1)
    above = np.float32(n1 + 1)
    below = np.float32(-1.0)
    top = np.int32(n1 - 1)
    b = np.int32(base)
    outside = np.int32(base + n1 * n1)
    for i in range(m):
        fx = ((px[i] - ox0) * sign - lo) * inv
        fy = ((py[i] - oy0) * sign - lo) * inv
        ix = min(np.int32(min(max(fx, below), above)), top)
        iy = min(np.int32(min(max(fy, below), above)), top)
        txs[i] = fx - np.float32(ix)
        tys[i] = fy - np.float32(iy)
        inside = (fx >= _ZERO) & (fx <= n1f) & (fy >= _ZERO) & (fy <= n1f)
        rows[i] = b + ix * n1i + iy if inside else outside
    for i in range(m):
        row = rows[i]
        tx = txs[i]
        ty = tys[i]
        txy = tx * ty
        mean = table[row, 0] + table[row, 1] * tx
        mean = mean + table[row, 2] * ty
        mean = mean + table[row, 3] * txy
        std = table[row, 4] + table[row, 5] * tx
        std = std + table[row, 6] * ty
        std = std + table[row, 7] * txy
        ll[i] = mean
        sd[i] = std
    for i in range(m):
        z = (reading - ll[i]) / sd[i]
        ll[i] = (_F32_HALF_NEG * z) * z - log32(sd[i])


@njit(**_JIT)
def calibrated_log_likelihood(off, lo, inv, n1, base, table, reading, ll):  # pragma: no cover - compiled
    """The calibrated sensor model's log-likelihoods for k envs at once (bilinear lookup, Gaussian term).

    Stands for ``CalibratedSensorModel.log_likelihood`` (``mean_std``, then
    ``gaussian_log_likelihood``) in float32 (per env ``e``, particle ``i``)::

        fx = (off_x − lo) · inv;  fy = (off_y − lo) · inv     # off = particle − position.astype(float32)
        inside = (fx ≥ 0) & (fx ≤ n1) & (fy ≥ 0) & (fy ≤ n1)
        ix = min(int(fx), n1 − 1);  iy = min(int(fy), n1 − 1);  tx = fx − ix;  ty = fy − iy
        c = coef[ix·n1 + iy if inside else n1²]                       # 8 float32 coefficients
        mean = c0 + c1·tx + c2·ty + c3·tx·ty;  std = c4 + c5·tx + c6·ty + c7·tx·ty
        z = (float32(reading) − mean) / std;  ll = −0.5·z·z − log32(std)

    Three passes per env, so that the two without the table gather vectorise: the cell index and
    (tx, ty) of every particle; the gather and the two bilinear sums; the Gaussian term. ``fx`` is
    clamped to [−1, n1 + 1] before the integer conversion (the conversion is then in range; ``ix`` is
    the same wherever the particle is inside, and outside the coefficients of ``tx``, ``ty`` are 0,
    so any finite value gives the same result).

    Args:
        off: (k, 2, M) float32 sensor-model offsets (target hypothesis − carriage), coordinate-major
            and C-contiguous (so that the first pass vectorises), mm.
        lo: (k,) float32 grid origin, mm.
        inv: (k,) float32 inverse grid step, 1/mm.
        n1: (k,) int64 cells per axis.
        base: (k,) int64 first row of each env's coefficients in ``table``.
        table: (rows, 8) float32 stacked coefficients (each env's last row: outside the grid).
        reading: (k,) float32 readings, V.
        ll: (k, M) float32 output, log-likelihoods up to the constant −½ log 2π.
    """
    k, _, m = off.shape
    sd = np.empty(m, dtype=np.float32)
    rows = np.empty(m, dtype=np.int32)
    txs = np.empty(m, dtype=np.float32)
    tys = np.empty(m, dtype=np.float32)
    for e in range(k):
        _calibrated_ll_one(off[e, 0], off[e, 1], _ZERO, _ZERO, _ONE, lo[e], inv[e], n1[e], base[e], table,
                           reading[e], ll[e], sd, rows, txs, tys)


@njit(**_JIT)
def _cov_about(x, y, mx, my, cov, e):  # pragma: no cover - compiled
    """Population covariance of one cloud (x, y: (M,)) about the mean (mx, my) into ``cov[e]`` (sequential float64)."""
    m = x.shape[0]
    fm = np.float64(m)
    cxx = 0.0
    cxy = 0.0
    cyy = 0.0
    for i in range(m):
        dx = np.float64(x[i]) - mx
        dy = np.float64(y[i]) - my
        cxx += dx * dx
        cxy += dx * dy
        cyy += dy * dy
    cov[e, 0, 0] = cxx / fm
    cov[e, 0, 1] = cxy / fm
    cov[e, 1, 0] = cxy / fm
    cov[e, 1, 1] = cyy / fm


@njit(**_JIT)
def _mean_cov_one(x, y, mean, cov, e):  # pragma: no cover - compiled
    """Mean and population covariance of one cloud (x, y: (M,)) into ``mean[e]``, ``cov[e]``."""
    m = x.shape[0]
    fm = np.float64(m)
    sx = 0.0
    sy = 0.0
    for i in range(m):
        sx += np.float64(x[i])
        sy += np.float64(y[i])
    mean[e, 0] = sx / fm
    mean[e, 1] = sy / fm
    _cov_about(x, y, sx / fm, sy / fm, cov, e)


@njit(**_JIT)
def _counts_one(x, y, cx, cy, scale, bins, out, e, cells, hist):  # pragma: no cover - compiled
    """Histogram counts of one cloud (x, y: (M,)) around (cx, cy) into ``out[e]`` (see egocentric_counts).

    ``cells`` (M,) int32 and ``hist`` (4, bins²) int32 are scratch: the cells are computed in a
    vectorised pass (the float cell coordinate is clamped before its integer conversion, so the
    conversion is always in range; in range it truncates as numpy's ``astype``), then counted into four
    interleaved histograms, so that repeated cells do not chain one increment on the previous one.
    """
    m = x.shape[0]
    fb = np.float32(bins)  # numpy's ``rel * 8`` keeps the particles' dtype (a Python int is weak)
    lo = np.float32(-1.0)
    top = np.int32(bins - 1)
    nb = np.int32(bins)
    zero = np.int32(0)
    for i in range(m):
        a = np.int32(min(max(((x[i] - cx) / scale + _F32_HALF) * fb, lo), fb))
        b = np.int32(min(max(((y[i] - cy) / scale + _F32_HALF) * fb, lo), fb))
        cells[i] = min(max(a, zero), top) * nb + min(max(b, zero), top)
    hist[:] = 0
    m4 = m - m % 4
    for i in range(0, m4, 4):
        hist[0, cells[i]] += 1
        hist[1, cells[i + 1]] += 1
        hist[2, cells[i + 2]] += 1
        hist[3, cells[i + 3]] += 1
    for i in range(m4, m):
        hist[0, cells[i]] += 1
    for c in range(bins * bins):
        out[e, c] = np.float64(hist[0, c] + hist[1, c] + hist[2, c] + hist[3, c])


@njit(**_JIT)
def _resample_one(w, t, u, src_x, src_y, jitter_idx, normal_table, h, out_x, out_y,  # pragma: no cover - compiled
                  mean, cov, cx, cy, scale, bins, counts, e, cum, ptr, kest, first, cells, hist):
    """One env of :func:`resample_jitter_clip` (``cum``, ``ptr`` (M + 1), ``kest``, ``first`` (M + 1),
    ``cells``, ``hist`` are scratch).
    """
    m = w.shape[0]
    fm = np.float64(m)
    acc = np.float64(w[0]) / t
    cum[0] = acc
    for i in range(1, m):
        acc = acc + np.float64(w[i]) / t
        cum[i] = acc
    last = cum[m - 1]
    for j in range(m):
        ptr[j] = (u + np.float64(j)) / fm
    ptr[m] = 2.0  # sentinel above every normalised cumulative weight (≤ 1)
    for i in range(m - 1):
        c = cum[i] / last
        cum[i] = c
        kk = np.ceil(c * fm - u)
        kk = kk if kk >= 0.0 else 0.0  # also NaN → 0: the index stays in range
        kest[i] = np.int32(kk if kk <= fm else fm)
    for j in range(m + 1):
        first[j] = 0
    for i in range(m - 1):
        c = cum[i]
        ki = kest[i]
        while ki > 0 and ptr[ki - 1] >= c:
            ki -= 1
        while ptr[ki] < c:
            ki += 1
        first[ki] += 1
    first[m] += 1
    nh = -h
    idx = np.int64(0)
    sx = 0.0
    sy = 0.0
    for j in range(m):
        idx += first[j]
        x = src_x[idx] + normal_table[jitter_idx[2 * j]]
        y = src_y[idx] + normal_table[jitter_idx[2 * j + 1]]
        x = nh if x < nh else x
        x = h if x > h else x
        y = nh if y < nh else y
        y = h if y > h else y
        out_x[j] = x
        out_y[j] = y
        sx += np.float64(x)
        sy += np.float64(y)
    mean[e, 0] = sx / fm
    mean[e, 1] = sy / fm
    _cov_about(out_x, out_y, sx / fm, sy / fm, cov, e)
    _counts_one(out_x, out_y, cx, cy, scale, bins, counts, e, cells, hist)


@njit(**_JIT)
def _resample_scratch(m, bins):  # pragma: no cover - compiled
    """Scratch of :func:`_resample_one` for M particles: cum, ptr (M + 1), kest, first (M + 1), cells, hist."""
    return (np.empty(m), np.empty(m + 1), np.empty(m, dtype=np.int32), np.empty(m + 1, dtype=np.int64),
            np.empty(m, dtype=np.int32), np.empty((4, bins * bins), dtype=np.int32))


@njit(**_JIT)
def resample_jitter_clip(w, total, u0, src, jitter_idx, normal_table, half, out,  # pragma: no cover - compiled
                         mean, cov, origin, scale, bins, counts):
    """Normalise, systematically resample, jitter and clip k clouds (ParticleBelief.assimilate's tail),
    then each new cloud's mean/covariance (:func:`mean_cov_rows`) and histogram counts
    (:func:`egocentric_counts`) while it is still in cache.

    Stands for, per env (``w`` the unnormalised ``exp(log_w − max)``, ``total`` its
    :func:`row_sums`)::

        w = w / total                                               # normalise_log_weights
        cum = np.cumsum(w); cum /= cum[-1]                          # systematic_resample
        u = (U + np.arange(M)) / M
        idx = np.minimum(np.searchsorted(cum, u, side="right"), M − 1)
        jitter = normal_table[jitter_idx].reshape(M, 2)             # belief.table_standard_normal
        p = particles[idx] + jitter                                 # resample, jitter (std 1 mm)
        p = np.minimum(np.maximum(p, −H), H)                        # _clip_to_box

    ``searchsorted`` without branches: particle ``i`` takes the pointers ``j`` with
    ``cum[i−1] ≤ u[j] < cum[i]``, i.e. ``K(i−1) ≤ j < K(i)`` where ``K(i) = #{j: u[j] < cum[i]}``
    (``K(M−1) = M``: the ``min(·, M − 1)``). ``K(i)`` is ``ceil(M·cum[i] − U)`` up to float rounding
    (computed for all particles in a vectorised pass), corrected by comparing with the pointers
    themselves (the same ``(U + j)/M`` values, so the same comparisons as ``searchsorted``); then
    ``idx[j] = #{i: K(i) ≤ j}`` is a running sum of a histogram of the ``K(i)`` — no data-dependent
    branch per particle. The mean's sums run in the resampling loop, in the same particle order as
    :func:`mean_cov_rows`.

    Args:
        w: (k, M) float64 unnormalised weights (read only).
        total: (k,) float64 row sums of ``w``.
        u0: (k,) float64 resampling offsets U in [0, 1).
        src: (k, 2, M) float32 particles, coordinate-major.
        jitter_idx: (k, 2·M) uint16 indices into ``normal_table`` (the single env's draw layout).
        normal_table: (65536,) float32 standard-normal quantiles (:func:`electroloc_gym.belief.normal_table`).
        half: (k,) float32 half-width H of the box, mm.
        out: (k, 2, M) float32 new particles (must not alias ``src``).
        mean: (k, 2) float64 output: the new clouds' means, mm.
        cov: (k, 2, 2) float64 output: their covariances, mm².
        origin: (k, 2) float32 histogram centres (:func:`egocentric_counts`'s ``carriage``), mm.
        scale: (k,) float32 histogram widths 2·H, mm.
        bins: histogram cells per axis.
        counts: (k, bins²) float64 output: the histogram counts.
    """
    k, m = w.shape
    scratch = _resample_scratch(m, bins)
    for e in range(k):
        _resample_one(w[e], total[e], u0[e], src[e, 0], src[e, 1], jitter_idx[e], normal_table, half[e],
                      out[e, 0], out[e, 1], mean, cov, origin[e, 0], origin[e, 1], scale[e], bins, counts, e,
                      *scratch)


@njit(**_JIT)
def _shifted_exp_one(ll, w):  # pragma: no cover - compiled
    """One cloud of ``belief.shifted_exp_weights`` (float32 log-weights ``ll``) into ``w`` (M,) (not
    ``ll`` itself: the exp pass would not vectorise); returns the weights' :func:`row_sums` total,
    or NaN if a log-weight is NaN.

    With a float32 ``w`` the weights stay float32 here and the consumers widen them to float64 as
    they read them (``np.float64(w[i])`` is exact), which is what ``.astype(np.float64)`` gives the
    single env; a float32 store halves the exp pass.
    """
    m = ll.shape[0]
    top = -_INF
    nan = False
    for i in range(m):
        v = ll[i]
        nan |= v != v
        top = v if v > top else top
    if nan:
        return np.nan
    finite = (top > -_INF) & (top < _INF)
    shift = top if finite else _ZERO
    for i in range(m):
        w[i] = exp32(ll[i] - shift) if finite else _ONE
    return _sum8(w)


@njit(**_JIT)
def calibrated_assimilate(src, origin, sign, lo, inv, n1, base, table, reading, u0, jitter_idx,  # pragma: no cover
                          normal_table, half, out, mean, cov, scale, bins, counts):
    """One calibrated measurement update of k clouds, one env at a time in cache:
    :func:`calibrated_log_likelihood` at the offsets ``sign·(particle − origin)``,
    ``belief.normalise_log_weights`` (the shifted ``exp32`` and its :func:`row_sums` total), then
    :func:`resample_jitter_clip` — the single env's ``assimilate(model.log_likelihood(...))`` in the
    same float operations.

    Args:
        src: (k, 2, M) float32 particles, coordinate-major, mm.
        origin: (k, 2) float32 frame origin, mm: the carriage (target localisation, ``sign`` = 1:
            offsets = target hypothesis − carriage) or the map origin (self-localisation, ``sign`` = −1:
            offsets = − carriage hypothesis); also the histogram's centre.
        sign: float32 ±1.
        lo: as :func:`calibrated_log_likelihood`.
        inv: as :func:`calibrated_log_likelihood`.
        n1: as :func:`calibrated_log_likelihood`.
        base: as :func:`calibrated_log_likelihood`.
        table: as :func:`calibrated_log_likelihood`.
        reading: as :func:`calibrated_log_likelihood`.
        u0: as :func:`resample_jitter_clip`.
        jitter_idx: as :func:`resample_jitter_clip`.
        normal_table: as :func:`resample_jitter_clip`.
        half: as :func:`resample_jitter_clip`.
        out: as :func:`resample_jitter_clip`.
        mean: as :func:`resample_jitter_clip`.
        cov: as :func:`resample_jitter_clip`.
        scale: as :func:`resample_jitter_clip`.
        bins: as :func:`resample_jitter_clip`.
        counts: as :func:`resample_jitter_clip`.

    ``out`` may be ``src`` (an update in place: each cloud is first copied to a scratch buffer, and
    the new cloud is written over the old one, whose cache lines the update has just read).

    Returns −1, or the first env whose log-likelihood is NaN (that env and those after it are left
    unchanged).
    """
    k, _, m = src.shape
    px = np.empty(m, dtype=np.float32)
    py = np.empty(m, dtype=np.float32)
    ll = np.empty(m, dtype=np.float32)
    sd = np.empty(m, dtype=np.float32)
    rows = np.empty(m, dtype=np.int32)
    txs = np.empty(m, dtype=np.float32)
    tys = np.empty(m, dtype=np.float32)
    w = np.empty(m, dtype=np.float32)
    scratch = _resample_scratch(m, bins)
    for e in range(k):
        px[:] = src[e, 0]
        py[:] = src[e, 1]
        _calibrated_ll_one(px, py, origin[e, 0], origin[e, 1], sign, lo[e], inv[e], n1[e], base[e],
                           table, reading[e], ll, sd, rows, txs, tys)
        total = _shifted_exp_one(ll, w)  # float32 weights (a separate buffer: in place, the exp pass
        if total != total:             # fails LLVM's runtime overlap check and does not vectorise)
            return e
        _resample_one(w, total, u0[e], px, py, jitter_idx[e], normal_table, half[e],
                      out[e, 0], out[e, 1], mean, cov, origin[e, 0], origin[e, 1], scale[e], bins, counts, e,
                      *scratch)
    return -1


@njit(**_JIT)
def box_affine(u, low, span, out_x, out_y):  # pragma: no cover - compiled
    """``low + span · u`` for uniform draws ``u`` (n, 2) float64, column c into ``out_c`` (cast on store).

    numpy's ``low + (high − low) * u`` with ``span = high − low`` (2,) — the same float64 operations —
    without its slow broadcast over an inner axis of length 2.
    """
    lx = low[0]
    ly = low[1]
    sx = span[0]
    sy = span[1]
    for j in range(u.shape[0]):
        out_x[j] = lx + sx * u[j, 0]
        out_y[j] = ly + sy * u[j, 1]


@njit(**_JIT)
def table_gather(table, idx, out):  # pragma: no cover - compiled
    """``out[i] = table[idx[i]]`` (1-D; numpy's fancy indexing first converts uint16 indices to intp)."""
    for i in range(idx.shape[0]):
        out[i] = table[idx[i]]


@njit(**_JIT)
def noisy_saturated(mean, idx, table, std, sat, out):  # pragma: no cover - compiled
    """``np.clip(mean + table[idx].astype(float64) · std, −sat, sat)`` over 1-D float64 arrays (same bits)."""
    for i in range(mean.shape[0]):
        v = mean[i] + np.float64(table[idx[i]]) * std
        v = v if v >= -sat else -sat
        out[i] = v if v <= sat else sat


@njit(**_JIT)
def mean_cov_rows(px, py, mean, cov):  # pragma: no cover - compiled
    """Mean (k, 2) and population covariance (k, 2, 2), float64, of k unweighted clouds.

    Two sequential float64 passes per cloud: ``μ = Σ x / M``, then ``Σ = Σ (x − μ)(x − μ)ᵀ / M``.

    Args:
        px: (k, M) particle x (float32 or float64, any strides), mm.
        py: (k, M) particle y, mm.
        mean: (k, 2) float64 output, mm.
        cov: (k, 2, 2) float64 output, mm².
    """
    for e in range(px.shape[0]):
        _mean_cov_one(px[e], py[e], mean, cov, e)


@njit(**_JIT)
def egocentric_counts(px, py, carriage, scale, bins, out):  # pragma: no cover - compiled
    """Particle counts (k, bins²) on a bins×bins grid of offsets around each carriage.

    Stands for ``observation._egocentric_histogram`` without weights, in the particles' dtype::

        rel = (p − carriage.astype(dtype)) / scale + 0.5        # scale = (2·H).astype(dtype)
        ij = np.clip((rel · bins).astype(intp), 0, bins − 1);  cell = i·bins + j

    Args:
        px: (k, M) particle x, mm.
        py: (k, M) particle y, mm.
        carriage: (k, 2) carriage centres cast to the particles' dtype, mm.
        scale: (k,) 2·H in the particles' dtype, mm.
        bins: cells per axis.
        out: (k, bins²) float64 counts.
    """
    cells = np.empty(px.shape[1], dtype=np.int32)
    hist = np.empty((4, bins * bins), dtype=np.int32)
    for e in range(px.shape[0]):
        _counts_one(px[e], py[e], carriage[e, 0], carriage[e, 1], scale[e], bins, out, e, cells, hist)


@njit(inline="always")
def _clip1(v):  # pragma: no cover - compiled
    """``np.clip(v, −1, 1)`` (NaN stays NaN)."""
    v = -1.0 if v < -1.0 else v
    return 1.0 if v > 1.0 else v


@njit(**_JIT)
def belief_observation_rows(carriage, reading, mean, cov, n_obs, max_obs, hw, noise, sat, success,  # pragma: no cover
                            hist, desc, out):
    """The belief observations (k, 81) float32 of k clouds from their statistics (see
    :mod:`electroloc_gym.envs.observation` for the layout), float64 arithmetic, then cast.

    Args:
        carriage: (k, 2) carriage centres, mm.
        reading: (k,) last readings, V.
        mean: (k, 2) belief means, mm.
        cov: (k, 2, 2) belief covariances, mm².
        n_obs: (k,) float64 readings fused so far.
        max_obs: the observation cap.
        hw: (k,) allowed half-widths H, mm.
        noise: (k,) G·σ_s, V.
        sat: (k,) saturation, V.
        success: the success threshold on √trace Σ, mm.
        hist: (k, 64) float64 histogram mass fractions.
        desc: (k, 5) float32 condition descriptors.
        out: (k, 81) float32 output.
    """
    for e in range(carriage.shape[0]):
        cx = carriage[e, 0]
        cy = carriage[e, 1]
        h = hw[e]
        c00 = cov[e, 0, 0]
        c11 = cov[e, 1, 1]
        sx = np.sqrt(c00 if c00 > 0.0 else 0.0)
        sy = np.sqrt(c11 if c11 > 0.0 else 0.0)
        sxy = sx * sy
        rho = cov[e, 0, 1] / (sxy if sxy > 1e-12 else 1e-12) if sxy > 1e-12 else 0.0
        tr = c00 + c11
        spread = np.sqrt(tr if tr > 0.0 else 0.0)
        r = reading[e]
        out[e, 0] = np.float32(_clip1(cx / h))
        out[e, 1] = np.float32(_clip1(cy / h))
        out[e, 2] = np.float32(_clip1(r / sat[e]))
        out[e, 3] = np.float32(_clip1(np.tanh(r / (3.0 * noise[e]))))
        out[e, 4] = np.float32(_clip1((mean[e, 0] - cx) / (2.0 * h)))
        out[e, 5] = np.float32(_clip1((mean[e, 1] - cy) / (2.0 * h)))
        out[e, 6] = np.float32(_clip1(sx / h))
        out[e, 7] = np.float32(_clip1(sy / h))
        out[e, 8] = np.float32(_clip1(rho))
        out[e, 9] = np.float32(_clip1(spread / h))
        out[e, 10] = np.float32(_clip1(np.log10((spread if spread > 1e-6 else 1e-6) / success)))
        out[e, 11] = np.float32(_clip1(n_obs[e] / max_obs))
        nh = hist.shape[1]
        for c in range(nh):
            out[e, 12 + c] = np.float32(hist[e, c])
        for c in range(desc.shape[1]):
            out[e, 12 + nh + c] = desc[e, c]


@njit(**_JIT)
def calibration_tables(samples, min_std, mean_out, std_out):  # pragma: no cover - compiled
    """Per grid point mean and sample std (ddof = 1, floored at ``min_std``) of calibration readings.

    Sequential float64 sums over the samples (the calibrated sensor model and the vector env's
    per-episode calibration both call this, so both get the same bits).

    Args:
        samples: (S, n, n) float64 readings, V (S ≥ 2).
        min_std: floor of the std, V.
        mean_out: (n, n) float64 output, mean per point, V.
        std_out: (n, n) float64 output, floored std per point, V.
    """
    s, nx, ny = samples.shape
    fs = np.float64(s)
    for a in range(nx):
        for b in range(ny):
            acc = samples[0, a, b]
            for t in range(1, s):
                acc += samples[t, a, b]
            mu = acc / fs
            ss = 0.0
            for t in range(s):
                d = samples[t, a, b] - mu
                ss += d * d
            sd = np.sqrt(ss / (fs - 1.0))
            mean_out[a, b] = mu
            std_out[a, b] = sd if sd > min_std else min_std


@njit(**_JIT)
def _cell_coefficients(t, a, b, out, r, col):  # pragma: no cover - compiled
    """``t00, t10 − t00, t01 − t00, t11 − t10 − t01 + t00`` of cell (a, b) of ``t`` into ``out[r, col:col + 4]``."""
    v00 = t[a, b]
    v10 = t[a + 1, b]
    v01 = t[a, b + 1]
    v11 = t[a + 1, b + 1]
    out[r, col] = v00
    out[r, col + 1] = v10 - v00
    out[r, col + 2] = v01 - v00
    out[r, col + 3] = v11 - v10 - v01 + v00


@njit(**_JIT)
def bilinear_coefficients(mean, std, outside_std, out):  # pragma: no cover - compiled
    """Per-cell bilinear coefficients of the mean and std tables, and the "outside the grid" row.

    Row ``a·n1 + b`` holds, for each table ``t`` (mean, then std), ``t00, t10 − t00, t01 − t00,
    t11 − t10 − t01 + t00`` (value = c0 + c1·tx + c2·ty + c3·tx·ty in the cell); the last row is
    ``(0, 0, 0, 0, outside_std, 0, 0, 0)`` (no target: mean 0 V). ``out`` may be float32 (cast on store).

    Args:
        mean: (n, n) float64 mean table, V.
        std: (n, n) float64 std table, V.
        outside_std: std outside the grid, V.
        out: (n1² + 1, 8) output, n1 = n − 1.
    """
    n1 = mean.shape[0] - 1
    for a in range(n1):
        for b in range(n1):
            _cell_coefficients(mean, a, b, out, a * n1 + b, 0)
            _cell_coefficients(std, a, b, out, a * n1 + b, 4)
    last = n1 * n1
    for c in range(8):
        out[last, c] = 0.0
    out[last, 4] = outside_std
