"""Layer 6, detection: suggested lines and the level of a panorama, found in the image.

- :mod:`.lines` straight 3D edges: segments detected in overlapping perspective views of
  the sphere, lifted to great-circle arcs and merged into one :class:`Suggestion` per edge
  (:func:`suggest_lines`, :func:`suggestions_to_handles`).
- :mod:`.structure` the scene's structure among them: each line's kind (vertical,
  horizontal, other) and a consistent set, no two crossing, texture (tiles, cobbles, grid
  paint, mullions) left out, each drop with its reason (:func:`choose_structure`,
  :class:`StructureChoice`); :func:`suggest_lines` gives it by default.
- :mod:`.vertical` where the true vertical is seen, from the vertical edges (:func:`find_up`),
  below both of the others' users.
- :mod:`.level` the camera's pitch and roll from the vertical edges, and the rotation that
  levels the panorama (:func:`level`, :class:`Level`, :func:`level_document`).
"""

from ..errors import LevelError
from .level import Level, level, level_document, tilt_rotation
from .lines import DETECT_WIDTH, Suggestion, suggest_lines, suggestions_to_handles
from .structure import StructureChoice, choose_structure

__all__ = [
    "DETECT_WIDTH",
    "Level",
    "LevelError",
    "StructureChoice",
    "Suggestion",
    "choose_structure",
    "level",
    "level_document",
    "suggest_lines",
    "suggestions_to_handles",
    "tilt_rotation",
]
