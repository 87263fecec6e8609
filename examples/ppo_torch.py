"""PPO with the rollouts on the env's device: ElectroLoc-v0's torch backend, CleanRL style.

    python examples/ppo_torch.py --device cuda --num-envs 4096 --total-timesteps 20000000
    python examples/ppo_torch.py --device cpu --num-envs 64 --total-timesteps 200000

The env is ``gym.make_vec("ElectroLoc-v0", num_envs=N, vectorization_mode="vector_entry_point",
backend="torch", device=...)``: observations, rewards and flags come back as tensors on ``device`` and
the actions go in as tensors there, so a rollout never leaves the device (no numpy round trip, no
``.cpu()`` inside the loop; the episode statistics are summed on the device and read once an update).
The network, the advantage estimation and the clipped-PPO update are the CPU example's
(:mod:`ppo_minimal`, imported from beside this file), run on the same device. Autoreset is Gymnasium's
``NEXT_STEP`` as there: the reset step after an episode's end is masked out of the loss.

Two parts of the shipped ppo-belief's training objective come along, both on the device (the
shipped model's ``config.yml``: SB3's ``VecNormalize(norm_obs=True)`` and ``shaping_coef: 1.0``):

* observations normalised by running mean and variance (:class:`RunningNorm`, clipped to ±10 as
  SB3's ``VecNormalize``), frozen for evaluation and saved with the network;
* potential-based shaping on the belief spread, F = γ·Φ(s′) − Φ(s) with Φ = −c·ln(spread / 10 mm)
  and Φ(success) = 0 (:mod:`electroloc_gym.train.wrappers`' rule, here as tensor operations): the
  optimal policy is unchanged (Ng, Harada & Russell 1999), the printed figures are the task's own.

``--bench-trials K`` evaluates at the end on the benchmark's own trial seeds (each of the eight
conditions, trials 0 … K−1 of ``electroloc bench``'s seed 0, the paper's fixed target), so the figure
sits beside the benchmark's rows; the training and the validation use other seeds.
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import gymnasium as gym
import torch
import torch.nn as nn

import electroloc_gym  # noqa: F401  (registers ElectroLoc-v0)
from electroloc_gym.bench.config import trial_seeds
from electroloc_gym.cli import HelpFormatter
from electroloc_gym.utils.checks import check_float
from electroloc_gym.utils.fileio import check_output_path
from electroloc_gym.utils.runtime import add_threads_argument, pin_threads
from electroloc_gym.world.conditions import PRESET_NAMES

sys.path.insert(0, str(Path(__file__).resolve().parent))
from ppo_minimal import Agent, ppo_update  # noqa: E402  (the network and the update, on any device)


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    """Command-line options (CleanRL's names, plus the device), each checked before any work: one
    ``ppo_torch.py: error: …`` line and exit 2 for a value out of range, a device this machine lacks or a
    ``--save`` path that cannot be written.
    """
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0], formatter_class=HelpFormatter)
    p.add_argument(
        "--device",
        default="cuda" if torch.cuda.is_available() else "cpu",
        help="the env's and the network's torch device",
    )
    add_threads_argument(p)
    p.add_argument("--compile", action="store_true", help="torch.compile the env's step (fullgraph; default: off)")
    p.add_argument(
        "--condition", default="random", help=f"a preset name ({', '.join(PRESET_NAMES)}) or 'random' (all eight)"
    )
    p.add_argument("--num-envs", type=int, default=256, help="envs stepped together on the device")
    p.add_argument(
        "--total-timesteps", type=int, default=2_000_000, help="env steps of training (at least one rollout)"
    )
    p.add_argument("--num-steps", type=int, default=64, help="steps per env per rollout")
    p.add_argument("--learning-rate", type=float, default=3e-4, help="Adam's initial step size (decays linearly to 0)")
    p.add_argument("--gamma", type=float, default=0.99, help="discount factor, in [0, 1]")
    p.add_argument("--gae-lambda", type=float, default=0.95, help="GAE's λ, in [0, 1]")
    p.add_argument("--num-minibatches", type=int, default=8, help="minibatches per epoch, 1 … num_envs × num_steps")
    p.add_argument("--update-epochs", type=int, default=4, help="passes over each rollout per update")
    p.add_argument("--clip-coef", type=float, default=0.2, help="PPO's ratio clip ε (> 0)")
    p.add_argument("--ent-coef", type=float, default=0.0, help="entropy bonus coefficient (≥ 0)")
    p.add_argument("--vf-coef", type=float, default=0.5, help="value loss coefficient (≥ 0)")
    p.add_argument("--max-grad-norm", type=float, default=0.5, help="gradient norm clip (> 0)")
    p.add_argument("--shaping-coef", type=float, default=1.0, help="c of the spread potential (0: no shaping)")
    p.add_argument(
        "--norm-obs",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="running observation normalisation (default: on)",
    )
    p.add_argument("--eval-episodes", type=int, default=256, help="validation episodes after training (≥ 1)")
    p.add_argument("--bench-trials", type=int, default=0, help="also evaluate on the benchmark's trials 0…K−1")
    p.add_argument("--seed", type=int, default=1, help="seed of the network, the envs and the validation (≥ 0)")
    p.add_argument("--save", default=None, help="write the policy's state_dict here (torch.save; default: not saved)")
    args = p.parse_args(argv)
    ints = {
        "--num-envs": (args.num_envs, 1),
        "--num-steps": (args.num_steps, 1),
        "--update-epochs": (args.update_epochs, 1),
        "--eval-episodes": (args.eval_episodes, 1),
        "--bench-trials": (args.bench_trials, 0),
        "--seed": (args.seed, 0),
    }
    for name, (value, low) in ints.items():
        if value < low:
            p.error(f"argument {name}: must be an integer ≥ {low}, got {value}")
    batch = args.num_envs * args.num_steps
    if args.total_timesteps < batch:
        p.error(f"argument --total-timesteps: must be ≥ num_envs × num_steps = {batch}, got {args.total_timesteps}")
    if not 1 <= args.num_minibatches <= batch:
        p.error(
            f"argument --num-minibatches: must be an integer in [1, {batch}] (num_envs × num_steps), "
            f"got {args.num_minibatches}"
        )
    floats = {  # name: (value, low, low included, high)
        "--learning-rate": (args.learning_rate, 0.0, False, None),
        "--gamma": (args.gamma, 0.0, True, 1.0),
        "--gae-lambda": (args.gae_lambda, 0.0, True, 1.0),
        "--clip-coef": (args.clip_coef, 0.0, False, None),
        "--ent-coef": (args.ent_coef, 0.0, True, None),
        "--vf-coef": (args.vf_coef, 0.0, True, None),
        "--max-grad-norm": (args.max_grad_norm, 0.0, False, None),
        "--shaping-coef": (args.shaping_coef, 0.0, True, None),
    }
    for name, (value, low, inclusive, high) in floats.items():
        try:
            check_float(name, value, low, inclusive=inclusive, high=high)
        except ValueError as exc:
            p.error(f"argument {exc}")
    if args.condition != "random" and args.condition not in PRESET_NAMES:
        p.error(f"argument --condition: must be 'random' or one of {', '.join(PRESET_NAMES)}, got {args.condition!r}")
    try:
        dev = torch.empty(0, device=args.device).device
        if dev.type == "meta":
            raise ValueError("meta holds shapes and no data")
    except Exception as exc:  # noqa: BLE001 - torch raises AssertionError, RuntimeError, ValueError …
        text = str(exc).strip().splitlines()[0][:160] if str(exc).strip() else type(exc).__name__
        p.error(f"argument --device: {args.device!r} is not a device this machine can compute on ({text})")
    if args.save is not None:
        try:
            check_output_path("--save", args.save)
        except ValueError as exc:
            p.error(f"argument {exc}")
    return args


class RunningNorm(nn.Module):
    """Running mean and variance of the observations on the device, float64 (SB3's ``RunningMeanStd``).

    ``update`` merges a batch (Chan et al.'s parallel rule, as SB3); calling the module normalises and
    clips to ±``clip`` (float32 out). Disabled, it passes observations through; its buffers are saved
    with the network's ``state_dict``.
    """

    def __init__(self, dim: int, device: torch.device, enabled: bool = True, clip: float = 10.0) -> None:
        super().__init__()
        self.enabled, self.clip = enabled, clip
        self.register_buffer("mean", torch.zeros(dim, dtype=torch.float64, device=device))
        self.register_buffer("var", torch.ones(dim, dtype=torch.float64, device=device))
        self.register_buffer("count", torch.full((), 1e-4, dtype=torch.float64, device=device))

    @torch.no_grad()
    def update(self, x: torch.Tensor) -> None:
        x = x.to(torch.float64)
        b_mean, b_var, b_count = x.mean(0), x.var(0, unbiased=False), x.shape[0]
        delta, total = b_mean - self.mean, self.count + b_count
        m2 = self.var * self.count + b_var * b_count + delta * delta * self.count * b_count / total
        self.mean += delta * b_count / total
        self.var.copy_(m2 / total)
        self.count.copy_(total)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if not self.enabled:
            return x
        z = (x.to(torch.float64) - self.mean) / torch.sqrt(self.var + 1e-8)
        return z.clamp(-self.clip, self.clip).to(torch.float32)


def potential(spread_mm: torch.Tensor, coef: float, success_spread_mm: float) -> torch.Tensor:
    """Φ(s) = −c·ln(spread / success spread), float64: rises as the belief tightens, ≈ 0 at success."""
    return -coef * torch.log(spread_mm.to(torch.float64).clamp_min(1e-6) / success_spread_mm)


def make_envs(
    args: argparse.Namespace, num_envs: int, randomize_target: bool, condition: str | None = None
) -> gym.vector.VectorEnv:
    """The torch backend: ``num_envs`` tanks and particle filters as tensors on ``args.device``."""
    return gym.make_vec(
        "ElectroLoc-v0",
        num_envs=num_envs,
        vectorization_mode="vector_entry_point",
        backend="torch",
        device=args.device,
        compile=args.compile,
        condition=args.condition if condition is None else condition,
        randomize_target=randomize_target,
    )


def train(args: argparse.Namespace) -> tuple[Agent, RunningNorm]:
    """Collect ``num_steps`` × ``num_envs`` transitions on the device, update with clipped PPO, repeat."""
    torch.manual_seed(args.seed)
    dev = torch.device(args.device)
    envs = make_envs(args, args.num_envs, randomize_target=True)
    obs_dim, act_dim = envs.single_observation_space.shape[0], envs.single_action_space.shape[0]
    agent = Agent(obs_dim, act_dim).to(dev)
    norm = RunningNorm(obs_dim, dev, enabled=args.norm_obs)
    success_spread_mm = envs.unwrapped.params.success_spread_mm
    optim = torch.optim.Adam(agent.parameters(), lr=args.learning_rate, eps=1e-5)
    T, N = args.num_steps, args.num_envs
    obs_buf = torch.zeros((T, N, obs_dim), device=dev)
    act_buf = torch.zeros((T, N, act_dim), device=dev)
    logp_buf, rew_buf, done_buf, val_buf, valid_buf = (torch.zeros((T, N), device=dev) for _ in range(5))
    raw_obs, info = envs.reset(seed=args.seed)
    phi = potential(info["spread_mm"], args.shaping_coef, success_spread_mm)
    next_done = torch.zeros(N, device=dev)
    n_updates = args.total_timesteps // (T * N)
    t0 = time.time()
    for update in range(1, n_updates + 1):
        for g in optim.param_groups:  # linear learning-rate decay
            g["lr"] = args.learning_rate * (1.0 - (update - 1) / n_updates)
        ended = successes = readings = torch.zeros((), device=dev)  # this rollout's episodes, summed on device
        for t in range(T):
            norm.update(raw_obs)
            next_obs = norm(raw_obs)
            obs_buf[t], valid_buf[t] = next_obs, 1.0 - next_done
            with torch.no_grad():
                action, logp, _, value = agent.act(next_obs)
            act_buf[t], logp_buf[t], val_buf[t] = action, logp, value
            raw_obs, reward, term, trunc, info = envs.step(action.clamp(-1.0, 1.0))
            # shaping: + γ·Φ(s′) − Φ(s), Φ of a success 0; on the masked reset step Φ restarts from the new cloud
            phi_next = potential(info["spread_mm"], args.shaping_coef, success_spread_mm)
            shaped = reward + args.gamma * torch.where(term, torch.zeros_like(phi_next), phi_next) - phi
            phi = phi_next
            done = (term | trunc).float()
            rew_buf[t], done_buf[t] = shaped.float(), done
            just = done * (1.0 - next_done)  # episodes that ended at this step (not the reset step after one)
            ended = ended + just.sum()
            successes = successes + (just * info["success"].float()).sum()
            readings = readings + (just * info["n_observations"].float()).sum()
            next_done = done
        with torch.no_grad():
            next_value = agent.value(norm(raw_obs))
        ppo_update(agent, optim, args, obs_buf, act_buf, logp_buf, rew_buf, done_buf, val_buf, valid_buf, next_value)
        if update % 10 == 0 or update == n_updates:  # one host read per report, outside the rollout
            n_ep = max(float(ended), 1.0)
            print(
                f"update {update}/{n_updates}  steps {update * T * N}  episodes {int(ended)}  "
                f"success {float(successes) / n_ep:.2f}  mean readings {float(readings) / n_ep:.1f}  "
                f"{update * T * N / (time.time() - t0):.0f} steps/s",
                flush=True,
            )
    envs.close()
    return agent, norm


def first_episodes(
    agent: Agent, norm: RunningNorm, args: argparse.Namespace, condition: str, seed: int | list[int], n: int
) -> tuple[torch.Tensor, torch.Tensor]:
    """(success, readings) of each of ``n`` sub-envs' first episode under the mean action, the paper's target."""
    envs = make_envs(args, n, randomize_target=False, condition=condition)
    obs, _ = envs.reset(seed=seed)
    first_done = torch.zeros(n, dtype=torch.bool, device=obs.device)
    success = torch.zeros(n, dtype=torch.bool, device=obs.device)
    readings = torch.zeros(n, device=obs.device)
    while not bool(first_done.all()):  # at most 35 steps: every episode ends by the cap
        with torch.no_grad():
            obs, _, term, trunc, info = envs.step(agent.actor_mean(norm(obs)).clamp(-1.0, 1.0))
        new = (term | trunc) & ~first_done
        success = torch.where(new, info["success"], success)
        readings = torch.where(new, info["n_observations"].float(), readings)
        first_done |= new
    envs.close()
    return success, readings


def evaluate(agent: Agent, norm: RunningNorm, args: argparse.Namespace) -> dict[str, float]:
    """Success rate and mean readings (a failure counts its 35) on validation seeds disjoint from training's."""
    success, readings = first_episodes(agent, norm, args, args.condition, 10_000 + args.seed, args.eval_episodes)
    return {"success_rate": float(success.float().mean()), "mean_readings": float(readings.mean())}


def evaluate_bench(agent: Agent, norm: RunningNorm, args: argparse.Namespace) -> dict[str, float]:
    """The same figures on the benchmark's trials 0 … K−1 of each condition (``electroloc bench``'s seed 0)."""
    k = args.bench_trials
    runs = [first_episodes(agent, norm, args, c, [trial_seeds(0, c, i)[0] for i in range(k)], k) for c in PRESET_NAMES]
    success, readings = torch.cat([r[0] for r in runs]), torch.cat([r[1] for r in runs])
    return {
        "bench_trials": float(success.numel()),
        "bench_successes": float(success.sum()),
        "bench_mean_readings": float(readings.mean()),
    }


def main(argv: list[str] | None = None) -> dict[str, float]:
    """Train, evaluate, optionally save; returns the evaluation figures."""
    args = parse_args(argv)
    pin_threads(args.threads)  # chosen, not torch's default of every core (busy machines slow down)
    agent, norm = train(args)
    result = evaluate(agent, norm, args)
    print(
        f"evaluation ({args.eval_episodes} episodes, mean action): success {result['success_rate']:.2f}, "
        f"mean readings {result['mean_readings']:.1f}"
    )
    if args.bench_trials:
        result |= evaluate_bench(agent, norm, args)
        print(
            f"benchmark trials ({int(result['bench_trials'])}): {int(result['bench_successes'])} successes, "
            f"mean readings {result['bench_mean_readings']:.2f} (a failure counts 35)"
        )
    if args.save:  # reload with torch.load(path, weights_only=True)
        torch.save({"agent": agent.state_dict(), "norm": norm.state_dict()}, args.save)
        print(f"wrote {args.save}")
    return result


if __name__ == "__main__":
    main()
