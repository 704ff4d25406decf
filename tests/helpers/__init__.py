"""Helpers shared by the test suite: test images, the command line, oracles and case tables.

Every test module imports them as ``from helpers.<module> import …`` (``tests`` is on
``pythonpath``, see ``[tool.pytest.ini_options]`` in ``pyproject.toml``):

- :mod:`helpers.paths`: the repository's folders (``ROOT``, ``DATA``, ``SAMPLES``);
- :mod:`helpers.images`: writing test images with OpenImageIO directly, random pictures;
- :mod:`helpers.cli`: the ``pyramid`` command in process (``invoke``) and as a subprocess (``run_cli``);
- :mod:`helpers.cases`: the expressions, sizes and channel counts the executor grids run;
- :mod:`helpers.oracles`: the paper's printed matrices, read independently of the algebra;
- :mod:`helpers.interrupt`: interrupting a run at chosen moments;
- :mod:`helpers.dask_processes`: real ``dask scheduler`` / ``dask worker`` processes.
"""
