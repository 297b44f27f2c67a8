"""``omniwidget.batch``: many panoramas warped alike, in-process or on a Dask cluster.

The short name of :mod:`omniwidget.app.batch`, where :func:`~omniwidget.app.batch.warp_files`,
:class:`~omniwidget.app.batch.BatchSettings`, :class:`~omniwidget.app.batch.BatchReport` and
:class:`~omniwidget.app.batch.FileReport` are defined and documented.

Examples
--------
>>> from omniwidget.batch import warp_files
>>> report = warp_files(["a.jpg", "b.jpg"], "out/", handles="handles.json", client="tcp://scheduler:8786")  # doctest: +SKIP
"""

from .app.batch import BatchReport as BatchReport
from .app.batch import BatchSettings as BatchSettings
from .app.batch import FileReport as FileReport
from .app.batch import warp_files as warp_files
