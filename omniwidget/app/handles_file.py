"""The handles file an editing session saves and loads: where it goes by default, and never over another panorama's."""

from __future__ import annotations

import os
from pathlib import Path

from ..document.handles import Handles, save_handles
from ._places import same_file, signature, writable_folder

__all__ = ["HandlesFile"]


def _handles_location(image_path: Path | None) -> tuple[Path, bool]:
    """Where Save writes the handles by default, and whether that name is the image's stem in the working folder only.

    ``day1/room.handles.json`` for ``day1/room.jpg`` (next to it, as Save image writes); for an
    array, the bundled sample or an image in a folder not to write to, ``<stem>.handles.json``
    in the working folder, a name other panoramas may share.
    """
    if image_path is not None and writable_folder(image_path):
        return image_path.with_name(f"{image_path.stem}.handles.json"), False
    stem = image_path.stem if image_path is not None else "panorama"
    return Path(f"{stem}.handles.json"), True


class HandlesFile:
    """Where an editor saves its handles, and the default file as it last saved or read it.

    Parameters
    ----------
    image_path : Path or None
        The panorama's file (None for an array): the default file is named after it.
    path : path-like, optional
        Where Save writes when given no path; default next to the panorama (see
        :meth:`EditingSession.save`).
    """

    def __init__(self, image_path: Path | None, path: str | os.PathLike[str] | None = None) -> None:
        self.default, shared_name = _handles_location(image_path)
        self.path = Path(path) if path is not None else self.default
        self._guard = path is None and shared_name  # Save replaces only a file of its own there
        self._written: tuple[int, ...] | None = None  # the default file as this editor last saved or read it

    def write(self, doc: Handles, path: str | os.PathLike[str] | None = None) -> Path:
        """Write ``doc`` (whole or not at all) to ``path``, or to :attr:`path`; return where.

        Raises
        ------
        FileExistsError
            If ``path`` is not given, the default file is the working folder's (a name other
            panoramas may share) and it is there already, not saved or loaded by this editor.
        """
        if path is None:
            path = self.path
            if self._guard and path == self.default and os.path.lexists(path) and signature(path) != self._written:
                raise FileExistsError(
                    f"{path.absolute()}: not saved: that file was not written by this editor and may hold another panorama's "
                    f"handles (in the working folder it is named after the image's name only); save to another file "
                    f"(save(path), or set handles_path)"
                )
        path = Path(path)
        save_handles(doc, path)
        self.note(path)
        return path

    def note(self, path: Path) -> None:
        """Remember the default file as this editor saved or read it (``path``): Save may write over it."""
        if same_file(path, self.default):
            self._written = signature(self.default)
