"""Layer 8, the applications in plain Python: the command line and the editing session the editor wraps.

- :mod:`.cli` ``omniwidget warp``, ``omniwidget demo``, ``omniwidget schema``.
- :mod:`.session` :class:`~.session.EditingSession`: undo, redo, autosave, the worker that
  computes only the newest job, the status; no widget package needed.
- :mod:`.video` a 360° video warped by one map (:func:`~.video.warp_video`, its settings a
  :class:`~.video.VideoSettings`); :mod:`.frames` many frames warped by one map;
  :mod:`.strips` a large panorama file warped in strips; :mod:`.batch` many files and
  videos alike, in-process or on a Dask cluster.
"""
