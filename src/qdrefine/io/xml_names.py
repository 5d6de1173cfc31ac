"""The names an XML file (VTU, XDMF) can hold: XML 1.0 has no way to write most control
characters, not even escaped, nor lone surrogates, so a writer refuses such a name before
it writes anything (a file written with one cannot be read back)."""

from __future__ import annotations

import re
from pathlib import Path

__all__ = ["check_xml_names"]

#: Characters that XML 1.0 cannot hold, not even escaped.
NOT_XML = re.compile("[\x00-\x08\x0b\x0c\x0e-\x1f\ud800-\udfff\ufffe\uffff]")


def check_xml_names(path: Path, mesh, physical: bool = True) -> None:
    """``ValueError`` naming ``path`` for a point or cell data name of ``mesh`` (and, with
    ``physical``, a physical name) that holds a character XML cannot hold."""
    names = [("physical name", name) for name in (mesh.physical_names or {}).values()
             if physical]
    names += [("point data name", name) for name in (mesh.point_data or {})]
    names += [("cell data name", name) for name in (mesh.cell_data or {})]
    for what, name in names:
        if NOT_XML.search(name):
            raise ValueError(f"{path}: {what} {name!r} contains a control character, which "
                             "XML files cannot hold")
