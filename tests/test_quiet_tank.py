"""A quieter tank (paper §7): the noise factor on the amplifier and the detection distance it buys."""

from __future__ import annotations

import json
import math
import os

import gymnasium as gym
import numpy as np
import pytest
from cli_inproc import run_cli  # the command in this process

import electroloc_gym  # noqa: F401  (registers the envs)
from electroloc_gym.cli import parse_noise_factor, quiet_tank_table, zero_crossing_mm
from electroloc_gym.world import detection as D
from electroloc_gym.world.conditions import PRESET_NAMES, Amplifier, Condition, get_condition
from electroloc_gym.world.sensor import expected_reading

QUIET = 1.0 / 32.0
FAR_EQ5, NEAR_EQ5, FAR_LAYOUT = 32**0.2, 32**0.5, 32 ** (1 / 6)
ENV = {**os.environ, "MPLBACKEND": "Agg", "OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1"}


# ---- the field ------------------------------------------------------------------------------
@pytest.mark.parametrize("bad", [0, 0.0, -1.0, -1 / 32, math.nan, math.inf, True, False, "1/32", None])
def test_noise_factor_validation_names_the_field(bad) -> None:
    with pytest.raises(ValueError, match="noise_factor"):
        Amplifier(gain=191.0, noise_rms_mV=0.25, noise_factor=bad)
    with pytest.raises(ValueError, match="noise_factor"):
        get_condition("fresh-steel-12.7").with_noise_factor(bad)


def test_noise_factor_default_scales_noise_and_round_trips() -> None:
    c = get_condition("salt-delrin-38.1")
    assert c.amplifier.noise_factor == 1.0
    q = c.replace(amplifier=Amplifier(c.amplifier.gain, c.amplifier.noise_rms_mV, noise_factor=np.float32(0.25)))
    assert type(q.amplifier.noise_factor) is float
    assert q.noise_std_V == pytest.approx(0.25 * c.noise_std_V, rel=1e-12)
    assert q.amplifier.effective_noise_rms_mV == pytest.approx(0.25 * c.amplifier.noise_rms_mV, rel=1e-12)
    assert q == c.with_noise_factor(0.25) and q.signal_scale == c.signal_scale
    d = json.loads(json.dumps(q.to_dict()))
    assert d["amplifier"]["noise_factor"] == 0.25
    assert Condition.from_dict(d) == q
    old = json.loads(json.dumps(c.to_dict()))
    del old["amplifier"]["noise_factor"]  # a dict written before the field existed
    assert Condition.from_dict(old) == c


# ---- the env and the calibrated model use it ------------------------------------------------
def test_env_reading_noise_and_calibrated_pooled_std_scale_with_noise_factor() -> None:
    base = get_condition("fresh-steel-12.7")
    residual, pooled = {}, {}
    for f in (1.0, QUIET):
        cond = base.replace(amplifier=Amplifier(base.amplifier.gain, base.amplifier.noise_rms_mV, noise_factor=f))
        env = gym.make("ElectroLoc-v0", condition=cond)
        u = env.unwrapped
        res = []
        for seed in range(12):
            env.reset(seed=seed)
            assert u.condition.noise_std_V == pytest.approx(cond.noise_std_V)
            mean = float(expected_reading(cond, np.asarray(cond.target_xy_mm) - u.position_mm))
            res.append((u.last_reading_V - mean, abs(u.last_reading_V) < 0.99 * cond.saturation_V))
        residual[f] = np.array(res)
        assert u.sensor_model_name == "calibrated"
        pooled[f] = float(np.median(u.sensor_model.std_table_V))
        env.close()
    clean = (residual[1.0][:, 1] > 0) & (residual[QUIET][:, 1] > 0)
    assert clean.sum() >= 8
    # The same seeds draw the same standard normals: every noise sample shrinks by the factor.
    np.testing.assert_allclose(residual[QUIET][clean, 0], QUIET * residual[1.0][clean, 0], rtol=2e-3, atol=1e-6)
    assert np.std(residual[1.0][clean, 0]) > 0.3 * base.noise_std_V  # the readings really are noisy
    assert pooled[QUIET] == pytest.approx(QUIET * pooled[1.0], rel=2e-3)
    assert pooled[1.0] == pytest.approx(base.noise_std_V, rel=0.1)


# ---- the physics of the detection distance --------------------------------------------------
def test_eq5_layout_ratio_lies_between_far_and_near_field_laws() -> None:
    """Fig. 5 (one detector, a = 0.05, e = 0.005): a 32× noise cut multiplies r_d by 2 (far) to 5.7 (near)."""

    def rd(n: float) -> float:
        return D.eq6_detection_distance(n, 0.05, 0.005, 1.0)

    ratios = np.array([rd(n * QUIET) / rd(n) for n in np.geomspace(1e-9, 1e-2, 15)])
    assert np.all(ratios >= 0.97 * FAR_EQ5) and np.all(ratios <= 1.01 * NEAR_EQ5)
    assert ratios[0] == pytest.approx(FAR_EQ5, rel=0.05)  # deep far field
    assert ratios[-1] == pytest.approx(NEAR_EQ5, rel=0.05)  # deep near field


