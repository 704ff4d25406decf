"""The float64 oracle: the paper's formulas in numpy, written literally. It imports only :mod:`pyramid_cli.core`,
never the planner or the algebra it checks."""
