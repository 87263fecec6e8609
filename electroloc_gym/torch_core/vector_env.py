"""ElectroLoc-v0's torch backend behind Gymnasium's ``VectorEnv`` (Gymnasium's torch conventions).

``gym.make_vec("ElectroLoc-v0", num_envs=N, vectorization_mode="vector_entry_point", backend="torch",
device="cuda")`` builds a :class:`TorchElectroLocVectorEnv`: observations (N, 81) float32, rewards (N,)
float64, terminated and truncated (N,) bool and the info's entries are tensors on ``device``; actions
may be tensors there (or anything ``torch.as_tensor`` takes). Autoreset is Gymnasium's
``NEXT_STEP``. A numpy view: :func:`numpy_view` (Gymnasium's ``ArrayConversion`` wrapper). The paper's
controllers read a sub-env through :meth:`TorchElectroLocVectorEnv.sub_env` (the single env's agent
accessors).

Seeding is Gymnasium's: ``reset(seed=s)`` gives sub-env i child i of ``SeedSequence(s)`` (as the numba
vector env spreads an int seed), ``reset(seed=[...])`` one seed per sub-env (its ``SeedSequence``),
None fresh entropy; a sub-env's key is the first two words of its seed sequence, so its episodes depend
on its seed and its actions only (:mod:`.rng`). ``compile=True`` runs the step through
``torch.compile(fullgraph=True)`` (``compile_backend``: inductor by default). On the CPU a step computes
the reset draws for the resetting envs only (:func:`.sim.begin_episodes`' ``gather``; the same values),
eagerly, writing them into the calibration tables in place (:data:`OWN_IN_PLACE`), and compiles the rest
(:func:`.sim.advance`); on an accelerator the whole step is one graph.
Inductor's generated code rounds its exponentials and sums its own way, so a compiled step agrees with
the eager one to float rounding (the same distribution), not bit for bit.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import gymnasium as gym
import numpy as np
import torch
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from electroloc_gym.checks import check_int
from electroloc_gym.core.observation import BELIEF_OBS_DIM, RAW_OBS_DIM
from electroloc_gym.core.params import EnvParams
from electroloc_gym.envs.actions import spaces_of
from electroloc_gym.torch_core import sim
from electroloc_gym.torch_core.consts import TorchConsts, torch_entry
from electroloc_gym.torch_core.sub_env import TorchSubEnv

__all__ = ["TorchElectroLocVectorEnv", "numpy_view", "OWN_IN_PLACE"]

#: The state tensors a CPU step updates in place (the calibration tables: never handed out by ``step`` or
#: ``reset``; ``state["table"]`` is the live buffer). Every other tensor a step returns is new.
OWN_IN_PLACE = ("table",)


def _device(value: Any) -> torch.device:
    try:
        return torch.device(value)
    except (RuntimeError, TypeError) as exc:
        raise ValueError(f"device must be a torch device name such as 'cpu' or 'cuda', got {value!r}") from exc


def _seed_words(seed: int | np.random.SeedSequence | None) -> tuple[int, int]:
    """The two 32-bit key words of a sub-env seed or seed sequence (None: fresh entropy)."""
    seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    w = seq.generate_state(2, np.uint32)
    return int(w[0]), int(w[1])


def _is_seed(value: Any) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)) and bool(value >= 0)


def _key_words(seed: Any, n: int) -> list[tuple[int, int] | None]:
    """Each sub-env's key words of ``reset``'s ``seed`` (None: keep or draw fresh): an int s gives sub-env i
    child i of ``SeedSequence(s)``, a sequence one seed per sub-env; anything else one ValueError.
    """
    if seed is None:
        return [None] * n
    if _is_seed(seed):
        return [_seed_words(child) for child in np.random.SeedSequence(int(seed)).spawn(n)]
    ok = isinstance(seed, (list, tuple, np.ndarray)) and len(seed) == n and all(v is None or _is_seed(v) for v in seed)
    if not ok:
        raise ValueError(
            f"seed must be None, an integer ≥ 0 or a sequence of {n} seeds (each None or an integer ≥ 0), got {seed!r}"
        )
    return [None if v is None else _seed_words(int(v)) for v in seed]


class TorchElectroLocVectorEnv(VectorEnv):
    """N ElectroLoc-v0 envs as one torch core on ``device`` (module docstring).

    Args:
        num_envs: N (≥ 1).
        device: the torch device ("cpu", "cuda", "cuda:1", …).
        compile: run the step through ``torch.compile(fullgraph=True)`` (on the CPU: the step after the
            resets' draws).
        compile_backend: ``torch.compile``'s backend ("inductor", or "eager" to check the capture only).
        render_mode: must be None.
        autoreset_mode: ``AutoresetMode.NEXT_STEP`` (the only mode of the torch core).
        **kwargs: the single env's arguments (:class:`~electroloc_gym.core.params.EnvParams`).
    """

    metadata: dict[str, Any] = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}

    def __init__(
        self,
        num_envs: int = 1,
        device: Any = "cpu",
        compile: bool = False,  # noqa: A002 - torch's word
        compile_backend: str = "inductor",
        render_mode: str | None = None,
        autoreset_mode: Any = AutoresetMode.NEXT_STEP,
        **kwargs: Any,
    ) -> None:
        n = check_int("num_envs", num_envs, 1)
        if render_mode is not None:
            raise ValueError(f"render_mode must be None for the torch vector env, got {render_mode!r}")
        if autoreset_mode not in (AutoresetMode.NEXT_STEP, "next_step", AutoresetMode.NEXT_STEP.value):
            raise ValueError(
                f"autoreset_mode: backend='torch' implements AutoresetMode.NEXT_STEP only, got {autoreset_mode!r}"
            )
        if not isinstance(compile, bool):
            raise ValueError(f"compile must be a bool, got {compile!r}")
        entry = torch_entry()
        self.params = EnvParams.from_kwargs(entry.task, kwargs, entry.env_id)
        self.device = _device(device)
        self.consts = TorchConsts.build(self.params, self.device)
        self.num_envs = n
        self.render_mode = None
        self.autoreset_mode = AutoresetMode.NEXT_STEP
        self.metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}
        obs_dim = BELIEF_OBS_DIM if self.params.observation == "belief" else RAW_OBS_DIM
        self.single_action_space, self.single_observation_space = spaces_of(self.params, obs_dim)
        self.action_space = batch_space(self.single_action_space, n)
        self.observation_space = batch_space(self.single_observation_space, n)
        self._state = sim.empty_state(self.consts, n)
        self._started = False
        #: the resets' draws for the resetting envs only: on the CPU, where no host synchronisation exists
        self.gather_resets = self.device.type == "cpu"
        self._step_fn = self._make_step(compile, compile_backend)

    def _make_step(self, compile_step: bool, backend: str) -> Any:
        """The step function: on the CPU the gathered resets (eager) then :func:`.sim.advance` (compiled with
        ``compile``); elsewhere :func:`.sim.step` as one graph (compiled with ``compile``).
        """
        c = self.consts
        if not self.gather_resets:
            whole = lambda state, actions: sim.step(c, state, actions)  # noqa: E731 - the compiled unit
            return torch.compile(whole, fullgraph=True, backend=backend) if compile_step else whole
        rest = lambda state, actions, reset: sim.advance(c, state, actions, reset)  # noqa: E731
        if compile_step:
            rest = torch.compile(rest, fullgraph=True, backend=backend)

        def step_fn(state: sim.State, actions: torch.Tensor) -> Any:
            reset = state["done"]
            return rest(sim.begin_episodes(c, state, reset, gather=True, in_place=OWN_IN_PLACE), actions, reset)

        return step_fn

    # ---- accessors ------------------------------------------------------------------------------
    @property
    def state(self) -> dict[str, torch.Tensor]:
        """The core's state tensors (read-only use: the particles (N, 2, M) mm, the means, …); a step replaces
        them with new tensors, except those of :data:`OWN_IN_PLACE`, which a CPU step updates in place.
        """
        return self._state

    def sub_env(self, index: int) -> TorchSubEnv:
        """Sub-env ``index`` through the single env's agent accessors (belief, carriage, predicted readings:
        :class:`~.sub_env.TorchSubEnv`), so the paper's controllers run on this backend; call after ``reset``.
        """
        i = check_int("index", index, 0, self.num_envs - 1)
        if not self._started:
            raise RuntimeError("call reset() before sub_env()")
        return TorchSubEnv(self, i)

    def memory_bytes_per_env(self) -> int:
        """Bytes of state per env on the device (the step's temporaries come on top, :mod:`.sim`)."""
        return sum(t.element_size() * t[0].numel() for t in self._state.values())

    # ---- gymnasium API ------------------------------------------------------------------------
    def reset(
        self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[torch.Tensor, dict[str, Any]]:
        """Reset every sub-env (or those of ``options["reset_mask"]``, a bool (N,) tensor or array)."""
        n = self.num_envs
        words = _key_words(seed, n)  # checked before any sub-env changes
        mask = torch.ones(n, dtype=torch.bool, device=self.device)
        if options is not None and "reset_mask" in options:
            m = torch.as_tensor(options["reset_mask"], device=self.device)
            if m.dtype != torch.bool or m.shape != (n,) or not bool(m.any()):
                raise ValueError(f"options['reset_mask'] must be a bool array of shape ({n},) with a True entry")
            mask = m
        s = dict(self._state)
        reseed = [i for i, w in enumerate(words) if w is not None or not self._started]
        if reseed:
            fresh = [w if w is not None else _seed_words(None) for w in (words[i] for i in reseed)]
            words_t = torch.tensor(fresh, dtype=torch.int64, device=self.device)
            idx = torch.tensor(reseed, device=self.device)
            sel = torch.zeros(n, dtype=torch.bool, device=self.device)
            sel[idx] = True
            sel &= mask
            k0, k1 = s["k0"].clone(), s["k1"].clone()
            k0[idx], k1[idx] = words_t[:, 0], words_t[:, 1]
            s["k0"], s["k1"] = torch.where(sel, k0, s["k0"]), torch.where(sel, k1, s["k1"])
            s["episode"] = torch.where(sel, torch.full_like(s["episode"], -1), s["episode"])
        s = sim.begin_episodes(self.consts, s, mask)
        s = sim.observe(self.consts, s, mask)
        s["done"] = torch.where(mask, torch.zeros_like(s["done"]), s["done"])
        self._state = s
        self._started = True
        return sim.observation(self.consts, s), sim.info(self.consts, s)

    def step(self, actions: Any) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, dict[str, Any]]:
        """One step of every sub-env (Gymnasium's next-step autoreset)."""
        if not self._started:
            raise RuntimeError("call reset() before step()")
        a = torch.as_tensor(actions, device=self.device)
        want = (self.num_envs,) if self.consts.discrete else (self.num_envs, 2)
        if tuple(a.shape) != want:
            raise ValueError(f"actions must have shape {want}, got {tuple(a.shape)}")
        self._state, obs, rewards, terminated, truncated = self._step_fn(self._state, a)
        return obs, rewards, terminated, truncated, sim.info(self.consts, self._state)

    def close_extras(self, **kwargs: Any) -> None:
        """Nothing to release."""


def numpy_view(env: VectorEnv) -> VectorEnv:
    """The torch vector env seen through numpy arrays (Gymnasium's ``ArrayConversion`` wrapper)."""
    try:
        from gymnasium.wrappers.vector import ArrayConversion
    except ImportError:  # added in gymnasium 1.2
        raise RuntimeError(
            f"numpy_view needs gymnasium >= 1.2 (its ArrayConversion wrapper); this is gymnasium {gym.__version__}"
        ) from None

    device = getattr(env, "device", None)
    if not isinstance(device, torch.device):
        raise TypeError(f"numpy_view needs a torch vector env (a torch.device in its `device`), got {env!r}")
    return ArrayConversion(env, env_xp=torch, target_xp=np, env_device=device, target_device=None)
