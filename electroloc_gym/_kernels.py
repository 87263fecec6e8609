"""Compiled (numba) loops of the particle filter's hot path, shared by the single and the vector env.

Why compiled loops: at M = 2500 particles a numpy step is ~25 elementwise passes, each a separate
C call with its own temporary; the batched env spends most of its time there. Each kernel below is
one pass (or two) over the particles of every env, with no temporaries.

Why the results are *identical* to the numpy code they replace (the native vector env is tested bit
for bit against the single env): every kernel performs the same IEEE operations, in the same dtype
and the same order, as the numpy expression it stands for — quoted beside each kernel. Numba compiles
without ``fastmath``, so LLVM neither reassociates nor contracts ``a*b + c`` into an FMA; float32
constants are written as ``np.float32`` so no operation is silently promoted to float64.
Transcendental functions (``exp``, ``log``) are *not* evaluated here: numpy's SIMD ``exp``/``log`` and
libm's can differ in the last bit, so callers apply numpy's ufuncs between the kernels.

The one place where the single env calls a kernel too is :func:`mean_cov_rows` (the belief's mean and
covariance, :func:`electroloc_gym.belief.weighted_mean_cov` without weights): numpy's summation order
there depends on the memory layout (pairwise along contiguous axes, sequential otherwise, BLAS for
the matmul), so both envs use this sequential float64 sum instead.

Compiled on first use and cached on disk (``cache=True``: a few seconds once per machine).
"""

from __future__ import annotations

import numpy as np
from numba import njit

__all__ = [
    "calibrated_zterm_std",
    "resample_jitter_clip",
    "mean_cov_rows",
    "egocentric_counts",
    "calibration_tables",
    "bilinear_coefficients",
]

_F32_HALF_NEG = np.float32(-0.5)
_F32_HALF = np.float32(0.5)

_JIT = {"cache": True, "nogil": True, "error_model": "numpy"}


