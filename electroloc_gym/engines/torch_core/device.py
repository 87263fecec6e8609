"""The torch core's device: which devices this machine has, and whether N envs fit in one's memory.

:func:`resolve_device` turns the ``device`` argument into a ``torch.device`` this machine can compute on,
or one ValueError naming ``device`` and the devices available (``"meta"``, which holds shapes and no
data, is refused). :func:`check_fits` refuses sizes that cannot fit in the device's memory, as the numba
engine refuses them at construction (:meth:`~electroloc_gym.contract.params.EnvParams.check_memory`), with
the memory needed and the limit named.

The estimate is the real allocation, not a restated formula: one env's step (its reset draws — the
largest step — then the move, the reading, the belief update and the observation) runs on the ``meta``
device — tensors with shapes and no data — under a dispatch mode that follows each allocation and its
release, from the constants (:class:`.consts.TorchConsts`) and the state (:func:`.sim.empty_state`) to
the step's last temporary. Its peak of the bytes alive at once, less the constants, is an env's share;
every tensor of a step but the constants has one row per env, so N envs need the constants plus N
shares (exact where nothing else in the step is independent of N, which the tests check). The step is
eager (a compiled step fuses temporaries and needs less) and on the all-env reset path (every env
resetting), its largest. A change of the state's layout or of the step changes the estimate with it.
"""

from __future__ import annotations

import dataclasses
from typing import Any

import torch
from torch.multiprocessing.reductions import StorageWeakRef
from torch.utils._python_dispatch import TorchDispatchMode
from torch.utils._pytree import tree_leaves

from electroloc_gym.contract.params import memory_limit_bytes
from electroloc_gym.engines.torch_core import sim
from electroloc_gym.engines.torch_core.consts import TorchConsts

__all__ = [
    "available_devices",
    "resolve_device",
    "device_memory_bytes",
    "traced_peak_bytes",
    "env_step_bytes",
    "estimate_bytes",
    "check_fits",
]

META = torch.device("meta")
#: :func:`env_step_bytes` by the constants' shapes: an env of the same sizes is not traced again.
_PEAKS: dict[tuple[Any, ...], int] = {}


def available_devices() -> list[str]:
    """The devices this machine's torch can compute on: ``"cpu"``, then each CUDA, XPU and MPS device."""
    found = ["cpu"]
    if torch.cuda.is_available():
        found += [f"cuda:{i}" for i in range(torch.cuda.device_count())]
    xpu = getattr(torch, "xpu", None)
    if xpu is not None and xpu.is_available():
        found += [f"xpu:{i}" for i in range(xpu.device_count())]
    if torch.backends.mps.is_available():
        found.append("mps")
    return found


def resolve_device(value: Any) -> torch.device:
    """``value`` (a ``torch.device``, a name such as ``"cuda:1"``, or an index) as the device a tensor made
    there reports (``"cuda"`` → ``cuda:0``); else one ValueError naming ``device`` and the devices available.
    """
    what = f"device must be a torch device this machine has, one of {available_devices()}"
    try:
        device = torch.device(value)
    except (RuntimeError, TypeError, ValueError):
        raise ValueError(f"{what}, got {value!r}") from None
    if device.type == "meta":
        raise ValueError(f"{what}, got {value!r} (a meta tensor holds shapes and no data: nothing to step)")
    try:
        probe = torch.empty(0, device=device)
    except Exception as exc:  # noqa: BLE001 - torch raises AssertionError, RuntimeError, NotImplementedError …
        text = str(exc).strip()
        reason = text.split(". ")[0].splitlines()[0][:160] if text else type(exc).__name__
        raise ValueError(f"{what}, got {value!r} ({reason})") from None
    return probe.device  # with its index ("cuda" → "cuda:0"), as the tensors there report it


def device_memory_bytes(device: torch.device) -> int | None:
    """The memory of ``device``, bytes: the host's physical memory for the CPU (as the numba engine's
    limit), the device's total memory for CUDA and XPU, the recommended maximum for MPS; None where torch
    does not say (no check).
    """
    if device.type == "cpu":
        return memory_limit_bytes()
    if device.type == "mps":
        recommended = getattr(getattr(torch, "mps", None), "recommended_max_memory", None)
        return int(recommended()) if recommended is not None else memory_limit_bytes()
    module = getattr(torch, device.type, None)
    props = getattr(module, "get_device_properties", None)
    if props is None:
        return None
    index = device.index if device.index is not None else module.current_device()
    return int(props(index).total_memory)


#: The scans (an output of the input's shape) whose meta rule is a quadratic decomposition.
_SCANS = (torch.ops.aten.cumsum.default, torch.ops.aten.cumprod.default)


