"""Layer 1, the sphere: directions as ``[lon, lat]`` in degrees, Möbius maps, arcs (Sec. 3.1 of the paper).

numpy only; imports nothing else of the package but :mod:`omniwidget.errors` and
:mod:`omniwidget._checks`.

- :mod:`.coords` owns the conventions: ``[lon, lat]`` degrees, unit vectors, the
  equirectangular pixel grid, homogeneous coordinates.
- :mod:`.moebius` the Möbius maps of the sphere (Sec. 3.1): from three point pairs, from a
  point and its arrows, the loxodromic/rotation forms.
- :mod:`.arcs` great-circle arcs: crossings of arcs and polylines, points inside a
  spherical polygon.
"""
