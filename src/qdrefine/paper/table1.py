"""Table 1 of the paper recomputed: orderings of the schemes per region, with the size of
every gap and a tolerance for "similar" (``=``) taken from the table itself.

The paper's legend: "To indicate that a partition is better than other according to min or
mean min-angle we use symbol < and > otherwise. If partition is similar according to these
values we use symbol =". The *gap* of a relation ``a op b`` on a region is the region mean of
``value(a) - value(b)`` (degrees, grid mean). The paper's own usage fixes the tolerance: the
smallest gap it writes as ``<`` or ``>`` is a difference to it, so ``=`` is read as
``|gap| < tau`` with ``tau`` that smallest strict gap (:func:`similar_tolerance`). When the
paper also writes ``=`` for a gap at least ``tau`` the table is inconsistent with any single
tolerance, and the report says so.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .claims import PAPER_TABLE1, SHORT, TOKENS

__all__ = ["Relation", "Tolerance", "parse_chain", "relations", "similar_tolerance",
           "our_chain", "row_verdict", "table_region"]

_SCHEMES = ("7t-d", "7t-qd", "7t-le")


@dataclass(frozen=True)
class Relation:
    """One relation ``a op b`` of a Table 1 cell with its measured gap.

    Attributes
    ----------
    a, op, b : str
    gap : float
        Region mean of ``value(a) - value(b)``, degrees.
    relative : float
        ``gap`` over the region mean of ``value(b)``.
    share : float
        Share of the region's grid points where ``a - b`` has the sign of ``op`` (``=``:
        where ``|a - b| < tau``).
    """

    a: str
    op: str
    b: str
    gap: float
    relative: float
    share: float

    def holds(self, tau: float) -> bool:
        if self.op == "=":
            return abs(self.gap) < tau
        return self.gap >= tau if self.op == ">" else self.gap <= -tau

    def text(self) -> str:
        return (f"{SHORT[self.a]} {self.op} {SHORT[self.b]}: gap {self.gap:+.2f} deg "
                f"({100 * self.relative:+.1f}%)")


@dataclass(frozen=True)
class Tolerance:
    """The tolerance for "similar" implied by Table 1.

    ``tau`` is the smallest ``|gap|`` the paper writes as a difference (at ``strict_at``);
    ``largest_equal`` the largest ``|gap|`` it writes as ``=`` (at ``equal_at``);
    ``consistent`` when ``largest_equal < tau``.
    """

    tau: float
    strict_at: str
    largest_equal: float
    equal_at: str

    @property
    def consistent(self) -> bool:
        return self.largest_equal < self.tau


def parse_chain(chain: str) -> list[tuple[str, str, str]]:
    """``"7D > 7TLE > 7TQD"`` -> pairwise relations ``[(a, op, b), ...]`` of adjacent terms."""
    parts = chain.split()
    if len(parts) % 2 != 1 or any(p not in TOKENS for p in parts[0::2]) or any(
            p not in ("<", ">", "=") for p in parts[1::2]):
        raise ValueError(f"cannot read Table 1 cell {chain!r}")
    terms = [TOKENS[t] for t in parts[0::2]]
    ops = parts[1::2]
    return [(terms[i], ops[i], terms[i + 1]) for i in range(len(ops))]


def relations(sample: dict, mask: np.ndarray, measure: str, chain: str,
              tau: float = 0.0) -> list[Relation]:
    """Measured relations of one Table 1 cell on the grid points ``mask`` of ``sample``."""
    out = []
    for a, op, b in parse_chain(chain):
        va, vb = sample[f"{measure} {a}"][mask], sample[f"{measure} {b}"][mask]
        d = va - vb
        if op == "=":
            share = float((np.abs(d) < tau).mean()) if tau > 0 else float((d == 0).mean())
        else:
            share = float((d > 0).mean() if op == ">" else (d < 0).mean())
        out.append(Relation(a, op, b, float(d.mean()), float(d.mean() / vb.mean()), share))
    return out


def table_region(region: str, fractions: dict[str, float], percent: str) -> str:
    """Our region for a Table 1 row: the row's name, except for "III", which is whichever
    of ``III`` and ``III-shaded`` rounds to the paper's percentage (``III-shaded`` when both
    or neither do: Table 1's rows add up to the whole diagram only without the shaded part)."""
    if region != "III":
        return region
    return "III" if _rounds_to(100 * fractions["III"], percent) and not _rounds_to(
        100 * fractions["III-shaded"], percent) else "III-shaded"


def _rounds_to(ours: float, quoted: str) -> bool:
    q = quoted.rstrip("%")
    digits = len(q.split(".")[1]) if "." in q else 0
    return round(ours, digits) == float(q)


def similar_tolerance(sample: dict, fractions: dict[str, float],
                      table=PAPER_TABLE1) -> Tolerance:
    """The tolerance for ``=`` implied by the paper's own Table 1 (see the module docstring)."""
    strict = (np.inf, "")
    equal = (0.0, "")
    for region, percent, min_chain, mean_chain in table:
        mask = sample[table_region(region, fractions, percent)]
        for measure, chain in (("min", min_chain), ("mean", mean_chain)):
            for r in relations(sample, mask, measure, chain):
                where = f"{region}, {measure}, {SHORT[r.a]} vs {SHORT[r.b]}"
                if r.op == "=" and abs(r.gap) > equal[0]:
                    equal = (abs(r.gap), where)
                if r.op != "=" and abs(r.gap) < strict[0]:
                    strict = (abs(r.gap), where)
    return Tolerance(strict[0], strict[1], equal[0], equal[1])


def our_chain(sample: dict, mask: np.ndarray, measure: str, tau: float) -> str:
    """Ordering of the three schemes by their region mean, ``=`` where the gap is below
    ``tau``, each gap in degrees."""
    mean = {s: float(sample[f"{measure} {s}"][mask].mean()) for s in _SCHEMES}
    order = sorted(_SCHEMES, key=lambda s: -mean[s])
    text = SHORT[order[0]]
    for p, q in zip(order[:-1], order[1:], strict=True):
        # the gap as :func:`relations` computes it (mean of the differences)
        gap = float((sample[f"{measure} {p}"][mask] - sample[f"{measure} {q}"][mask]).mean())
        text += f" {'=' if gap < tau else '>'} {SHORT[q]} ({gap:.2f})"
    return text


def row_verdict(rels: list[Relation], tau: float) -> str:
    """"confirmed" when every relation holds at tolerance ``tau``, else the failing ones."""
    bad = [r for r in rels if not r.holds(tau)]
    if not bad:
        return "confirmed"
    return "wrong: " + "; ".join(r.text() for r in bad)
