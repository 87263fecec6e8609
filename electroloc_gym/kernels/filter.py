"""The particle filter's measurement update (paper §4.1, Algorithm 1): weights, systematic resampling, jitter.

One env at a time, in a few passes over its particles while they are in cache, in place:

* :func:`calibrated_assimilate`: the calibrated model's lookup (:mod:`.lookup`) and the update;
* :func:`loglik_assimilate`: the update from given float32 log-likelihoods (the analytic models);
* :func:`resample_indices` and :func:`jitter_resampled`: the same update of clouds with more coordinates
  than x, y (the unknown target's radius and contrast, the moving target's speed and heading), in two
  passes; :func:`calibrated_log_likelihood` gives such a cloud's calibrated log-likelihoods.

Each ends with the new cloud's mean, covariance and histogram counts (:mod:`.moments`).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from electroloc_gym.kernels.lookup import _calibrated_ll_one
from electroloc_gym.kernels.mathf32 import JIT, exp32, sum8
from electroloc_gym.kernels.moments import _counts_one, _cov_about

__all__ = [
    "calibrated_assimilate",
    "loglik_assimilate",
    "calibrated_log_likelihood",
    "resample_indices",
    "jitter_resampled",
]

_ZERO = np.float32(0.0)
_ONE = np.float32(1.0)
_INF = np.float32(np.inf)


@njit(**JIT)
def _resample_one(
    w,
    t,
    u,
    src_x,
    src_y,
    jitter_idx,
    normal_table,
    h,
    out_x,
    out_y,  # pragma: no cover - compiled
    mean,
    cov,
    cx,
    cy,
    scale,
    bins,
    counts,
    e,
    cum,
    ptr,
    kest,
    first,
    cells,
    hist,
):
    """Normalise, systematically resample, jitter and clip one cloud, then the new cloud's mean,
    covariance (:func:`~electroloc_gym.kernels.mean_cov_rows`'s sums) and histogram counts
    (:func:`~electroloc_gym.kernels.egocentric_counts`'s cells) while it is still in cache.

    Stands for (``w`` the unnormalised ``exp(log_w − max)``, ``t`` its fixed-order total)::

        w = w / t                                                   # normalised weights
        cum = np.cumsum(w); cum /= cum[-1]                          # systematic_resample
        u = (U + np.arange(M)) / M
        idx = np.minimum(np.searchsorted(cum, u, side="right"), M − 1)
        jitter = normal_table[jitter_idx].reshape(M, 2)             # the quantile-table draws (draws.py)
        p = particles[idx] + jitter                                 # resample, jitter (std 1 mm)
        p = np.minimum(np.maximum(p, −H), H)                        # the clip to the box

    ``searchsorted`` without branches: particle ``i`` takes the pointers ``j`` with
    ``cum[i−1] ≤ u[j] < cum[i]``, i.e. ``K(i−1) ≤ j < K(i)`` where ``K(i) = #{j: u[j] < cum[i]}``
    (``K(M−1) = M``: the ``min(·, M − 1)``). ``K(i)`` is ``ceil(M·cum[i] − U)`` up to float rounding
    (computed for all particles in a vectorised pass), corrected by comparing with the pointers
    themselves (the same ``(U + j)/M`` values, so the same comparisons as ``searchsorted``); then
    ``idx[j] = #{i: K(i) ≤ j}`` is a running sum of a histogram of the ``K(i)`` — no data-dependent
    branch per particle. The mean's sums run in the resampling loop, in the same particle order as
    :func:`mean_cov_rows`.

    ``cum``, ``ptr`` (M + 1), ``kest``, ``first`` (M + 1), ``cells``, ``hist`` are scratch
    (:func:`_resample_scratch`); the results go to ``out_x``, ``out_y`` (must not alias the sources)
    and row ``e`` of ``mean``, ``cov``, ``counts``.
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


@njit(**JIT)
def _resample_scratch(m, bins):  # pragma: no cover - compiled
    """Scratch of :func:`_resample_one` for M particles: cum, ptr (M + 1), kest, first (M + 1), cells, hist."""
    return (
        np.empty(m),
        np.empty(m + 1),
        np.empty(m, dtype=np.int32),
        np.empty(m + 1, dtype=np.int64),
        np.empty(m, dtype=np.int32),
        np.empty((4, bins * bins), dtype=np.int32),
    )


@njit(**JIT)
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
    return sum8(w)


@njit(**JIT)
def calibrated_assimilate(
    src,
    origin,
    sign,
    lo,
    inv,
    n1,
    base,
    table,
    reading,
    u0,
    jitter_idx,  # pragma: no cover
    normal_table,
    half,
    out,
    mean,
    cov,
    scale,
    bins,
    counts,
):
    """One calibrated measurement update of k clouds, one env at a time in cache:
    the calibrated model's log-likelihood (:mod:`.lookup`) at the offsets ``sign·(particle − origin)``,
    ``belief.normalise_log_weights`` (the shifted ``exp32`` and its :func:`row_sums` total), then
    ``_resample_one`` — the reference filter's ``assimilate(model.log_likelihood(...))`` in the
    same float operations.

    Args:
        src: (k, 2, M) float32 particles, coordinate-major, mm.
        origin: (k, 2) float32 frame origin, mm: the carriage (target localisation, ``sign`` = 1:
            offsets = target hypothesis − carriage) or the map origin (self-localisation, ``sign`` = −1:
            offsets = − carriage hypothesis); also the histogram's centre.
        sign: float32 ±1.
        lo: (k,) float32 calibration grid origins, mm.
        inv: (k,) float32 inverse grid steps, 1/mm.
        n1: (k,) int64 cells per axis.
        base: (k,) int64 first row of each env's coefficients in ``table``.
        table: (rows, 8) float32 stacked bilinear coefficients (each env's last row: outside the grid).
        reading: (k,) float32 readings, V.
        u0: (k,) float64 resampling offsets U in [0, 1).
        jitter_idx: (k, 2·M) uint16 indices into ``normal_table`` (x, y of particle j at 2j, 2j + 1).
        normal_table: (65536,) float32 standard-normal quantiles (:func:`electroloc_gym.kernels.streams.normal_table`).
        half: (k,) float32 half-width H of the box, mm.
        out: (k, 2, M) float32 new particles.
        mean: (k, 2) float64 output: the new clouds' means, mm.
        cov: (k, 2, 2) float64 output: their covariances, mm².
        scale: (k,) float32 histogram widths 2·H, mm.
        bins: histogram cells per axis.
        counts: (k, bins²) float64 output: the histogram counts.

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
        _calibrated_ll_one(
            px,
            py,
            origin[e, 0],
            origin[e, 1],
            sign,
            lo[e],
            inv[e],
            n1[e],
            base[e],
            table,
            reading[e],
            ll,
            sd,
            rows,
            txs,
            tys,
        )
        total = _shifted_exp_one(ll, w)  # float32 weights (a separate buffer: in place, the exp pass
        if total != total:  # fails LLVM's runtime overlap check and does not vectorise)
            return e
        _resample_one(
            w,
            total,
            u0[e],
            px,
            py,
            jitter_idx[e],
            normal_table,
            half[e],
            out[e, 0],
            out[e, 1],
            mean,
            cov,
            origin[e, 0],
            origin[e, 1],
            scale[e],
            bins,
            counts,
            e,
            *scratch,
        )
    return -1


@njit(**JIT)
def loglik_assimilate(
    ll,
    src,
    origin,
    u0,
    jitter_idx,
    normal_table,
    half,
    out,  # pragma: no cover - compiled
    mean,
    cov,
    scale,
    bins,
    counts,
):
    """One measurement update of k clouds from their float32 log-likelihoods ``ll`` (k, M): the shifted
    ``exp32`` weights and their fixed-order total, then ``_resample_one``'s resampling,
    jitter, clip, statistics and histogram, one env at a time in cache.

    Arguments as :func:`calibrated_assimilate` (``origin`` is only the histogram's centre here);
    ``out`` may be ``src``. Returns −1, or the first env whose log-likelihood is NaN (that env and
    those after it are left unchanged).
    """
    k, _, m = src.shape
    px = np.empty(m, dtype=np.float32)
    py = np.empty(m, dtype=np.float32)
    w = np.empty(m, dtype=np.float32)
    scratch = _resample_scratch(m, bins)
    for e in range(k):
        px[:] = src[e, 0]
        py[:] = src[e, 1]
        total = _shifted_exp_one(ll[e], w)
        if total != total:
            return e
        _resample_one(
            w,
            total,
            u0[e],
            px,
            py,
            jitter_idx[e],
            normal_table,
            half[e],
            out[e, 0],
            out[e, 1],
            mean,
            cov,
            origin[e, 0],
            origin[e, 1],
            scale[e],
            bins,
            counts,
            e,
            *scratch,
        )
    return -1


@njit(**JIT)
def calibrated_log_likelihood(src, origin, sign, lo, inv, n1, base, table, reading, ll):  # pragma: no cover - compiled
    """The calibrated model's float32 log-likelihoods ``ll`` (k, M) of k clouds' positions, one env at a time:
    :func:`calibrated_assimilate`'s first pass (the same ``_calibrated_ll_one``, so the same values), for
    clouds resampled by :func:`resample_indices` and :func:`jitter_resampled` (more coordinates than x, y).

    Arguments as :func:`calibrated_assimilate` (``src`` (k, ≥ 2, M) float32: rows 0–1 are x, y, mm).
    """
    k = src.shape[0]
    m = src.shape[2]
    px = np.empty(m, dtype=np.float32)
    py = np.empty(m, dtype=np.float32)
    sd = np.empty(m, dtype=np.float32)
    rows = np.empty(m, dtype=np.int32)
    txs = np.empty(m, dtype=np.float32)
    tys = np.empty(m, dtype=np.float32)
    for e in range(k):
        px[:] = src[e, 0]
        py[:] = src[e, 1]
        _calibrated_ll_one(
            px,
            py,
            origin[e, 0],
            origin[e, 1],
            sign,
            lo[e],
            inv[e],
            n1[e],
            base[e],
            table,
            reading[e],
            ll[e],
            sd,
            rows,
            txs,
            tys,
        )


@njit(**JIT)
def resample_indices(ll, u0, idx):  # pragma: no cover - compiled
    """Systematic-resampling indices of k clouds from their float32 log-likelihoods ``ll`` (k, M)
    (uniform prior weights): the shifted ``exp32`` weights and their fixed-order total, as in
    :func:`loglik_assimilate`, then ``idx[e] = min(searchsorted(cum, (U + arange(M))/M, "right"), M − 1)``
    as one merge of the sorted pointers with the cumulative weights (exact comparisons only).

    For clouds whose particles carry more than the two position coordinates (the unknown-target env
    resamples position and shape with the same indices). ``u0``: (k,) float64 offsets U in [0, 1);
    ``idx``: (k, M) int64 output. Returns −1, or the first env whose log-likelihood is NaN.
    """
    k, m = ll.shape
    fm = np.float64(m)
    w = np.empty(m, dtype=np.float32)
    cum = np.empty(m)
    for e in range(k):
        t = _shifted_exp_one(ll[e], w)
        if t != t:
            return e
        acc = 0.0
        for i in range(m):
            acc = acc + np.float64(w[i]) / t
            cum[i] = acc
        last = cum[m - 1]
        i = 0
        for j in range(m):
            u = (u0[e] + np.float64(j)) / fm
            while i < m - 1 and cum[i] / last <= u:
                i += 1
            idx[e, j] = i
    return -1


@njit(**JIT)
def jitter_resampled(idx, src, jitter_idx, normal_table, scale, lo, hi, out):  # pragma: no cover - compiled
    """The resampled, jittered and clipped particles of k clouds of D coordinates per particle, after
    :func:`resample_indices` (the unknown-target env: x, y, radius, χ)::

        out[e, d, j] = min(max(src[e, d, idx[e, j]] + scale[d] · z(e, d, j), lo[e, d]), hi[e, d])

    with ``z(e, d, j) = normal_table[jitter_idx[e, (d // 2)·2M + 2j + d % 2]]`` (coordinate pair d // 2 of
    particle j at 2j, 2j + 1 of its block of 2M draws). Float32 throughout, one rounding per operation
    (``scale`` 1 adds the draw itself, 0 leaves the coordinate unjittered).

    Args:
        idx: (k, M) int64 resampling indices.
        src: (k, D, M) float32 particles, coordinate-major.
        jitter_idx: (k, ≥ 2·⌈D/2⌉·M) uint16 normal-table indices.
        normal_table: float32 standard normal quantiles.
        scale: (D,) float32 jitter std per coordinate.
        lo: (k, D) float32 lower bounds per env and coordinate.
        hi: (k, D) float32 upper bounds per env and coordinate.
        out: (k, D, M) float32 output (must not alias ``src``).
    """
    k, d_count, m = src.shape
    for e in range(k):
        for d in range(d_count):
            base = (d // 2) * 2 * m + (d % 2)
            s = scale[d]
            low = lo[e, d]
            high = hi[e, d]
            for j in range(m):
                v = src[e, d, idx[e, j]] + s * normal_table[jitter_idx[e, base + 2 * j]]
                v = low if v < low else v
                out[e, d, j] = high if v > high else v
