"""Layer 9, the pane: the adaptive mesh and each handle's weights in 3D (pyvista).

:mod:`.pane` is a thin adapter over a warp's :class:`~omniwidget.raster.pipeline.Result`.
"""
