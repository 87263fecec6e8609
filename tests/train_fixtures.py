"""What the training tests share: a tiny PPO hyper-parameter file (a few seconds of training)."""

#: PPO on ElectroLoc-v0 with 64-step rollouts, one epoch, a 16-unit network and shaping on.
TINY_YAML = """
default:
  policy: MlpPolicy
  normalize: {norm_obs: true, norm_reward: false}
ElectroLoc-v0:
  n_steps: 64
  batch_size: 64
  n_epochs: 1
  learning_rate: lin_3e-4
  shaping_coef: 1.0
  policy_kwargs: {net_arch: [16], activation_fn: tanh}
"""
