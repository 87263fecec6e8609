"""Reset and step of N ElectroLoc-v0 envs as tensor operations on one device (the torch core).

The state is a dict of tensors (:func:`empty_state`); :func:`begin_episodes`, :func:`observe` and
:func:`step` are pure functions of it, with no host synchronisation — no ``.item()``, no transfer, no
Python loop over envs, no branch on tensor values: which envs reset, which are in the box, which
resample which particle are all masks and ``torch.where``. ``torch.compile(step, fullgraph=True)``
captures a whole step in one graph (tested). The one exception is opt-in: ``gather=True`` (below), which
the vector env uses on the CPU only (where it compiles :func:`advance`, the step after the resets).

One step, as :mod:`electroloc_gym.engines.numba_core.step` with ``autoreset="next_step"``: the envs whose episode
ended at the last step start a new one (their draws: condition, calibration, target, start, particles;
reward 0, flags false, the action ignored); the others move by their commanded move, truncated at the
walls; every env takes one reading and fuses it (:mod:`.belief_update`); reward −1, terminated when
√trace Σ ≤ the success spread, truncated at the reading cap (or ``max_episode_steps``). The rules that
are not inner loops are the contract's, shared with the numba engine: the move and the walls
(:mod:`electroloc_gym.contract.motion`), the rewards, the flags and the raw observation
(:mod:`electroloc_gym.contract.observation`), the belief observation's scalars and the info's error and
spread (:mod:`electroloc_gym.contract.belief_summary`).

Every draw is the env's counter-based stream (:mod:`.rng`) at (key, episode, reading index): the
reading's noise and the resampling offset, the jitter (2M table normals), and at a reset the
condition (``condition="random"``), the target (``randomize_target``), the start (2 uniforms), the
particles (2M uniforms) and the calibration. Each draw is a hash of the env's own coordinates, so a
reset's draws can be computed for any subset of the envs with the same values; three schedules
(:func:`begin_episodes`) give the same bits:

* the all-env path: every env's draws, kept where the env resets — a whole reset's work per env per
  step, where one env in 5 to 20 resets;
* ``capacity=K`` (:func:`reset_capacity`; the accelerator's schedule): the first K resetting envs
  gathered into a fixed-shape block (``torch.nonzero_static``), their draws only, scattered back — no
  data-dependent shape, no host synchronisation in the gather. More than K resets at one step (the
  synchronised first episodes of a ``reset()``, all truncated at the reading cap together) take the
  all-env path instead, chosen on the device by ``torch.cond`` on the count: no episode changes;
* ``gather=True`` (the CPU's, where the host is the device): ``nonzero``'s exact count, eagerly.

The state's memory (:func:`state_bytes_per_env`): per env, the particles (2M float32), the histogram
counts and the scalars, and with a per-episode calibration its two float64 grids (mean and std,
:func:`.calibration.calibration_grids`, 2·n² values), from which a lookup forms each cell's
coefficients (:func:`.belief_update.grid_mean_std`). What is per condition — a fixed ``calibration_seed``'s
table, the noise-free grid, the boxes — is kept once (:class:`~.consts.TorchConsts`), not per env.
"""

from __future__ import annotations

import math
from typing import TypedDict

import torch

from electroloc_gym.contract.belief_summary import belief_info_values, belief_spread_mm
from electroloc_gym.contract.motion import carriage_after_move_mm, commanded_moves_mm
from electroloc_gym.contract.observation import RESET_REWARD, STEP_REWARD, episode_flags, raw_observation_values
from electroloc_gym.engines.torch_core import belief_update as F
from electroloc_gym.engines.torch_core.calibration import calibration_grids
from electroloc_gym.engines.torch_core.consts import TorchConsts
from electroloc_gym.engines.torch_core.rng import STREAMS, bits32, normal_pair_indices, stream_key, uniform24, uniform53

__all__ = [
    "empty_state",
    "state_bytes_per_env",
    "reset_capacity",
    "begin_episodes",
    "observe",
    "step",
    "advance",
    "observation",
    "info",
    "sensor_mean_std",
    "State",
]

State = dict[str, torch.Tensor]


class _TensorOptions(TypedDict):
    """The ``dtype`` and ``device`` keywords of a tensor factory (``torch.zeros(n, **opts)``)."""

    dtype: torch.dtype
    device: torch.device


