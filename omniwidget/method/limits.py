"""The method's caps: samples, mesh vertices and weights, so that no handles document exhausts the machine.

The bounded biharmonic weights cost memory and time in proportion to their count, mesh
vertices times controls: about 50 bytes each, and a time of their own (``bench/bench_limits.py``
measures both; ``bench/RESULTS.md``, "Limits"). Each cap refuses, before the work, with a
:class:`~omniwidget.errors.HandlesError` that names the cap, what reached it and the
environment variable that raises it (``OMNIWIDGET_MAX_<NAME>``, read by
:func:`omniwidget._checks.limit`). The document's own cap on handles is
:data:`omniwidget.document.handles.MAX_HANDLES`.
"""

from __future__ import annotations

from .._checks import limit
from ..errors import HandlesError

__all__ = ["MAX_MESH_VERTICES", "MAX_SAMPLES", "MAX_WEIGHTS", "check_mesh", "check_samples", "check_weights"]

#: The most samples per line and cage edge ``samples`` may ask for (the paper's 50):
#: ``OMNIWIDGET_MAX_SAMPLES`` raises it. Every sample is a vertex of the weights' mesh.
MAX_SAMPLES = 1000
#: The most vertices the adaptive mesh may have, counted on the handles' samples before it is
#: built (each sample is a vertex; refinement adds a few thousand): ``OMNIWIDGET_MAX_MESH_VERTICES``
#: raises it.
MAX_MESH_VERTICES = 200_000
#: The most weights (mesh vertices times controls) the bounded biharmonic solve may have:
#: ``OMNIWIDGET_MAX_WEIGHTS`` raises it. What documents near the cap take, in memory and time, is
#: in ``bench/RESULTS.md``, "Limits".
MAX_WEIGHTS = 30_000_000


def check_samples(samples: int) -> int:
    """``samples`` if at most :data:`MAX_SAMPLES`, else a ValueError saying the cap and how to raise it."""
    cap = limit("SAMPLES", MAX_SAMPLES)
    if samples > cap:
        raise ValueError(
            f"samples: {samples} per line and cage edge are more than the limit of {cap} (MAX_SAMPLES; the paper uses 50, "
            f"and each is a vertex of the weights' mesh); set OMNIWIDGET_MAX_SAMPLES={samples} to allow them"
        )
    return samples


def check_mesh(count: int, samples: int) -> None:
    """Refuse a mesh of more than :data:`MAX_MESH_VERTICES` samples before it is built.

    Parameters
    ----------
    count : int
        The samples the mesh is to hold as vertices.
    samples : int
        Samples per line and cage edge, for the message.
    """
    cap = limit("MESH_VERTICES", MAX_MESH_VERTICES)
    if count > cap:
        raise HandlesError(
            "handles",
            f"the handles make {count:,} samples, each a vertex of the weights' mesh ({samples} per line and cage edge), more "
            f"than the limit of {cap:,} (MAX_MESH_VERTICES); use fewer handles or samples, or set "
            f"OMNIWIDGET_MAX_MESH_VERTICES={count} to allow them",
        )


def check_weights(vertices: int, controls: int) -> None:
    """Refuse a weights solve of more than :data:`MAX_WEIGHTS` entries (``vertices * controls``) before it starts.

    Parameters
    ----------
    vertices : int
        Mesh vertices (or, before the mesh is built, the samples it will hold at least).
    controls : int
        The controls whose weights are solved.
    """
    cap, size = limit("WEIGHTS", MAX_WEIGHTS), vertices * controls
    if size > cap:
        raise HandlesError(
            "handles",
            f"the weights to solve are at least {vertices:,} mesh vertices x {controls:,} controls = {size / 1e6:.0f} million, "
            f"more than the limit of {cap / 1e6:.0f} million (MAX_WEIGHTS: about 50 bytes and 2 to 7 µs each, "
            f"{size * 50 / 1e9:.1f} GB here); use fewer handles (a line crossing others is cut into more controls), or set "
            f"OMNIWIDGET_MAX_WEIGHTS={size} to allow them",
        )
