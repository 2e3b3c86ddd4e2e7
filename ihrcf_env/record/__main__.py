"""``python -m ihrcf_env.record`` (the same command as ``ihrcf-record``): runs
:mod:`ihrcf_env.record.command` through :func:`ihrcf_env.cmdline.launch.run_command` (a Ctrl-C
while the command is imported exits with status 130). Importing the package
:mod:`ihrcf_env.record` never loads this file."""

from ihrcf_env.cmdline.launch import run_command

if __name__ == "__main__":
    raise SystemExit(run_command("record", "ihrcf_env.record.command"))
