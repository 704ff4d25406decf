"""``python -m pyramid_cli.cli``: the ``pyramid`` command."""

import sys

from pyramid_cli.cli import run

sys.exit(run())
