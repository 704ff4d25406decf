"""OpenSeadragon in headless Chromium, the viewer the Deep Zoom and IIIF tile sets are made for (issue 27).

The folder holds what the browser side needs: ``viewer.html`` (OpenSeadragon configured to draw one pyramid
level 1:1 on screen), ``drive.js`` (playwright-core driving the system's ``chromium``) and the npm manifest
pinning both (``package.json`` + ``package-lock.json``; ``npm ci --prefix tests/helpers/osd`` installs them into
``node_modules`` here: ``make test`` and ``.ci/run`` do it). The Python side:

- :mod:`helpers.osd.viewer`: whether the browser side is installed, the local HTTP server (every request and its
  status recorded) and one run of ``drive.js`` over several tile sets;
- :mod:`helpers.osd.levels`: a tile set's level read back by stitching its decoded tiles (Deep Zoom and IIIF
  static trees, read independently of the writers), the view a level gives on screen, and the per-pixel error
  between a screenshot and it.
"""