def per_episode_calibration(c: TorchConsts) -> bool:
    """Whether each episode draws its own calibration (the state then holds each env's grids)."""
    return c.calibrated and c.fixed_table is None


def empty_state(c: TorchConsts, num_envs: int) -> State:
    """The state of ``num_envs`` envs before their first reset (keys 0; call :func:`begin_episodes`).

    ``"table"``: (N, 2, n²) float64 each env's calibration grids with a per-episode calibration, else
    (N, 0) (nothing per env: a fixed calibration's table is the condition's, in the constants).
    """
    n, m, dev = num_envs, c.n_particles, c.device
    i64 = _TensorOptions(dtype=torch.int64, device=dev)
    f64 = _TensorOptions(dtype=torch.float64, device=dev)
    table = (n, 2, c.grid_n * c.grid_n) if per_episode_calibration(c) else (n, 0)
    return {
        "k0": torch.zeros(n, **i64),
        "k1": torch.zeros(n, **i64),
        "episode": torch.full((n,), -1, **i64),
        "cond": torch.zeros(n, **i64),
        "position_mm": torch.zeros(n, 2, **f64),
        "target_mm": torch.zeros(n, 2, **f64),
        "particles_mm": torch.zeros(n, 2, m, dtype=torch.float32, device=dev),
        "table": torch.zeros(table, **f64),
        "reading_V": torch.zeros(n, **f64),
        "n_observations": torch.zeros(n, **i64),
        "elapsed": torch.zeros(n, **i64),
        "mean_mm": torch.zeros(n, 2, **f64),
        "cov_mm2": torch.zeros(n, 2, 2, **f64),
        "counts": torch.zeros(n, F.HIST_BINS * F.HIST_BINS, **f64),
        "done": torch.zeros(n, dtype=torch.bool, device=dev),
    }


def state_bytes_per_env(c: TorchConsts) -> int:
    """Bytes of state per env on the device (:func:`empty_state`; a step's temporaries come on top)."""
    return sum(t.element_size() * t[0].numel() for t in empty_state(c, 1).values())


#: The reset rate :func:`reset_capacity` provisions for: one reset per 4 steps per env (an episode of
#: 3 moves and its reset step; the paper's controllers and ppo-belief need 5–6 readings on average,
#: random moves about 11).
RESET_RATE = 0.25
#: The margin above the expected number of resets, in binomial standard deviations.
RESET_SIGMAS = 4.0


def reset_capacity(num_envs: int) -> int:
    """K, the rows of the static reset gather for N envs: ⌈N·p + 4·√(N·p·(1 − p))⌉ with p = 1/4
    (:data:`RESET_RATE`), at most N.

    With next-step autoreset an env resets at most every other step; N·p is the expected number of
    resets when episodes average 4 steps, and 4 binomial standard deviations above it the chance that
    independent episodes overflow is about 3·10⁻⁵ per step (episodes of realistic lengths, 6 steps or
    more, far less). What does overflow — synchronised episodes, such as a whole ``reset()``'s first
    episodes ending at the reading cap together — takes the all-env path for that step
    (:func:`begin_episodes`), so K sets the work, never the result. For N = 1024, K = 312 (30 %); for
    N = 262 144, K = 66 423 (25.3 %).
    """
    n = int(num_envs)
    p = RESET_RATE
    return min(n, math.ceil(n * p + RESET_SIGMAS * math.sqrt(n * p * (1.0 - p))))


def _keep(mask: torch.Tensor, new: torch.Tensor, old: torch.Tensor) -> torch.Tensor:
    """``new`` where ``mask`` (N,) else ``old`` (broadcast over the trailing dims)."""
    return torch.where(mask.reshape(mask.shape + (1,) * (new.dim() - 1)), new, old)


