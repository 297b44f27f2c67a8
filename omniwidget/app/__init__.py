"""Layer 8, the applications in plain Python: the command line and the editing session the editor wraps.

- :mod:`.cli` ``omniwidget warp``, ``omniwidget demo``, ``omniwidget schema``.
- :mod:`.session` :class:`~.session.EditingSession`: undo, redo, autosave, the worker that
  computes only the newest job, the status; no widget package needed.
"""
