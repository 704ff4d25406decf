"""Executors: where plans run.

:mod:`.base` names what every executor offers (:class:`~pyramid_cli.exec.base.Executor`);
:mod:`.emulate` is the numpy definition of a plan (and its executor, float64), :mod:`.cpu`
the compiled CPU executor (numba), :mod:`.gl` the GL executor (moderngl on EGL);
:mod:`.tiles` runs any plan in bounded memory on any of them, and :mod:`.session` picks one
for a whole command. Importing this package loads none of them.
"""
