"""ElectroLoc-v0's torch backend behind Gymnasium's ``VectorEnv`` (Gymnasium's torch conventions).

``gym.make_vec("ElectroLoc-v0", num_envs=N, vectorization_mode="vector_entry_point", backend="torch",
device="cuda")`` builds a :class:`TorchElectroLocVectorEnv`: observations (N, 81) float32, rewards (N,)
float64, terminated and truncated (N,) bool and the info's entries are tensors on ``device``. Autoreset is
Gymnasium's ``NEXT_STEP``. A numpy view: :func:`numpy_view` (Gymnasium's ``ArrayConversion`` wrapper).
The paper's controllers read a sub-env through :meth:`TorchElectroLocVectorEnv.sub_env` (the single
env's agent accessors). What the torch engine implements of the env's options, and what it refuses, is
the capability table (:mod:`electroloc_gym.contract.capabilities`).

Arguments are checked as the numba vector env checks them, with the same messages
(:mod:`electroloc_gym.utils.checks`, :class:`~electroloc_gym.contract.params.EnvParams`); beside them ``device``
must be one this machine has (:func:`.device.resolve_device`; ``"meta"`` is refused), ``num_envs`` is in
[1, :data:`MAX_NUM_ENVS`] and must fit in the device's memory with the state and a step's peak
(:func:`.device.check_fits`, the estimate traced from the real allocations), ``compile_backend`` names a
registered ``torch.compile`` backend. After ``close()`` (which releases the state) ``step``, ``reset``,
``sub_env`` and the sub-env views raise.

Actions, and the rule that keeps a check from costing an accelerator a host synchronisation per step
(``action_check``):

* checked on the host — numpy arrays, lists, numbers, tensors on another device than the env's (CPU
  tensors for a GPU env), and everything when ``action_check="host"`` or the env is on the CPU (the
  default ``"auto"``): the numba engine's rules and messages (:class:`~electroloc_gym.envs.actions.
  ActionParser`): NaN or infinite continuous actions, discrete ones outside [0, 8] or not integers,
  bool, complex, strings, None, a wrong shape, a meta or sparse tensor (also on the device path) — one
  ValueError naming ``actions``, before anything changes. A device tensor checked on the host costs one
  synchronisation per step.
* checked on the device — a tensor already on the env's accelerator (``action_check="auto"`` there, or
  ``"device"``): its dtype and shape on the host (metadata, no synchronisation: bool, complex, a float
  tensor for discrete actions and a wrong shape are one ValueError); its values on the device, without
  a synchronisation (a few elementwise operations before the step, outside its compiled graph): an
  invalid action (NaN or infinite, a discrete index outside [0, 8]) never enters
  the state — that env's move is zero (the discrete "stay") — and it is reported: ``info["invalid_action"]``
  (N,) bool marks it at that step, :attr:`~TorchElectroLocVectorEnv.invalid_action_count` counts them
  since the last ``reset()``, and the next ``reset()`` — a synchronisation point anyway — raises one
  ValueError saying how many there were (then counts from zero).

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
from typing import Any, cast

import gymnasium as gym
import numpy as np
import torch
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from electroloc_gym.contract.capabilities import check_engine, params_options
from electroloc_gym.contract.observation import BELIEF_OBS_DIM, RAW_OBS_DIM, info_names
from electroloc_gym.contract.params import DISCRETE_MOVES_MM, EnvParams
from electroloc_gym.contract.reset import VECTOR_RESET_OPTIONS, check_first_reset, check_reset_options, reset_mask_error
from electroloc_gym.engines.torch_core import sim
from electroloc_gym.engines.torch_core.consts import TorchConsts, torch_entry
from electroloc_gym.engines.torch_core.device import check_fits, estimate_bytes, resolve_device
from electroloc_gym.envs.actions import ActionParser, spaces_of
from electroloc_gym.envs.agent_view import AgentView, agent_view
from electroloc_gym.envs.torch_sub_env import TorchSubEnv
from electroloc_gym.utils.checks import check_bool, check_choice, check_int, check_seeds

__all__ = [
    "TorchElectroLocVectorEnv",
    "numpy_view",
    "OWN_IN_PLACE",
    "MAX_NUM_ENVS",
    "ACTION_CHECKS",
    "RESET_OPTIONS",
]

#: The state tensors a CPU step updates in place (the calibration tables: never handed out by ``step`` or
#: ``reset``; ``state["table"]`` is the live buffer). Every other tensor a step returns is new.
OWN_IN_PLACE = ("table",)


#: The most envs one torch vector env holds (int32-sized env indices; the memory check refuses far fewer
#: on any device there is).
MAX_NUM_ENVS = 2**31 - 1
#: ``action_check``'s values: where the actions' values are checked (module docstring).
ACTION_CHECKS = ("auto", "host", "device")
#: ``reset``'s options (the numba vector env's: :mod:`electroloc_gym.contract.reset`).
RESET_OPTIONS = VECTOR_RESET_OPTIONS
#: The discrete action that does not move: what an invalid action becomes on the device.
STAY = int(np.flatnonzero(np.all(DISCRETE_MOVES_MM == 0.0, axis=1))[0])
#: Float dtypes numpy holds (a bfloat16 or float8 tensor is widened to float32 for the host check).
_NUMPY_FLOATS = (torch.float16, torch.float32, torch.float64)


def _compile_backend(value: Any) -> str:
    """``compile_backend``: the name of a registered ``torch.compile`` backend, else one ValueError listing
    them (dynamo's registry is read only for a name other than the default, "inductor").
    """
    if isinstance(value, str) and value == "inductor":
        return value
    import torch._dynamo  # noqa: PLC0415 - 1.5 s of import, only for a backend other than the default

    names = sorted(set(torch._dynamo.list_backends(exclude_tags=())) | {"inductor"})
    if not isinstance(value, str) or value not in names:
        raise ValueError(f"compile_backend must be one of torch.compile's backends {names}, got {value!r}")
    return value


def _data_tensor_problem(value: torch.Tensor) -> str | None:
    """Why ``value`` holds no values a check can read (None: it does): a meta tensor (shapes only) or a
    sparse or other non-strided layout.
    """
    if value.is_meta:
        return "a meta tensor (shapes only, no values)"
    if value.layout != torch.strided:
        return f"a {str(value.layout).removeprefix('torch.')} tensor (pass .to_dense())"
    return None


def _seed_words(seed: int | np.random.SeedSequence | None) -> tuple[int, int]:
    """The two 32-bit key words of a sub-env seed or seed sequence (None: fresh entropy)."""
    seq = seed if isinstance(seed, np.random.SeedSequence) else np.random.SeedSequence(seed)
    w = seq.generate_state(2, np.uint32)
    return int(w[0]), int(w[1])


def _is_seed(value: Any) -> bool:
    return isinstance(value, (int, np.integer)) and not isinstance(value, (bool, np.bool_)) and bool(value >= 0)


def _key_words(seed: Any, n: int) -> list[tuple[int, int] | None]:
    """Each sub-env's key words of ``reset``'s ``seed`` (None: keep or draw fresh): an int s gives sub-env i
    child i of ``SeedSequence(s)``, a sequence one seed per sub-env; anything else one ValueError
    (:func:`~electroloc_gym.utils.checks.check_seeds`, the numba vector env's check).
    """
    check_seeds(seed, n)
    if seed is None:
        return [None] * n
    if _is_seed(seed):
        return [_seed_words(child) for child in np.random.SeedSequence(int(seed)).spawn(n)]
    return [None if v is None else _seed_words(int(v)) for v in seed]


def _refuse_dataless(actions: torch.Tensor) -> None:
    """One ValueError naming ``actions`` for a tensor whose values cannot be read (:func:`_data_tensor_problem`)."""
    why = _data_tensor_problem(actions)
    if why is not None:
        raise ValueError(f"actions must be a number array or a dense tensor holding values, got {why}")


class TorchElectroLocVectorEnv(VectorEnv):
    """N ElectroLoc-v0 envs as one torch core on ``device`` (module docstring).

    Args:
        num_envs: N, in [1, :data:`MAX_NUM_ENVS`], and the N envs must fit in the device's memory.
        device: a torch device this machine has ("cpu", "cuda", "cuda:1", "mps", …; not "meta").
        compile: run the step through ``torch.compile(fullgraph=True)`` (on the CPU: the step after the
            resets' draws).
        compile_backend: a registered ``torch.compile`` backend ("inductor", or "eager" to check the
            capture only).
        render_mode: must be None.
        autoreset_mode: ``AutoresetMode.NEXT_STEP`` (the only mode of the torch core).
        action_check: where the actions' values are checked (module docstring): ``"host"`` (every action,
            a ValueError at the step; a device tensor costs a host synchronisation), ``"device"`` (a
            tensor on the env's device is checked there: an invalid action moves nothing, is marked in
            ``info["invalid_action"]`` and raised by the next ``reset()``), ``"auto"`` (the default:
            ``"host"`` on the CPU, ``"device"`` elsewhere).
        **kwargs: the single env's arguments (:class:`~electroloc_gym.contract.params.EnvParams`).
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
        action_check: str = "auto",
        **kwargs: Any,
    ) -> None:
        n = check_int("num_envs", num_envs, 1, MAX_NUM_ENVS)
        compile_step = check_bool("compile", compile)
        backend = _compile_backend(compile_backend)
        check_choice("action_check", action_check, ACTION_CHECKS)
        entry = torch_entry()
        self.params = EnvParams.from_kwargs(entry.task, kwargs, entry.env_id)
        check_engine(
            "torch", {**params_options(self.params), "render_mode": render_mode, "autoreset_mode": autoreset_mode}
        )
        self.device = resolve_device(device)
        self.consts = TorchConsts.build(self.params, self.device)
        check_fits(self.consts, n)  # before any per-env tensor exists
        self.num_envs = n
        self.render_mode = None
        self.autoreset_mode = AutoresetMode.NEXT_STEP
        self.metadata = {
            "autoreset_mode": AutoresetMode.NEXT_STEP,
            "render_modes": [],
            "info_names": info_names(entry.task_class.info_names),
        }
        auto = "host" if self.device.type == "cpu" else "device"
        #: "host" or "device": where a tensor on the env's device has its values checked
        self.action_check = auto if action_check == "auto" else action_check
        obs_dim = BELIEF_OBS_DIM if self.params.observation == "belief" else RAW_OBS_DIM
        self.single_action_space, self.single_observation_space = spaces_of(self.params, obs_dim)
        self.action_space = batch_space(self.single_action_space, n)
        self.observation_space = batch_space(self.single_observation_space, n)
        self._parser = ActionParser(self.params, n)
        self._state = sim.empty_state(self.consts, n)
        self._started = False
        self._invalid = torch.zeros((), dtype=torch.int64, device=self.device)
        #: the resets' draws for the resetting envs only: on the CPU, where no host synchronisation exists
        self.gather_resets = self.device.type == "cpu"
        self._step_fn = self._make_step(compile_step, backend)

    def _make_step(self, compile_step: bool, backend: str) -> Any:
        """The step function: on the CPU the gathered resets (eager) then :func:`.sim.advance` (compiled with
        ``compile``); elsewhere :func:`.sim.step` as one graph (compiled with ``compile``).
        """
        c = self.consts
        if not self.gather_resets:
            k = sim.reset_capacity(self.num_envs)  # the static reset gather's rows
            whole = lambda state, actions: sim.step(c, state, actions, capacity=k)  # noqa: E731 - the compiled unit
            return torch.compile(whole, fullgraph=True, backend=backend) if compile_step else whole
        rest = lambda state, actions, reset: sim.advance(c, state, actions, reset)  # noqa: E731
        if compile_step:
            rest = torch.compile(rest, fullgraph=True, backend=backend)

        def step_fn(state: sim.State, actions: torch.Tensor) -> Any:
            reset = state["done"]
            return rest(sim.begin_episodes(c, state, reset, gather=True, in_place=OWN_IN_PLACE), actions, reset)

        return step_fn

    # ---- accessors ------------------------------------------------------------------------------
    def _check_open(self, what: str) -> None:
        if self.closed:
            raise RuntimeError(f"{what} on a closed env: close() released its state; make a new env")

    @property
    def state(self) -> dict[str, torch.Tensor]:
        """The core's state tensors (read-only use: the particles (N, 2, M) mm, the means, …); a step replaces
        them with new tensors, except those of :data:`OWN_IN_PLACE`, which a CPU step updates in place.
        """
        self._check_open("state")
        return self._state

    def sub_env(self, index: int) -> AgentView:
        """Sub-env ``index`` through the single env's agent accessors (belief, carriage, predicted readings:
        :class:`~.sub_env.TorchSubEnv`), as its agent view (:mod:`electroloc_gym.envs.agent_view`: no route to
        the engine's state), so the paper's controllers run on this backend; call after ``reset``.
        """
        self._check_open("sub_env()")
        i = check_int("index", index, 0, self.num_envs - 1)
        if not self._started:
            raise RuntimeError("call reset() before sub_env()")
        return agent_view(TorchSubEnv(self, i))

    @property
    def invalid_action_count(self) -> int:
        """Invalid actions the device check turned into no move since the last ``reset()`` (module docstring;
        always 0 where every action is checked on the host). Reading it is a host synchronisation.
        """
        return int(self._invalid)

    def memory_estimate_bytes(self) -> int:
        """The device memory this env's constants, state and a step's peak need, bytes
        (:func:`.device.estimate_bytes`: what the constructor checked against the device's memory).
        """
        return estimate_bytes(self.consts, self.num_envs)

    def memory_bytes_per_env(self) -> int:
        """Bytes of state per env on the device (the step's temporaries come on top, :mod:`.sim`)."""
        return sum(t.element_size() * t[0].numel() for t in self.state.values())

    # ---- gymnasium API ------------------------------------------------------------------------
    def reset(
        self, *, seed: int | Sequence[int | None] | None = None, options: dict[str, Any] | None = None
    ) -> tuple[torch.Tensor, dict[str, Any]]:
        """Reset every sub-env (or those of ``options["reset_mask"]``, a bool (N,) array or tensor with a True
        entry, after a first full reset; ``options`` takes :data:`RESET_OPTIONS` only: the numba engine's
        check, :mod:`electroloc_gym.contract.reset`). Everything is checked before any sub-env changes; then
        the invalid actions the device check saw since the last reset, if any, are one ValueError (module
        docstring).
        """
        self._check_open("reset()")
        n = self.num_envs
        words = _key_words(seed, n)
        opts = check_reset_options(options, RESET_OPTIONS)
        mask = self._reset_mask(opts["reset_mask"]) if "reset_mask" in opts else None
        if not self._started:  # reading the mask back is a synchronisation: only before the first reset
            check_first_reset(False, mask is not None and not bool(mask.all()))
        if self.action_check == "device":
            self._raise_invalid_actions()
        if mask is None:
            mask = torch.ones(n, dtype=torch.bool, device=self.device)
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
        return sim.observation(self.consts, s), self._info(torch.zeros(n, dtype=torch.bool, device=self.device))

    def _reset_mask(self, value: Any) -> torch.Tensor:
        """``options["reset_mask"]`` on the device: a bool (N,) array or tensor with a True entry, else the
        numba vector env's ValueError (None included).
        """
        n = self.num_envs
        what = reset_mask_error(n)
        if isinstance(value, np.ndarray):
            if value.dtype != np.bool_ or value.shape != (n,) or not value.any():
                raise ValueError(what)
            return torch.as_tensor(value, device=self.device)
        if not isinstance(value, torch.Tensor) or value.dtype != torch.bool or tuple(value.shape) != (n,):
            raise ValueError(what)
        why = _data_tensor_problem(value)
        if why is not None:
            raise ValueError(f"{what}, got {why}")
        mask = value.detach().to(self.device)
        if not bool(mask.any()):  # reset is a synchronisation point anyway
            raise ValueError(what)
        return mask

    def _raise_invalid_actions(self) -> None:
        count = int(self._invalid)
        if count:
            self._invalid = torch.zeros_like(self._invalid)
            raise ValueError(
                f"actions: {count} invalid action(s) (NaN or infinite, or a discrete index outside [0, "
                f"{len(DISCRETE_MOVES_MM) - 1}]) reached step() on {self.device} since the last reset(); those "
                "envs did not move at those steps (info['invalid_action'] marked them). action_check='host' "
                "makes step() raise at the action itself"
            )

    def host_actions(self, actions: Any) -> torch.Tensor:
        """``actions`` checked on the host by the numba engine's rules (:class:`~electroloc_gym.envs.actions.
        ActionParser`: one ValueError naming ``actions`` and what is allowed), as a tensor on the device
        (discrete: int64). A tensor on an accelerator is copied to the host first (a synchronisation).
        """
        a = actions
        if isinstance(a, torch.Tensor):
            _refuse_dataless(a)
            a = a.detach()
            if a.is_floating_point() and a.dtype not in _NUMPY_FLOATS:
                a = a.to(torch.float32)
            a = a.cpu().numpy()
        self._parser(a)
        arr = np.asarray(a)
        return torch.as_tensor(arr.astype(np.int64) if self.consts.discrete else arr, device=self.device)

    def _device_actions(self, actions: torch.Tensor) -> tuple[torch.Tensor, torch.Tensor]:
        """A tensor on the env's device: dtype and shape checked on the host (metadata), values on the device
        without a synchronisation — (the actions with each invalid one replaced by no move, the (N,) bool
        invalid marks), the count accumulated (module docstring).
        """
        n, discrete = self.num_envs, self.consts.discrete
        a = actions.detach()
        want = (n,) if discrete else (n, 2)
        if a.dtype == torch.bool or a.is_complex() or (discrete and a.is_floating_point()):
            kind = f"{n} integers in [0, {len(DISCRETE_MOVES_MM) - 1}]" if discrete else "integers or reals"
            raise ValueError(f"actions must be a number array of shape {want} ({kind}), got dtype {a.dtype}")
        if tuple(a.shape) != want:
            raise ValueError(f"actions must have shape {want}, got shape {tuple(a.shape)}")
        if discrete:
            bad = (a < 0) | (a >= len(DISCRETE_MOVES_MM))
            clean = torch.where(bad, torch.full_like(a, STAY), a)
        elif a.is_floating_point():
            bad = ~torch.isfinite(a).all(dim=1)
            clean = torch.where(bad[:, None], torch.zeros_like(a), a)
        else:
            bad, clean = torch.zeros(n, dtype=torch.bool, device=a.device), a
        self._invalid = self._invalid + bad.sum()
        return clean, bad

    def step(self, actions: Any) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor, torch.Tensor, dict[str, Any]]:
        """One step of every sub-env (Gymnasium's next-step autoreset); the actions checked as the module
        docstring says.
        """
        self._check_open("step()")
        if not self._started:
            raise RuntimeError("call reset() before step()")
        if self.action_check == "device" and isinstance(actions, torch.Tensor) and actions.device == self.device:
            _refuse_dataless(actions)
            a, invalid = self._device_actions(actions)
        else:
            a, invalid = self.host_actions(actions), torch.zeros(self.num_envs, dtype=torch.bool, device=self.device)
        self._state, obs, rewards, terminated, truncated = self._step_fn(self._state, a)
        return obs, rewards, terminated, truncated, self._info(invalid)

    def _info(self, invalid: torch.Tensor) -> dict[str, torch.Tensor]:
        """The info tensors (:func:`.sim.info`) and ``"invalid_action"`` (N,) bool (module docstring)."""
        info = sim.info(self.consts, self._state)
        info["invalid_action"] = invalid
        return info

    def close_extras(self, **kwargs: Any) -> None:
        """Release the state (the device memory); ``step``, ``reset`` and ``sub_env`` raise from now on."""
        self._state = {}