def _reset_draws(c: TorchConsts, k0: torch.Tensor, k1: torch.Tensor, ep: torch.Tensor) -> State:
    """The new episode ``ep`` (n,) of the envs with keys ``k0``, ``k1`` (n,): condition, target, start,
    particles and (calibrated) the calibration table — any subset of the envs, the same values for each.
    """
    zero = torch.zeros_like(ep)

    def key(name: str) -> torch.Tensor:
        return stream_key(k0, k1, ep, zero, STREAMS[name])

    if c.pool > 1:
        cond = (bits32(key("condition"), 1)[:, 0] * c.pool) >> 32
    else:
        cond = zero
    start = c.start_half_mm[cond][:, None]
    if c.randomize_target:
        target = -start + 2.0 * start * uniform53(key("target"), 2)
    else:
        target = c.target_mm[cond]
    position = -start + 2.0 * start * uniform53(key("start"), 2)
    m = c.n_particles
    h = c.half_mm[cond][:, None]
    u = uniform24(key("particles"), 2 * m)
    draws = {
        "cond": cond,
        "target_mm": target,
        "position_mm": position,
        "particles_mm": (-h + 2.0 * h * u).to(torch.float32).reshape(-1, 2, m),
        "n_observations": zero,
        "elapsed": zero,
    }
    if per_episode_calibration(c):
        draws["table"] = calibration_grids(c, cond, k0, k1, ep)
    return draws


def begin_episodes(
    c: TorchConsts,
    s: State,
    mask: torch.Tensor,
    gather: bool = False,
    in_place: tuple[str, ...] = (),
    capacity: int | None = None,
) -> State:
    """The envs of ``mask`` (N,) bool start a new episode (the reset draws; no reading yet).

    Three schedules with the same bits (module docstring): by default the all-env path (every env's draws,
    kept where ``mask`` holds); ``capacity=K`` the static gather of up to K resetting envs, the all-env
    path under ``torch.cond`` when more reset (one graph, no data-dependent shape; K ≥ N is the all-env
    path); ``gather=True`` the exact ``nonzero`` (a data-dependent shape: a host synchronisation on an
    accelerator and a graph break under ``torch.compile``; on the CPU it saves most of a step's work).
    With ``gather``, the state tensors named in ``in_place`` take the new rows in place (for a caller
    that owns them: the vector env's calibration grids, which a copy per step would stream through
    memory); otherwise every changed tensor is new.
    """
    s = dict(s)
    ep = torch.where(mask, s["episode"] + 1, s["episode"])
    s["episode"] = ep
    if gather:
        idx = torch.nonzero(mask).reshape(-1)
        if idx.numel() == 0:
            return s
        for name, value in _reset_draws(c, s["k0"][idx], s["k1"][idx], ep[idx]).items():
            s[name] = s[name].index_copy_(0, idx, value) if name in in_place else s[name].index_copy(0, idx, value)
        return s
    names = _reset_names(c)
    old = tuple(s[name] for name in names)
    n = mask.shape[0]
    if capacity is None or capacity >= n:
        new = _all_env_draws(c, names, mask, s["k0"], s["k1"], ep, *old)
    else:
        k = int(capacity)
        if k < 1:
            raise ValueError(f"capacity must be an integer ≥ 1, got {capacity!r}")

        def all_env(mask: torch.Tensor, k0: torch.Tensor, k1: torch.Tensor, ep: torch.Tensor, *old: torch.Tensor):
            return _all_env_draws(c, names, mask, k0, k1, ep, *old)

        def gathered(mask: torch.Tensor, k0: torch.Tensor, k1: torch.Tensor, ep: torch.Tensor, *old: torch.Tensor):
            return _gathered_draws(c, names, k, mask, k0, k1, ep, *old)

        overflow = mask.sum() > k
        new = torch.cond(overflow, all_env, gathered, (mask, s["k0"], s["k1"], ep, *old))
    s.update(zip(names, new, strict=True))
    return s


def _reset_names(c: TorchConsts) -> tuple[str, ...]:
    """The state tensors a reset draws (:func:`_reset_draws`' keys, in a fixed order)."""
    names = ("cond", "target_mm", "position_mm", "particles_mm", "n_observations", "elapsed")
    return names + ("table",) if per_episode_calibration(c) else names


def _all_env_draws(
    c: TorchConsts,
    names: tuple[str, ...],
    mask: torch.Tensor,
    k0: torch.Tensor,
    k1: torch.Tensor,
    ep: torch.Tensor,
    *old: torch.Tensor,
) -> tuple[torch.Tensor, ...]:
    """The all-env path: every env's draws of episode ``ep``, kept where ``mask`` (new tensors)."""
    draws = _reset_draws(c, k0, k1, ep)
    return tuple(_keep(mask, draws[name], o) for name, o in zip(names, old, strict=True))


