"""The commutativity claim of §7, tested: K readings fused at once give the same belief as the same readings fused
one by one — exactly for the Bayesian posterior, in distribution for the particle filter.

The paper: "Because of the commutative property of Bayesian filters, the final belief shown in Figure 11 could
have been achieved by four stationary sensor pairs positioned at the four asterisks." Per condition and trial:

1. the carriage stands still at a uniform point of the start box; the ``grid-2x2`` array (four copies of the
   paper's unit, :mod:`electroloc_gym.world.sensor_array`) takes one noisy reading per pair: four readings from four
   positions, exactly what the paper's single pair would read with its carriage at those four positions;
2. **exact**: the posterior on a 1 mm grid over the allowed box (uniform prior), as one product and as four
   normalised updates in order 0..3 and in reverse; the largest |Δp| between them (rounding only);
3. **particle filter** (M particles, uniform in the box, the env's update: shifted float32 weights, systematic
   resampling, jitter N(0, 1 mm²) per axis, clip): the four readings fused at once (one update of the summed
   log-likelihood) and one by one (four updates), from the same initial cloud, each with its own draws.

Across trials it compares the distributions of the posterior mean (x, y), its error |mean − target| and the
spread √trace Σ: two-sample Kolmogorov–Smirnov (``scipy.stats.ks_2samp``) and a paired sign-flip permutation
test of the mean difference (``scipy.stats.permutation_test``), at once against one by one and each against
the exact posterior. A positive control (one reading dropped from the one-by-one filter) shows the tests'
power. docs/extensions.md ("A sensor array") reports seed 0.

    python experiments/array/commutativity.py --seed 0 --trials 200 --out commutativity.json
"""

from __future__ import annotations

import argparse
import os
import sys

for _v in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_v, "1")

import numpy as np  # noqa: E402
from scipy import stats  # noqa: E402

from electroloc_gym.kernels.fusion import assimilate_readings, grid_posterior  # noqa: E402
from electroloc_gym.protocol import N_PARTICLES  # noqa: E402
from electroloc_gym.sensor_models.pairs import ArrayAnalyticSensorModel  # noqa: E402
from electroloc_gym.utils.fileio import check_output_options, write_json_atomic  # noqa: E402
from electroloc_gym.world.conditions import PRESET_NAMES, SIGNAL_CHOICES, get_condition  # noqa: E402
from electroloc_gym.world.sensor_array import array_noisy_reading, named_layout  # noqa: E402

STATISTICS = ("mean_x_mm", "mean_y_mm", "error_mm", "spread_mm")


def _summaries(mean: np.ndarray, cov: np.ndarray, target: np.ndarray) -> dict[str, np.ndarray]:
    return {
        "mean_x_mm": mean[:, 0],
        "mean_y_mm": mean[:, 1],
        "error_mm": np.hypot(mean[:, 0] - target[0], mean[:, 1] - target[1]),
        "spread_mm": np.sqrt(np.maximum(cov[:, 0, 0] + cov[:, 1, 1], 0.0)),
    }