@pytest.mark.parametrize("name", PRESET_NAMES)
def test_differential_layout_far_field_follows_one_sixth_power(name: str) -> None:
    """Deep in the far field the differential pair reads ∝ R⁻⁶: ×32^(1/6) per 32× cut, below Eq. 5's ×2."""
    c = get_condition(name, "paper")
    d1, d2 = (c.with_noise_factor(f).detection_distance_mm() for f in (QUIET**2, QUIET**3))
    assert d1 > 2 * zero_crossing_mm(c) and math.isfinite(d2)
    assert FAR_LAYOUT * 0.99 <= d2 / d1 <= FAR_LAYOUT * 1.04 < FAR_EQ5


def test_presets_at_one_thirty_second() -> None:
    """The eight conditions: a near-field distance that stays inside the zero crossing grows < 2×;
    one that jumps the zero-crossing gap grows by more than it would on its branch; all are < 5.7×."""
    rows = quiet_tank_table(QUIET)
    assert [r["condition"] for r in rows] == list(PRESET_NAMES)
    for r in rows:
        zero = float(r["zero_crossing_mm"])
        assert 40.0 < zero < 50.0  # ≈0.9 L for L = 50 mm
        for s in ("paper", "fitted"):
            d1, dq, ratio = float(r[f"{s}_mm"]), float(r[f"{s}_quiet_mm"]), float(r[f"{s}_ratio"])
            assert 1.0 < ratio < NEAR_EQ5 and ratio == pytest.approx(dq / d1, abs=2e-3)
            if r[f"{s}_branch"] == "near→near":
                assert dq < zero and ratio < zero / d1 < FAR_EQ5
            if r[f"{s}_branch"] == "near→far":
                assert d1 < zero < dq
    # With the paper's equations (the §7 technique) every condition starts inside the zero crossing.
    assert all(str(r["paper_branch"]).startswith("near") for r in rows)
    gm = math.exp(np.mean([math.log(float(r["paper_ratio"])) for r in rows]))
    assert 1.5 < gm < 2.5  # "roughly doubled" on average, not row by row


# ---- the CLI --------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("text", "value"), [("1/32", QUIET), ("0.03125", QUIET), (" 1/2 ", 0.5), ("1e-3", 1e-3), ("1", 1.0), ("1e-4", 1e-4)]
)
def test_parse_noise_factor(text: str, value: float) -> None:
    assert parse_noise_factor(text) == pytest.approx(value)


def test_cli_detect_noise_factor_one_thirty_second() -> None:
    out = run_cli("detect", "--noise-factor", "1/32")
    assert out.returncode == 0, out.stderr
    for name in PRESET_NAMES:
        assert name in out.stdout
    assert "roughly doubled" in out.stdout and "×2.00" in out.stdout and "×5.66" in out.stdout
    js = run_cli("detect", "--noise-factor", "0.03125", "--json")
    assert js.returncode == 0, js.stderr
    data = json.loads(js.stdout)
    assert data["noise_factor"] == QUIET and len(data["rows"]) == len(PRESET_NAMES)
    for row, (name, table_row) in zip(data["rows"], zip(PRESET_NAMES, quiet_tank_table(QUIET))):
        assert row == table_row and row["condition"] == name


@pytest.mark.parametrize(
    "bad", ["0", "1/0", "abc", "nan", "inf", "--noise-factor=-1/32", "1e-320", "1e-9", "1e308", "2", "9/100000"]
)
def test_cli_bad_noise_factor_is_one_clear_error(bad: str) -> None:
    args = [bad] if bad.startswith("--") else ["--noise-factor", bad]
    out = run_cli("detect", *args)
    assert out.returncode == 2
    assert "--noise-factor" in out.stderr and "must be a number in [1/10000, 1]" in out.stderr
    assert "Traceback" not in out.stderr and out.stderr.count("\n") == 1


@pytest.mark.parametrize("factor", [1e-4, 1e-3, 1 / 32, 0.5, 1.0])
def test_every_admitted_noise_factor_gives_a_full_table(factor: float) -> None:
    rows = quiet_tank_table(factor)
    assert all(math.isfinite(v) for r in rows for v in r.values() if isinstance(v, float))


def test_cli_detect_plot_writes_png(tmp_path) -> None:
    path = tmp_path / "quiet.png"
    out = run_cli("detect", "--noise-factor", "1/32", "--plot", str(path))
    assert out.returncode == 0, out.stderr
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert not [p for p in os.listdir(tmp_path) if p.endswith(".tmp")]