def _gathered_draws(
    c: TorchConsts,
    names: tuple[str, ...],
    k: int,
    mask: torch.Tensor,
    k0: torch.Tensor,
    k1: torch.Tensor,
    ep: torch.Tensor,
    *old: torch.Tensor,
) -> tuple[torch.Tensor, ...]:
    """The static gather: the first ``k`` resetting envs (``nonzero_static``), their draws only, scattered
    into new tensors; correct when at most ``k`` envs reset. A padding row stands for env N − 1 and writes
    what that env's own row writes (its draws where it resets, its old values where not), so rows that
    land on the same env agree and the scatter's order cannot matter.
    """
    n = mask.shape[0]
    rows = torch.clamp(torch.nonzero_static(mask, size=k, fill_value=n).reshape(-1), max=n - 1)
    resets = mask[rows]
    draws = _reset_draws(c, k0[rows], k1[rows], ep[rows])
    return tuple(o.index_copy(0, rows, _keep(resets, draws[name], o[rows])) for name, o in zip(names, old, strict=True))


def true_reading_V(c: TorchConsts, s: State) -> torch.Tensor:
    """(N,) float64 noise-free, unsaturated readings of the true targets (the physics in float64)."""
    k = s["cond"]
    off = s["target_mm"] - s["position_mm"]
    delta = F.dipole_difference(off[:, 0], off[:, 1], c.dip_h[k], c.dip_z2[k], c.dip_k[k], c.dip_strength[k])
    return delta * c.dip_scale[k]


def sensor_mean_std(
    c: TorchConsts, s: State, x: torch.Tensor, y: torch.Tensor, env: torch.Tensor | None = None
) -> tuple[torch.Tensor, torch.Tensor]:
    """(R, M) float32 mean and std (V) of the calibrated model at offsets (target − carriage) ``x``, ``y``
    (R, M) float32 mm: row r is env ``env[r]``'s model (None: row i is env i) — its episode's grids, or its
    condition's fixed table.
    """
    env_ = torch.arange(x.shape[0], device=x.device) if env is None else env
    k = s["cond"][env_]
    args = (x, y, c.grid_lo_mm[k], c.grid_inv_mm[k], c.grid_points[k] - 1)
    if c.fixed_table is not None:
        return F.calibrated_mean_std(*args, c.grid_n - 1, c.fixed_table, which=k)
    return F.grid_mean_std(*args, c.grid_n, s["table"], c.noise_V[k], which=env)


def log_likelihood(c: TorchConsts, s: State, particles: torch.Tensor, reading: torch.Tensor) -> torch.Tensor:
    """(N, M) float32 log-likelihoods of the readings (N,) V under each env's sensor model."""
    k = s["cond"]
    origin = s["position_mm"].to(torch.float32)
    r32 = reading.to(torch.float32)
    if c.calibrated:
        x = particles[:, 0] - origin[:, 0:1]
        y = particles[:, 1] - origin[:, 1:2]
        mean, std = sensor_mean_std(c, s, x, y)
        return F.gaussian_log_likelihood(mean, std, r32)
    dip = tuple(d[k].to(torch.float32) for d in (c.dip_h, c.dip_z2, c.dip_k, c.dip_strength))
    return F.analytic_log_likelihood(
        particles,
        origin,
        dip,
        c.dip_scale[k].to(torch.float32),
        c.saturation_V[k].to(torch.float32),
        c.noise_V[k].to(torch.float32),
        r32,
    )


def observe(c: TorchConsts, s: State, mask: torch.Tensor | None = None) -> State:
    """Every env (or those of ``mask``) takes a noisy reading and fuses it into its belief."""
    s = dict(s)
    k = s["cond"]
    t = s["n_observations"]

    def key(name: str) -> torch.Tensor:
        return stream_key(s["k0"], s["k1"], s["episode"], t + 1, STREAMS[name])

    table = c.normal_table
    noise_idx, _ = normal_pair_indices(key("noise"), 1)
    sat = c.saturation_V[k]
    reading = torch.clamp(
        true_reading_V(c, s) + table[noise_idx[:, 0]].to(torch.float64) * c.noise_V[k], min=-sat, max=sat
    )
    u0 = uniform53(key("resample"), 1)[:, 0]
    jx, jy = normal_pair_indices(key("jitter"), c.n_particles)
    ll = log_likelihood(c, s, s["particles_mm"], reading)
    half = c.half_mm[k]
    particles, _ = F.resample(ll, s["particles_mm"], u0, jx, jy, table, half.to(torch.float32))
    mean, cov, counts = F.statistics(particles, s["position_mm"].to(torch.float32), (2.0 * half).to(torch.float32))
    new = {
        "reading_V": reading,
        "n_observations": t + 1,
        "particles_mm": particles,
        "mean_mm": mean,
        "cov_mm2": cov,
        "counts": counts,
    }
    for name, value in new.items():
        s[name] = value if mask is None else _keep(mask, value, s[name])
    return s