def run_trials(
    condition_name: str,
    layout_name: str,
    seed: int,
    trials: int,
    n_particles: int,
    grid_mm: float = 1.0,
    drop_last_control: bool = True,
    signal: str = "fitted",
) -> dict[str, object]:
    """One condition's trials: the posterior summaries of every method (arrays over trials) and the exact check.

    Trial i draws from ``SeedSequence([seed, i])``: its carriage position and readings, its initial cloud,
    then the draws of the at-once filter, the one-by-one filter and the control, each its own stream.
    """
    condition = get_condition(condition_name, signal)
    layout = named_layout(layout_name, condition.geometry)
    model = ArrayAnalyticSensorModel(condition, layout)
    k_pairs = layout.n_pairs
    half, start = condition.allowed_half_width_mm, condition.start_half_width_mm
    target = np.asarray(condition.target_xy_mm)
    streams = [np.random.SeedSequence([seed, i]).spawn(5) for i in range(trials)]
    gens = [[np.random.default_rng(s) for s in row] for row in streams]
    carriage = np.array([g[0].uniform(-start, start, 2) for g in gens])
    readings = np.stack([array_noisy_reading(condition, layout, target - c, g[0]) for c, g in zip(carriage, gens)])
    clouds0 = np.stack([g[1].uniform(-half, half, (2, n_particles)) for g in gens]).astype(np.float32)
    car32 = carriage.astype(np.float32)

    def pair_loglik(j: int, clouds: np.ndarray) -> np.ndarray:
        off = clouds.transpose(0, 2, 1) - car32[:, None, :]
        return model.pair_log_likelihood(j, readings[:, j, None], off)

    out: dict[str, object] = {}
    for method, stream, at_once, pairs in (
        ("at_once", 2, True, k_pairs),
        ("one_by_one", 3, False, k_pairs),
        ("control_drop_last", 4, False, k_pairs - 1),
    ):
        if method.startswith("control") and not drop_last_control:
            continue
        clouds = clouds0.copy()
        mean, cov = assimilate_readings(
            pair_loglik, pairs, clouds, np.full(trials, half), [g[stream] for g in gens], at_once=at_once
        )
        out[method] = _summaries(mean, cov, target)

    axis = np.arange(-half, half + 1e-9, grid_mm)
    gx, gy = np.meshgrid(axis, axis, indexing="ij")
    grid = np.stack([gx.ravel(), gy.ravel()], axis=-1)
    ex_mean, ex_cov, worst = np.empty((trials, 2)), np.empty((trials, 2, 2)), 0.0
    for i in range(trials):
        off = grid - carriage[i]
        ll = np.stack([model.pair_log_likelihood(j, readings[i, j], off) for j in range(k_pairs)])
        p = grid_posterior(ll, at_once=True)
        for order in (None, list(range(k_pairs))[::-1]):
            worst = max(worst, float(np.max(np.abs(grid_posterior(ll, at_once=False, order=order) - p))))
        m = p @ grid
        d = grid - m
        ex_mean[i], ex_cov[i] = m, (d * p[:, None]).T @ d
    out["exact"] = _summaries(ex_mean, ex_cov, target)
    out["exact_max_abs_diff"] = worst
    return out


def compare(a: np.ndarray, b: np.ndarray, seed: int, paired: bool = True) -> dict[str, float]:
    """KS two-sample p-value, and (paired) the sign-flip permutation p-value of mean(a − b)."""
    res = {"ks_p": float(stats.ks_2samp(a, b).pvalue), "mean_a": float(np.mean(a)), "mean_b": float(np.mean(b))}
    if paired:
        perm = stats.permutation_test(
            (a, b),
            lambda x, y, axis=-1: np.mean(x - y, axis=axis),
            permutation_type="samples",
            n_resamples=9999,
            random_state=seed,
        )
        res["perm_p"] = float(perm.pvalue)
    return res


def main(argv: list[str] | None = None) -> int:
    """Run the comparison over the conditions; print a table, optionally write JSON."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--trials", type=int, default=200)
    ap.add_argument("--particles", type=int, default=N_PARTICLES)
    ap.add_argument("--layout", default="grid-2x2")
    ap.add_argument("--conditions", nargs="*", default=list(PRESET_NAMES))
    ap.add_argument("--signal", default="fitted", choices=SIGNAL_CHOICES, help="the conditions' signal scale")
    ap.add_argument("--out", default=None, help="JSON file of the results")
    args = ap.parse_args(argv)
    check_output_options(ap, files={"--out": args.out})
    report: dict[str, object] = {
        "seed": args.seed,
        "trials": args.trials,
        "particles": args.particles,
        "layout": args.layout,
        "signal": args.signal,
        "conditions": {},
    }
    pairs = (
        ("at_once", "one_by_one"),
        ("at_once", "exact"),
        ("one_by_one", "exact"),
        ("one_by_one", "control_drop_last"),
    )
    print(f"{'condition':18s} {'a vs b':32s} " + " ".join(f"{s:>22s}" for s in STATISTICS))
    for name in args.conditions:
        res = run_trials(name, args.layout, args.seed, args.trials, args.particles, signal=args.signal)
        rows = {}
        for a, b in pairs:
            rows[f"{a} vs {b}"] = {s: compare(res[a][s], res[b][s], args.seed) for s in STATISTICS}
            cells = " ".join(
                f"{r['mean_a']:6.2f}/{r['mean_b']:6.2f} {r['ks_p']:.2f} {r['perm_p']:.2f}"
                for r in rows[f"{a} vs {b}"].values()
            )
            print(f"{name:18s} {a + ' vs ' + b:32s} {cells}")
        print(f"{name:18s} exact: max |p_at_once − p_one_by_one| = {res['exact_max_abs_diff']:.2e}")
        report["conditions"][name] = {"exact_max_abs_diff": res["exact_max_abs_diff"], "tests": rows}
    if args.out:
        write_json_atomic(args.out, report)
        print(f"wrote: {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
