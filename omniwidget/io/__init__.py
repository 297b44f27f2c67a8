"""Layer 7, input and output: image files, batches of frames, handles drawn on an image.

- :mod:`.images` reading and writing panoramas (orientation, bit depth, atomic writes).
- :mod:`.frames` one map applied to many frames.
- :mod:`.draw` handles drawn over an image (figures, ``omniwidget demo``).
"""