def observation(c: TorchConsts, s: State) -> torch.Tensor:
    """(N, obs_dim) float32 observations (the "belief" or "raw" layout)."""
    k = s["cond"]
    half = c.half_mm[k]
    if not c.belief_obs:
        raw = raw_observation_values(torch, s["position_mm"], s["reading_V"], half, c.saturation_V[k])
        return raw.to(torch.float32)
    return F.belief_observation(
        s["position_mm"],
        s["reading_V"],
        s["mean_mm"],
        s["cov_mm2"],
        s["counts"] / c.n_particles,
        s["n_observations"],
        c.max_observations,
        half,
        c.noise_V[k],
        c.saturation_V[k],
        c.success_spread_mm,
        c.descriptor[k],
    )


def info(c: TorchConsts, s: State) -> dict[str, torch.Tensor]:
    """The info tensors (the numba core's numeric ``INFO_KEYS``; ``condition_index``: the condition's index
    in :data:`~electroloc_gym.world.conditions.PRESET_NAMES`, −1 for a custom condition, as the numba envs').
    """
    error, spread, success = belief_info_values(torch, s["mean_mm"], s["cov_mm2"], s["target_mm"], c.success_spread_mm)
    return {
        "position_mm": s["position_mm"],
        "estimate_mm": s["mean_mm"],
        "error_mm": error,
        "spread_mm": spread,
        "reading_V": s["reading_V"],
        "n_observations": s["n_observations"],
        "success": success,
        "condition_index": c.preset_index[s["cond"]],
    }


def moves_of(c: TorchConsts, actions: torch.Tensor) -> torch.Tensor:
    """(N, 2) float64 commanded moves (mm) of the actions, by the rule both engines share
    (:func:`~electroloc_gym.contract.motion.commanded_moves_mm`).
    """
    a = actions.to(torch.int64).reshape(-1) if c.discrete else actions.to(torch.float64)
    return commanded_moves_mm(torch, a, c.discrete, c.moves_mm)


def step(
    c: TorchConsts, s: State, actions: torch.Tensor, gather: bool = False, capacity: int | None = None
) -> tuple[State, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """One step of every env (module docstring): (state, observations, rewards, terminated, truncated);
    ``gather`` or ``capacity``: the resets' schedule (:func:`begin_episodes`; the same bits). It is
    :func:`begin_episodes` of the envs whose episode ended, then :func:`advance`.
    """
    reset = s["done"]
    return advance(c, begin_episodes(c, s, reset, gather, capacity=capacity), actions, reset)


def advance(
    c: TorchConsts, s: State, actions: torch.Tensor, reset: torch.Tensor
) -> tuple[State, torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor]:
    """The step after the resets' draws: the envs not in ``reset`` (N,) bool move, every env reads and fuses,
    then reward, termination and truncation (:func:`step`). One graph with no data-dependent shape: what
    the CPU compiles when its resets are gathered eagerly.
    """
    s = dict(s)
    moving = ~reset
    moved = carriage_after_move_mm(torch, s["position_mm"], moves_of(c, actions), c.half_mm[s["cond"]][:, None])
    s["position_mm"] = _keep(moving, moved, s["position_mm"])
    s = observe(c, s)
    s["elapsed"] = s["elapsed"] + moving.to(torch.int64)
    spread = belief_spread_mm(torch, s["cov_mm2"])
    terminated, truncated = episode_flags(
        spread, s["n_observations"], s["elapsed"], c.success_spread_mm, c.max_observations, c.max_episode_steps
    )
    terminated, truncated = terminated & moving, truncated & moving
    s["done"] = terminated | truncated
    rewards = torch.where(moving, STEP_REWARD, RESET_REWARD).to(torch.float64)
    return s, observation(c, s), rewards, terminated, truncated
