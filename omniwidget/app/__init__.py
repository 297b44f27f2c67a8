"""Layer 7, the applications in plain Python: the command line and the editing session the editor wraps.

- :mod:`.cli` ``omniwidget warp | apply | draw | demo``.
- :mod:`.session` :class:`~.session.EditingSession`: undo, redo, autosave, the worker that
  computes only the newest job, the status; no widget package needed.
"""
