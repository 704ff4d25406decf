"""The shipped sample images (installed as pyramid_cli.samples, so the demo runs from a wheel)."""
