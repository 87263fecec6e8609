"""One sub-env of the torch vector env seen through the single env's read-only accessors.

The paper's controllers (``baselines``) read their env through a few documented accessors of
``env.unwrapped`` — the belief's particles, weights and moments, the carriage's position, box and move
bounds, and the reading each hypothesis predicts after a move (min-var's Algorithm 1).
:class:`TorchSubEnv` gives those of sub-env ``i`` of a
:class:`~electroloc_gym.envs.torch_vector.TorchElectroLocVectorEnv`, as numpy arrays with the single env's
shapes, dtypes and units, so the same agent objects run on either backend (the benchmark's rows of both).
The predictions are the torch core's own sensor model of that sub-env's episode — its calibration table
(bilinear mean and std) or the analytic model (the saturated physics, std G·σ_s) — evaluated on the device
and copied to the host: a host synchronisation per call, outside the step, as any agent that reads numpy
has. ``tests/test_engine_conformance.py`` checks every accessor against the numba engine's from the same
state.

A view reads the vector env's current state on every access: after ``step`` it shows the new state
(after an autoreset, the new episode's first reading).
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from numpy.typing import ArrayLike, NDArray

from electroloc_gym.contract.motion import carriage_after_move_mm
from electroloc_gym.contract.params import LocalizeOptions
from electroloc_gym.engines.torch_core import belief_update as F
from electroloc_gym.engines.torch_core import sim
from electroloc_gym.protocol import MAX_STEP_MM
from electroloc_gym.utils.checks import check_prediction_args
from electroloc_gym.world.conditions import Condition

__all__ = ["TorchSubEnv", "TorchBeliefView"]


class TorchBeliefView:
    """Sub-env ``i``'s particle belief (the single env's ``BeliefView``): uniform weights after resampling."""

    def __init__(self, env: Any, index: int) -> None:
        self._env = env
        self._index = index
        self.n_particles = int(env.consts.n_particles)
        w = np.full(self.n_particles, 1.0 / self.n_particles)
        w.flags.writeable = False
        self._weights = w

    @property
    def particles(self) -> NDArray[np.float32]:
        """Particle positions (M, 2) float32, mm (a read-only copy from the device)."""
        v = self._env.state["particles_mm"][self._index].T.cpu().numpy().copy()
        v.flags.writeable = False
        return v

    @property
    def weights(self) -> NDArray[np.float64]:
        """Normalised weights (M,), float64: uniform (every reading ends with a resampling)."""
        return self._weights

    @property
    def uniform_weights(self) -> bool:
        """True: the weights are uniform after every update."""
        return True

    def mean(self) -> NDArray[np.float64]:
        """Estimate: the particle mean (2,), mm (the step's, a copy from the device)."""
        return self._env.state["mean_mm"][self._index].cpu().numpy().astype(np.float64, copy=True)

    def covariance(self) -> NDArray[np.float64]:
        """Population covariance Σ (2, 2), mm² (the step's, a copy from the device)."""
        return self._env.state["cov_mm2"][self._index].cpu().numpy().astype(np.float64, copy=True)

    def spread(self) -> float:
        """√trace Σ, mm (the paper's success measure, §5.4)."""
        c = self.covariance()
        return float(np.sqrt(max(c[0, 0] + c[1, 1], 0.0)))


class TorchSubEnv:
    """Sub-env ``index`` of a torch vector env through the single env's agent accessors (module docstring).

    Args:
        env: a :class:`~electroloc_gym.envs.torch_vector.TorchElectroLocVectorEnv` (reset).
        index: the sub-env, in [0, num_envs − 1].
    """

    #: What the hypotheses are: a static target's position (ElectroLoc-v0).
    belief_frame = "target"
    #: No dynamic gain on the torch backend.
    gain_levels = None

    def __init__(self, env: Any, index: int) -> None:
        self._env = env
        self._index = int(index)
        self._belief = TorchBeliefView(env, self._index)
        self._conditions: list[Condition] = list(env.params.options_as(LocalizeOptions).conditions())

    @property
    def unwrapped(self) -> TorchSubEnv:
        """The view itself (what agents bind to: ``env.unwrapped``)."""
        return self

    def _row(self, name: str) -> torch.Tensor:
        return self._env.state[name][self._index]

    @property
    def belief(self) -> TorchBeliefView:
        """The particle belief over the target's position (mm), read-only."""
        return self._belief

    @property
    def condition(self) -> Condition:
        """The sub-env's current episode's condition."""
        return self._conditions[int(self._row("cond"))]

    @property
    def position_mm(self) -> NDArray[np.float64]:
        """The true carriage centre (x, y), mm (a copy)."""
        return self._row("position_mm").cpu().numpy().astype(np.float64, copy=True)

    @property
    def allowed_box_mm(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(low, high) corners of the carriage's allowed box, mm."""
        h = self.condition.allowed_half_width_mm
        return np.array([-h, -h]), np.array([h, h])

    @property
    def move_bounds_mm(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """(lo, hi) moves, mm, within ±10 mm that keep the carriage in the allowed box (0 always inside)."""
        low, high = self.allowed_box_mm
        p = self.position_mm
        lo = np.minimum(np.maximum(-MAX_STEP_MM, low - p), 0.0)
        hi = np.maximum(np.minimum(MAX_STEP_MM, high - p), 0.0)
        return lo, hi

    @property
    def n_observations(self) -> int:
        """Readings fused so far in this episode."""
        return int(self._row("n_observations"))

    @property
    def last_reading_V(self) -> float:
        """The last reading Φ, V."""
        return float(self._row("reading_V"))

    def predicted_particles_mm(self, particles_mm: ArrayLike, moves_mm: ArrayLike) -> NDArray:
        """The hypotheses after a commanded move — the target does not move: (M, 2) for a (2,) move, (C, M, 2)
        for (C, 2) moves (the single env's accessor).
        """
        p, u = self._check(particles_mm, moves_mm)
        return np.broadcast_to(p, u.shape[:-1] + p.shape).copy()

    def predicted_reading_model(
        self, particles_mm: ArrayLike, moves_mm: ArrayLike, gain_level: int | None = None
    ) -> tuple[NDArray, NDArray]:
        """Sensor-model mean and std (V) of the reading each hypothesis predicts after a commanded move (the
        carriage kept in its box), each (M,) for a (2,) move and (C, M) for (C, 2) moves, in the
        particles' precision (the torch core computes in float32).

        Args:
            particles_mm: (M, 2) target hypotheses (normally ``belief.particles``), mm.
            moves_mm: (2,) or (C, 2) commanded moves, mm (clipped to ±``MAX_STEP_MM`` like ``step``).
            gain_level: must be None (the torch backend has no dynamic gain).
        """
        if gain_level is not None:
            raise ValueError(f"gain_level must be None (backend='torch' has no dynamic gain), got {gain_level!r}")
        p, u = self._check(particles_mm, moves_mm)
        c, s, i = self._env.consts, self._env.state, self._index
        k = s["cond"][i : i + 1]
        moves = torch.as_tensor(u.reshape(-1, 2), dtype=torch.float64, device=c.device)
        h = c.half_mm[k]
        carriage = carriage_after_move_mm(torch, s["position_mm"][i : i + 1], moves, h).to(torch.float32)  # (C, 2)
        pt = torch.tensor(p, dtype=torch.float32, device=c.device)
        x = pt[None, :, 0] - carriage[:, 0:1]  # (C, M)
        y = pt[None, :, 1] - carriage[:, 1:2]
        rows = moves.shape[0]
        kk = k.expand(rows)
        if c.calibrated:
            env = torch.full((rows,), i, dtype=torch.int64, device=c.device)
            mean, std = sim.sensor_mean_std(c, s, x, y, env)
        else:
            dip = tuple(d[kk].to(torch.float32) for d in (c.dip_h, c.dip_z2, c.dip_k, c.dip_strength))
            mean = F.analytic_mean(x, y, dip, c.dip_scale[kk].to(torch.float32), c.saturation_V[kk].to(torch.float32))
            std = c.noise_V[kk].to(torch.float32)[:, None].expand_as(mean)
        shape = u.shape[:-1] + (p.shape[0],)
        dtype = p.dtype
        return (
            mean.cpu().numpy().astype(dtype, copy=False).reshape(shape),
            std.cpu().numpy().astype(dtype, copy=False).reshape(shape),
        )

    @staticmethod
    def _check(particles_mm: ArrayLike, moves_mm: ArrayLike) -> tuple[NDArray, NDArray]:
        return check_prediction_args(particles_mm, moves_mm, 2, MAX_STEP_MM)

    def __repr__(self) -> str:
        return f"TorchSubEnv(index={self._index}, num_envs={self._env.num_envs})"