@njit(**_JIT)
def calibrated_zterm_std(off, lo, inv, n1, base, table, reading, zterm, std):  # pragma: no cover - compiled
    """The calibrated sensor model's bilinear lookup and Gaussian term for k envs at once.

    Stands for ``CalibratedSensorModel.mean_std`` and ``gaussian_log_likelihood`` in float32 (per env
    ``e``, particle ``i``)::

        fx = (off_x − lo) · inv;  fy = (off_y − lo) · inv     # off = particle − position.astype(float32)
        inside = (fx ≥ 0) & (fx ≤ n1) & (fy ≥ 0) & (fy ≤ n1)
        ix = min(int(fx), n1 − 1);  iy = min(int(fy), n1 − 1);  tx = fx − ix;  ty = fy − iy
        c = coef[ix·n1 + iy if inside else n1²]                       # 8 float32 coefficients
        mean = c0 + c1·tx + c2·ty + c3·tx·ty;  std = c4 + c5·tx + c6·ty + c7·tx·ty
        z = (float32(reading) − mean) / std;  zterm = −0.5·z·z

    The caller finishes with ``zterm − np.log(std)``.

    Three passes per env, so that the two without the table gather vectorise: the cell index and
    (tx, ty) of every particle; the gather and the two bilinear sums; the division and the square.
    ``fx`` is clamped to [−1, n1 + 1] before the integer conversion (the conversion is then in range;
    ``ix`` is the same wherever the particle is inside, and outside the coefficients of ``tx``, ``ty``
    are 0, so any finite value gives the same result).

    Args:
        off: (k, 2, M) float32 sensor-model offsets (target hypothesis − carriage), coordinate-major
            and C-contiguous (so that the first pass vectorises), mm.
        lo: (k,) float32 grid origin, mm.
        inv: (k,) float32 inverse grid step, 1/mm.
        n1: (k,) int64 cells per axis.
        base: (k,) int64 first row of each env's coefficients in ``table``.
        table: (rows, 8) float32 stacked coefficients (each env's last row: outside the grid).
        reading: (k,) float32 readings, V.
        zterm: (k, M) float32 output, −½ z².
        std: (k, M) float32 output, the model's std, V.
    """
    k, _, m = off.shape
    zero = np.float32(0.0)
    below = np.float32(-1.0)
    rows = np.empty(m, dtype=np.int32)
    txs = np.empty(m, dtype=np.float32)
    tys = np.empty(m, dtype=np.float32)
    for e in range(k):
        n1i = np.int32(n1[e])
        n1f = np.float32(n1[e])
        above = np.float32(n1[e] + 1)
        top = np.int32(n1[e] - 1)
        lo_e = lo[e]
        inv_e = inv[e]
        b = np.int32(base[e])
        outside = np.int32(base[e] + n1[e] * n1[e])
        ox = off[e, 0]
        oy = off[e, 1]
        for i in range(m):
            fx = (ox[i] - lo_e) * inv_e
            fy = (oy[i] - lo_e) * inv_e
            ix = min(np.int32(min(max(fx, below), above)), top)
            iy = min(np.int32(min(max(fy, below), above)), top)
            txs[i] = fx - np.float32(ix)
            tys[i] = fy - np.float32(iy)
            inside = (fx >= zero) & (fx <= n1f) & (fy >= zero) & (fy <= n1f)
            rows[i] = b + ix * n1i + iy if inside else outside
        ze = zterm[e]
        se = std[e]
        for i in range(m):
            row = rows[i]
            tx = txs[i]
            ty = tys[i]
            txy = tx * ty
            mean = table[row, 0] + table[row, 1] * tx
            mean = mean + table[row, 2] * ty
            mean = mean + table[row, 3] * txy
            sd = table[row, 4] + table[row, 5] * tx
            sd = sd + table[row, 6] * ty
            sd = sd + table[row, 7] * txy
            ze[i] = mean
            se[i] = sd
        r = reading[e]
        for i in range(m):
            z = (r - ze[i]) / se[i]
            ze[i] = (_F32_HALF_NEG * z) * z


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
def resample_jitter_clip(w, total, u0, src, jitter_idx, normal_table, half, out,  # pragma: no cover - compiled
                         mean, cov, origin, scale, bins, counts):
    """Normalise, systematically resample, jitter and clip k clouds (ParticleBelief.assimilate's tail),
    then each new cloud's mean/covariance (:func:`mean_cov_rows`) and histogram counts
    (:func:`egocentric_counts`) while it is still in cache.

    Stands for, per env (``w`` the unnormalised ``exp(log_w − max)``, ``total`` its ``np.sum``)::

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
    fm = np.float64(m)
    cum = np.empty(m)
    ptr = np.empty(m + 1)
    kest = np.empty(m, dtype=np.int32)
    first = np.empty(m + 1, dtype=np.int64)
    cells = np.empty(m, dtype=np.int32)
    hist = np.empty((4, bins * bins), dtype=np.int32)
    ptr[m] = 2.0  # sentinel above every normalised cumulative weight (≤ 1)
    for e in range(k):
        t = total[e]
        acc = w[e, 0] / t
        cum[0] = acc
        for i in range(1, m):
            acc = acc + w[e, i] / t
            cum[i] = acc
        last = cum[m - 1]
        u = u0[e]
        for j in range(m):
            ptr[j] = (u + np.float64(j)) / fm
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
        h = half[e]
        nh = -h
        idx = np.int64(0)
        sx = 0.0
        sy = 0.0
        for j in range(m):
            idx += first[j]
            x = src[e, 0, idx] + normal_table[jitter_idx[e, 2 * j]]
            y = src[e, 1, idx] + normal_table[jitter_idx[e, 2 * j + 1]]
            x = nh if x < nh else x
            x = h if x > h else x
            y = nh if y < nh else y
            y = h if y > h else y
            out[e, 0, j] = x
            out[e, 1, j] = y
            sx += np.float64(x)
            sy += np.float64(y)
        mean[e, 0] = sx / fm
        mean[e, 1] = sy / fm
        _cov_about(out[e, 0], out[e, 1], sx / fm, sy / fm, cov, e)
        _counts_one(out[e, 0], out[e, 1], origin[e, 0], origin[e, 1], scale[e], bins, counts, e, cells, hist)


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
