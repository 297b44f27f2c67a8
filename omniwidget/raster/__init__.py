"""Layer 4, the per-pixel engine: the method's deformation evaluated at every output pixel and the input resampled.

- :mod:`.pipeline` :func:`~.pipeline.warp`, the whole path from an image and a document to
  a :class:`~.pipeline.Result`.
- :mod:`.warping` one Möbius map per pixel, the padding over the seam and the poles,
  OpenCV's resampling.
- :mod:`.blend` eq. (2) per pixel in numpy (the reference backend); :mod:`._kernels` the
  compiled backend (numba, loaded through :mod:`._native`), chosen by
  :func:`._kernels.available`; :mod:`.sampled` the blend on a coarse grid where that is
  exact enough.
- :mod:`.fold` where the output is turned over.
- :mod:`.live` a handle's share of eq. (2) for the editor's live drag.
- :mod:`.perspective` the perspective camera: a rectilinear view of a panorama (``omniwidget view``,
  the editor's look-around view, the paper's Fig. 2b).
"""
