"""The ``pyramid`` command line: one click group, one module per command group.

Command bodies only translate options; the policy lives in the jobs (:mod:`pyramid_cli.jobs.work`) and the
runners (:mod:`pyramid_cli.run`), which the Python API calls too. Heavy modules (numpy, OpenImageIO, moderngl)
are imported inside the commands so that ``pyramid --help`` stays fast.

- :mod:`~pyramid_cli.cli.main`: the group, its errors and exit codes, the console script's ``run``
- :mod:`~pyramid_cli.cli.params`: option groups and parameter types the commands share
- :mod:`~pyramid_cli.cli.running`: options to a reporter, a session and a pipeline run
- :mod:`~pyramid_cli.cli.describe`: ``explain``, ``plan``
- :mod:`~pyramid_cli.cli.filters`: ``apply``, ``blur``, ``levels``, ``collapse``
- :mod:`~pyramid_cli.cli.mip`: ``mipmap``
- :mod:`~pyramid_cli.cli.methods`: ``fill``, ``blend``
- :mod:`~pyramid_cli.cli.farm`: ``farm-template``
- :mod:`~pyramid_cli.cli.diff`: ``diff``
"""

from __future__ import annotations

from pyramid_cli.cli.describe import explain, plan_command
from pyramid_cli.cli.diff import diff
from pyramid_cli.cli.farm import farm_template
from pyramid_cli.cli.filters import apply, blur, collapse, levels
from pyramid_cli.cli.main import main, run
from pyramid_cli.cli.methods import blend, fill
from pyramid_cli.cli.mip import mipmap

for _command in (explain, plan_command, apply, blur, levels, collapse, mipmap, fill, blend, farm_template, diff):
    main.add_command(_command)

__all__ = ["main", "run"]
