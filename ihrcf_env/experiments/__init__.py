"""Experiments: rollouts of the env scored with :mod:`ihrcf_env.core.metrics` (may use envs/,
wrappers/, sim/, core/ and control/, never cli/).

* :mod:`ihrcf_env.experiments.rollout`: :func:`rollout`, the one loop that flies a policy and
  records a :class:`Recording`.
* :mod:`ihrcf_env.experiments.accuracy`: the paper's motionless hover, :func:`accuracy`.
* :mod:`ihrcf_env.experiments.hover_and_track`: the IHRCF tracking hover, :func:`run`, CSV output.
* :mod:`ihrcf_env.experiments.figures`: Figs. 14-20 of a recording (matplotlib, imported lazily).
* :mod:`ihrcf_env.experiments.episode`: the one episode loop of the landing evaluations,
  :func:`run_episode` / :func:`run_episodes`, and its frozen :class:`EpisodeResult`.
* :mod:`ihrcf_env.experiments.landing`: the landing evaluation, :func:`evaluate`.
* :mod:`ihrcf_env.experiments.speed`: env and component speed; :mod:`ihrcf_env.experiments.camera_realism`:
  the realistic camera's cost per frame and the README's example frame.
* :mod:`ihrcf_env.experiments.detector_fit`: rendered frames paired with the projection, and the
  projected camera's detector model fitted to them, :func:`fit_detector_model`.
* :mod:`ihrcf_env.experiments.progress`: progress output (a bar on a terminal, plain lines in a log).
* :mod:`ihrcf_env.experiments.camera_validation`: the projected camera model against rendered
  frames, paired, :func:`validate_camera_model`.
* :mod:`ihrcf_env.experiments.closed_loop`: the two camera models in closed loop (scripted
  landings), :func:`fly` and :func:`compare`.
"""
