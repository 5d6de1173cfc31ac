"""The mark options of ``qdrefine refine`` and ``qdrefine coarsen`` (``--mark-tag``,
``--mark-box``, ``--mark-file``) and the marking rule they give."""

from __future__ import annotations

import argparse
from collections.abc import Callable

import numpy as np
from numpy.typing import NDArray

from ..marking import mark_box, mark_file, mark_tag
from ..mesh import Mesh

#: ``mark(mesh) -> (M,) bool``.
Marker = Callable[[Mesh], NDArray[np.bool_]]

#: The cell data field that carries ``--mark-file``'s marks through the cycles: inherited
#: as cell data is, so that the marks of later cycles do not depend on the triangle order
#: (through ``parents``, a family's new triangles took its first member's mark); removed
#: before the mesh is written (:func:`without_marks`).
CARRIED = "qdrefine:mark-file"


def add_options(group) -> None:
    """The three mutually exclusive mark options, into ``group``."""
    group.add_argument("--mark-tag", type=_tags, metavar="T[,T...]",
                       help="mark the triangles with these cell tags")
    group.add_argument("--mark-box", type=_box, metavar="x0,y0,x1,y1",
                       help="mark the triangles that meet this closed box (a negative "
                            "x0 works as it is: --mark-box -1,-1,0,0)")
    group.add_argument("--mark-file", metavar="F",
                       help="mark the triangles listed in F: ids of IN's triangles (0-based, "
                            "whitespace separated, '#' comments), or a .npy file of ids or "
                            "of a boolean mask; with --cycles, each cycle marks everything "
                            "inside them again")


def given(args: argparse.Namespace) -> bool:
    """Whether a mark option is given."""
    return any(v is not None for v in (args.mark_tag, args.mark_box, args.mark_file))


def marker(mesh: Mesh, args: argparse.Namespace) -> tuple[Marker, Mesh]:
    """The marking rule of the options, checked on the input mesh; and the mesh to start
    from (with ``--mark-file``: carrying the marks, :data:`CARRIED`)."""
    if args.mark_tag is not None:
        known = np.unique(mesh.cell_tags) if mesh.cell_tags is not None else []
        missing = sorted(set(args.mark_tag) - set(np.asarray(known).tolist()))
        if missing:
            raise ValueError(f"{args.input}: no triangle has cell tag {missing[0]} (cell "
                             f"tags: {', '.join(map(str, known)) or 'none'})")
        return (lambda m: mark_tag(m, args.mark_tag)), mesh
    if args.mark_box is not None:
        if not mark_box(mesh, args.mark_box).any():
            raise ValueError(f"{args.input}: the box {','.join(map(str, args.mark_box))} "
                             "meets no triangle")
        return (lambda m: mark_box(m, args.mark_box)), mesh
    first = mark_file(mesh, args.mark_file)
    if not first.any():  # as for a box: an output equal to the input is not what was asked
        raise ValueError(f"{args.mark_file}: lists no triangle (ids of {args.input}'s "
                         "triangles, or a boolean mask with some True)")
    if CARRIED in mesh.cell_data:
        raise ValueError(f"{args.input}: has a cell data field named {CARRIED!r}, which "
                         "qdrefine uses to carry --mark-file's marks; rename it")
    return (lambda m: m.cell_data[CARRIED]), mesh.replace(
        cell_data={**mesh.cell_data, CARRIED: first})


def without_marks(mesh: Mesh, args: argparse.Namespace) -> Mesh:
    """``mesh`` without the field that carried ``--mark-file``'s marks. Without
    ``--mark-file``, a user's field of that name stays (with it, :func:`marker` refuses
    such an input)."""
    if args.mark_file is None or CARRIED not in mesh.cell_data:
        return mesh
    return mesh.replace(cell_data={k: v for k, v in mesh.cell_data.items() if k != CARRIED})


def _tags(text: str) -> list[int]:
    """argparse type: ``T[,T...]`` integers."""
    try:
        return [int(t) for t in text.split(",")]
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected integer cell tags like 1 or 1,2; got "
                                         f"{text!r}") from None


def _box(text: str) -> tuple[float, float, float, float]:
    """argparse type: ``x0,y0,x1,y1`` with ``x0 <= x1`` and ``y0 <= y1``."""
    words = text.split(",")
    try:
        box = tuple(float(w) for w in words)
    except ValueError:
        box = ()
    if len(box) != 4 or not np.isfinite(box).all():
        raise argparse.ArgumentTypeError(f"expected four numbers x0,y0,x1,y1; got {text!r}")
    if box[0] > box[2] or box[1] > box[3]:
        raise argparse.ArgumentTypeError(f"expected x0 <= x1 and y0 <= y1; got {text!r}")
    return box  # type: ignore[return-value]
