"""Layer 7, input and output: readers and writers of images, videos, maps and metadata; handles drawn on an image.

- :mod:`.images` reading and writing panoramas (orientation, bit depth, atomic writes);
  :mod:`.large` panoramas larger than memory, read a patch at a time and written in strips.
- :mod:`.video` reading, decoding and writing 360° videos (their sound and spherical
  metadata kept); :mod:`.spherical` the spherical metadata itself.
- :mod:`.metadata` EXIF, ICC profile and XMP (Photo Sphere) read and written.
- :mod:`.frames` inverse maps saved to files.
- :mod:`.draw` handles drawn over an image (figures, ``omniwidget demo``).

The workflows that warp (a video, many frames, a file in strips) are :mod:`omniwidget.app`'s.
"""
