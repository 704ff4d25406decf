"""The ``pyramid`` command line: one click group, one module per command group.

Command bodies only translate options; the policy lives in the jobs (:mod:`pyramid_cli.jobs.work`) and the
runners (:mod:`pyramid_cli.run`), which the Python API calls too. Heavy modules (numpy, OpenImageIO, moderngl)
are imported inside the commands so that ``pyramid --help`` stays fast.

- :mod:`~pyramid_cli.cli.group`: the group, its errors and exit codes, the console script's ``run``
- :mod:`~pyramid_cli.cli.params`: option groups and parameter types the commands share
- :mod:`~pyramid_cli.cli.running`: options to a reporter, a session and a pipeline run
- :mod:`~pyramid_cli.cli.describe`: ``explain``, ``plan``
- :mod:`~pyramid_cli.cli.filters`: ``apply``, ``blur``, ``levels``, ``collapse``
- :mod:`~pyramid_cli.cli.mip`: ``mipmap``
- :mod:`~pyramid_cli.cli.tiles`: ``tiles``
- :mod:`~pyramid_cli.cli.methods`: ``fill``, ``blend``
- :mod:`~pyramid_cli.cli.farm`: ``farm-template``
- :mod:`~pyramid_cli.cli.diff`: ``diff``
"""

from __future__ import annotations

from pyramid_cli.cli import describe, diff, farm, filters, methods, mip, tiles
from pyramid_cli.cli.group import main, run

# The commands are reached through ``main``; binding them here by name would hide their modules
# (``pyramid_cli.cli.diff`` is the module, ``diff.diff`` the command).
for _command in (describe.explain, describe.plan_command, filters.apply, filters.blur, filters.levels,
                 filters.collapse, mip.mipmap, tiles.tiles, methods.fill, methods.blend, farm.farm_template, diff.diff):
    main.add_command(_command)

__all__ = ["main", "run"]
