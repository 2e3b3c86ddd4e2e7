"""Reinforcement-learning helpers for ``examples/train_ppo.py`` and ``examples/train_rllib.py``.

``ihrcf_env.rl.curves`` (CSV learning curves and their plot), ``ihrcf_env.rl.envs`` (the training
env factory) and ``ihrcf_env.rl.curriculum`` (a start curriculum for v1) need only numpy, Gymnasium
and, for plots, matplotlib. ``ihrcf_env.rl.sb3`` (callbacks,
the observation normaliser inside the policy) imports stable-baselines3 and torch: install the
``[rl]`` extra. Importing ``ihrcf_env`` or this package never imports torch.
"""
