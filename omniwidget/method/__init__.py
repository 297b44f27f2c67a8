"""Layer 3, the paper's method: from a handles document to Möbius maps blended by bounded biharmonic weights.

One module per step of the paper:

- :mod:`.constraints` Sec. 3.3: each handle's controls (one Möbius map each, Sec. 3.1)
  and the points where its weight is prescribed.
- :mod:`.rectify` Sec. 3.4: the least squares that places many rectified lines at once.
- :mod:`.mesh` Sec. 3.5: the adaptive sphere mesh through the constrained points.
- :mod:`.locate` which mesh triangle holds a direction (barycentric weights).
- :mod:`.bbw` Sec. 3.2: the Laplacian and the bounded biharmonic weights.
- :mod:`.background` our extension: the still background (``options.anchor``).
- :mod:`.deformation` the steps above in order: a document in, the blended deformation
  (maps, mesh, weights) out; eq. (2) at any direction.
- :mod:`.edits` edits of a document that need the method ("rectify current line").

Nothing here touches an image: the per-pixel engine is :mod:`omniwidget.raster`.
"""
