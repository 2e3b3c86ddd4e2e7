"""The pieces the command lines share, below every package that has a command of its own.

* :mod:`~ihrcf_env.cmdline.common`: the parser, argument types, output checks, Ctrl-C handling
  (standard library only);
* :mod:`~ihrcf_env.cmdline.env_args`: the arguments that choose an env (id, level, options, seed,
  camera model, sensor preset, step limit);
* :mod:`~ihrcf_env.cmdline.episode_args`: those plus the policy, and the episode line of a report;
* :mod:`~ihrcf_env.cmdline.launch`: running a command module with Ctrl-C handled from its import on.

The commands themselves live above: :mod:`ihrcf_env.cli` (evaluate, benchmark, calibrate,
fit-detector) and the packages with a face of their own (:mod:`ihrcf_env.record.command`,
:mod:`ihrcf_env.mavlink.command`). Nothing here imports a command.
"""
