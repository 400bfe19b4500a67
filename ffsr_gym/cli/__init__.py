"""The ``ffsr-gym`` command line: :mod:`ffsr_gym.cli.main` (the parser and the entry point), one module per group of
sub-commands."""
