"""Layer 2, the handles document: points, lines and cages as a person marks them, and its file format.

:mod:`.handles` holds the value objects (:class:`~.handles.Handles`, ``PointHandle``,
``LineHandle``, ``CageHandle``, ``Options``), their validation and the JSON file. A
document says what the person wants; the method (:mod:`omniwidget.method`) says how.
"""
