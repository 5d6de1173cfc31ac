"""Transition families: what a later cycle needs to coarsen a transition before refining."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit
from numpy.typing import NDArray

from .edgekeys import edge_keys, oriented
from .labels import split_codes
from .patterns import pattern_stencil


@dataclass(frozen=True, eq=False)
class Families:
    """Transition ("green") families of a mesh: the children of each transition pattern,
    grouped by the triangle they replace. :func:`~qdrefine.adaptive.refine_step` takes and
    returns them; :func:`~qdrefine.adaptive.refine_cycles` carries them from one cycle to
    the next.

    Parameters
    ----------
    member : (M,) int64
        Family of each triangle, ``-1`` for triangles that are not transition children.
        The members of a family are consecutive rows (as ``refine_step`` emits them).
    parent_triangles : (F, 3) int64
        Each family's parent triangle: its vertex row, counter-clockwise.
    stencil : (F, S) int64
        The parent's points in :func:`~qdrefine.adaptive.patterns.pattern_stencil` order:
        canonical vertices ``M, N, O``, the ``k`` points of ``MN``, ``NO`` and ``OM``
        (listed from ``M``, ``N``, ``O``), ``-1`` on unsplit edges; for seven-triangle
        schemes (``S = 10``) then the centroid ``X``, ``-1`` where the pattern does not
        use it.
    """

    member: NDArray[np.int64]
    parent_triangles: NDArray[np.int64]
    stencil: NDArray[np.int64]

    def __post_init__(self) -> None:
        member = np.asarray(self.member, dtype=np.int64)
        rows = np.asarray(self.parent_triangles, dtype=np.int64).reshape(-1, 3)
        stencil = np.asarray(self.stencil, dtype=np.int64)
        f = rows.shape[0]
        if member.ndim != 1:
            raise ValueError(f"families: member must be one-dimensional, got {member.shape}")
        if stencil.shape not in ((f, 6), (f, 10)):
            raise ValueError(f"families: stencil must have shape ({f}, 6) or ({f}, 10), got "
                             f"{stencil.shape}")
        first, last, count = family_spans(member, f)
        if first is None:
            raise ValueError(f"families: member ids must be in -1..{f - 1}")
        for name, value in (("member", member), ("parent_triangles", rows), ("stencil", stencil)):
            value.flags.writeable = False
            object.__setattr__(self, name, value)
        bad = (count < 2) | (last - first + 1 != count)
        if bad.any():
            raise ValueError(f"families: family {int(np.flatnonzero(bad)[0])} does not have "
                             "two or more consecutive members")

    @classmethod
    def trusted(cls, member: NDArray[np.int64], parent_triangles: NDArray[np.int64],
                stencil: NDArray[np.int64]) -> Families:
        """Families from arrays known to be valid (int64, ``(M,)``, ``(F, 3)``, ``(F, S)``,
        members consecutive: made by the step's own passes), without the checks' passes
        over every triangle; the arrays are made read-only."""
        out = object.__new__(cls)
        for name, value in (("member", member), ("parent_triangles", parent_triangles),
                            ("stencil", stencil)):
            value = np.asarray(value, dtype=np.int64)
            value.flags.writeable = False
            object.__setattr__(out, name, value)
        return out

    @classmethod
    def empty(cls, n_triangles: int, per_edge: int) -> Families:
        """No transition children among ``n_triangles``."""
        width = len(pattern_stencil(per_edge).names)
        return cls.trusted(np.full(n_triangles, -1, dtype=np.int64),
                           np.empty((0, 3), np.int64), np.empty((0, width), np.int64))

    @property
    def per_edge(self) -> int:
        return 1 if self.stencil.shape[1] == 6 else 2

    def centroids(self) -> NDArray[np.int64]:
        """The centroid points the families' patterns use ``(C,)``."""
        if self.per_edge != 2:
            return np.empty(0, dtype=np.int64)
        x = self.stencil[:, -1]
        return x[x >= 0]

    @property
    def n_families(self) -> int:
        return int(self.parent_triangles.shape[0])

    def counts(self) -> NDArray[np.int64]:
        """Members per family ``(F,)``."""
        return np.bincount(self.member[self.member >= 0], minlength=self.n_families)

    def first(self) -> NDArray[np.int64]:
        """First member of each family ``(F,)``."""
        return family_spans(self.member, self.n_families)[0]

    def codes(self, families: NDArray[np.int64] | None = None) -> NDArray[np.int64]:
        """Split code of each family's transition ``(F,)`` (bits ``MN=1, NO=2, OM=4``), or
        of the ``families (G,)`` given only."""
        k = self.per_edge
        stencil = self.stencil if families is None else self.stencil[families]
        return split_codes(stencil[:, [3, 3 + k, 3 + 2 * k]] >= 0)

    def registry(self) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Split edges of the parents: sorted keys ``(R,)`` and their points ``(R, k)``,
        listed from the lower point id."""
        k = self.per_edge
        keys, pts = [], []
        for e in range(3):
            a, b = self.stencil[:, e], self.stencil[:, (e + 1) % 3]
            p = self.stencil[:, 3 + k * e: 3 + k * (e + 1)]
            ok = p[:, 0] >= 0
            keys.append(edge_keys(a[ok], b[ok]))
            pts.append(oriented(p[ok], a[ok], b[ok]))
        keys_, first = np.unique(np.concatenate(keys), return_index=True)
        return keys_, np.concatenate(pts).reshape(-1, k)[first]


def family_spans(member: NDArray[np.int64], f: int) -> tuple[NDArray[np.int64] | None, ...]:
    """First and last member and member count of each of ``f`` families ``(F,)`` (first
    ``M`` and last ``-1`` for a family without members), from ``member (M,)`` in one
    compiled pass; ``(None, None, None)`` if an id is outside ``-1 .. f - 1``."""
    first = np.full(f, member.shape[0], dtype=np.int64)
    last = np.full(f, -1, dtype=np.int64)
    count = np.zeros(f, dtype=np.int64)
    if not _member_spans(member, first, last, count):
        return None, None, None
    return first, last, count


@njit(cache=True)
def _member_spans(member, first, last, count):
    f = first.shape[0]
    for t in range(member.shape[0]):
        m = member[t]
        if m < -1 or m >= f:
            return False
        if m >= 0:
            if count[m] == 0:
                first[m] = t
            last[m] = t
            count[m] += 1
    return True


def smallest_first(rows: NDArray[np.int64]) -> NDArray[np.int64]:
    """Each triangle row ``(R, 3)`` rotated to start at its smallest id (the same triangle,
    one spelling)."""
    shift = np.argmin(rows, axis=1)[:, None]
    return np.take_along_axis(rows, (shift + np.arange(3)) % 3, axis=1)