class _PeakBytes(TorchDispatchMode):
    """Follows every tensor storage the dispatched operations create, and the peak of those alive."""

    def __init__(self) -> None:
        super().__init__()
        self.live: dict[int, tuple[StorageWeakRef, int]] = {}
        self.peak = 0

    def __torch_dispatch__(self, func: Any, types: Any, args: Any = (), kwargs: Any = None) -> Any:
        kwargs = kwargs or {}
        if func in _SCANS:  # their meta rule builds an (…, M, M) mask: its element count overflows at large M
            a = args[0]
            dtype = kwargs.get("dtype") or (a.dtype if a.is_floating_point() else torch.int64)
            out = torch.empty(a.shape, dtype=dtype, device=a.device)
        else:
            out = func(*args, **kwargs)
        for t in tree_leaves(out):
            if isinstance(t, torch.Tensor):
                storage = t.untyped_storage()
                ref = StorageWeakRef(storage)
                self.live.setdefault(ref.cdata, (ref, storage.nbytes()))
        for key in [k for k, (ref, _) in self.live.items() if ref.expired()]:
            del self.live[key]
        self.peak = max(self.peak, sum(nbytes for _, nbytes in self.live.values()))
        return out


def _shape_key(c: TorchConsts) -> tuple[Any, ...]:
    """What the step's allocations depend on: the constants' scalars and their tensors' shapes and dtypes."""
    return tuple(
        (f.name, (tuple(v.shape), v.dtype) if isinstance(v, torch.Tensor) else v)
        for f in dataclasses.fields(c)
        if f.name != "device"
        for v in [getattr(c, f.name)]
    )


def _tensor_bytes(c: TorchConsts) -> int:
    return sum(v.nbytes for f in dataclasses.fields(c) for v in [getattr(c, f.name)] if isinstance(v, torch.Tensor))


def traced_peak_bytes(c: TorchConsts, num_envs: int) -> int:
    """The peak bytes alive at once from the constants' first tensor to the end of one eager step of
    ``num_envs`` envs, every env resetting (module docstring), traced on the meta device: no memory is
    allocated, whatever the sizes.
    """
    with _PeakBytes() as tracker, torch.no_grad():
        tensors = {f.name: getattr(c, f.name) for f in dataclasses.fields(c)}
        mc = dataclasses.replace(
            c, device=META, **{k: v.to(META) for k, v in tensors.items() if isinstance(v, torch.Tensor)}
        )
        state = sim.empty_state(mc, num_envs)
        state["done"] = torch.ones(num_envs, dtype=torch.bool, device=META)
        shape = (num_envs,) if mc.discrete else (num_envs, 2)
        actions = torch.zeros(shape, dtype=torch.int64 if mc.discrete else torch.float32, device=META)
        out = sim.step(mc, state, actions)
        sim.info(mc, out[0])
        del out
    return tracker.peak


def env_step_bytes(c: TorchConsts) -> int:
    """Bytes per env of the state and of one eager step's temporaries at their peak: one env's
    :func:`traced_peak_bytes` less the constants (computed once per set of shapes).
    """
    key = _shape_key(c)
    if key not in _PEAKS:
        if len(_PEAKS) >= 256:
            _PEAKS.clear()
        _PEAKS[key] = traced_peak_bytes(c, 1) - _tensor_bytes(c)
    return _PEAKS[key]


def estimate_bytes(c: TorchConsts, num_envs: int) -> int:
    """The device memory ``num_envs`` envs need, bytes: the constants, and per env the state and a step's
    peak (:func:`env_step_bytes`; every tensor of a step but the constants is one row per env).
    """
    return _tensor_bytes(c) + num_envs * env_step_bytes(c)


def check_fits(c: TorchConsts, num_envs: int) -> int:
    """The estimate of :func:`estimate_bytes`; a ValueError naming the memory needed and the device's when
    it cannot fit (a device whose memory torch does not report is not checked).
    """
    need = estimate_bytes(c, num_envs)
    limit = device_memory_bytes(c.device)
    if limit is None or need <= limit:
        return need
    per_env = env_step_bytes(c)
    most = (limit - _tensor_bytes(c)) // per_env
    fewer = f"at most {most} envs of {c.n_particles} particles, or fewer particles" if most > 0 else "fewer particles"
    raise ValueError(
        f"n_particles × num_envs = {c.n_particles} × {num_envs} needs ≈{need / 2**30:.3g} GiB on {c.device} "
        f"({_size(per_env)} per env: its state and a step's peak), more than its {limit / 2**30:.3g} GiB: "
        f"{fewer}"
    )


def _size(nbytes: int) -> str:
    return f"≈{nbytes / 2**30:.3g} GiB" if nbytes >= 2**30 else f"≈{nbytes / 2**20:.3g} MiB"
