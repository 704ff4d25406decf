"""GLSL sources of the GL executor, shipped inside the package as ``pyramid_cli.shaders``."""
