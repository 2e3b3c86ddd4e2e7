"""Command-line tools: ``python -m ihrcf_env.calibrate``, ``python -m ihrcf_env.benchmark``."""
