"""The notebook widgets: the editor (anywidget). Needs the ``widget`` extra (anywidget, ipywidgets)."""

from .editor import Editor, saved_handles

__all__ = ["Editor", "saved_handles"]