def numpy_view(env: VectorEnv) -> VectorEnv:
    """The torch vector env seen through numpy arrays (Gymnasium's ``ArrayConversion`` wrapper). Actions and
    reset options reach the env as the numpy arrays they are, so they are checked on the host (the module
    docstring's rule) before they move to the env's device.
    """
    try:
        from gymnasium.wrappers.vector import ArrayConversion
    except (ImportError, gym.error.DependencyNotInstalled) as exc:  # the wrapper: gymnasium >= 1.2, array-api-compat
        if str(getattr(exc, "name", None) or "").split(".")[0] == "array_api_compat" or isinstance(
            exc, gym.error.DependencyNotInstalled
        ):
            raise RuntimeError(
                "numpy_view needs array-api-compat (Gymnasium's ArrayConversion wrapper imports it): "
                'pip install -c constraints.txt "electroloc-gym[train]"'
            ) from None
        raise RuntimeError(
            f"numpy_view needs gymnasium >= 1.2 (its ArrayConversion wrapper); this is gymnasium {gym.__version__}"
        ) from None

    device = getattr(env, "device", None)
    if not isinstance(device, torch.device):
        raise TypeError(f"numpy_view needs a torch vector env (a torch.device in its `device`), got {env!r}")

    class NumpyView(ArrayConversion):
        """Gymnasium's ``ArrayConversion``; an action array it cannot convert (object, string or other
        non-number dtypes) reaches the env's host check instead, for its ValueError.
        """

        def step(self, actions: Any) -> Any:
            if isinstance(actions, np.ndarray) and actions.dtype.kind not in "biufc":
                torch_env = cast(TorchElectroLocVectorEnv, env.unwrapped)  # a torch env: its `device` says so
                torch_env.host_actions(actions)  # raises: the numba engine's message
            return super().step(actions)

    return NumpyView(env, env_xp=np, target_xp=np, env_device=None, target_device=None)
