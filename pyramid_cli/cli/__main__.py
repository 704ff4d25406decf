"""``python -m pyramid_cli.cli``: the ``pyramid`` command."""

from pyramid_cli.cli import run

run()  # exits with the command's code (click's standalone mode)
