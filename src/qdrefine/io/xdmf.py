"""XDMF 3 with its heavy data in HDF5: ``name.xdmf`` (XML) and ``name.h5`` (arrays).

Written: geometry ``XYZ`` (z = 0), topology ``Triangle`` (or ``Mixed`` with the tagged edges
as two-node polylines after the triangles), the cell attribute ``tag`` when the mesh has
tags, each point / cell data field as a node / cell attribute in its own dtype and shape,
and the physical names as meshio's ``Information`` map (which meshio reads as
``field_data``). The two files are written as a set (both, or neither). ParaView and meshio
read them; qdrefine reads XDMF through meshio (which uses h5py, so large meshes read fast).
The XML carries the comment ``<!-- qdrefine set DIGEST -->`` and the HDF5 file the root
attribute ``qdrefine_set`` with the same digest (a hash of the XML and of a sample of every
array): a reader that finds two different ones refuses the pair (a mixed set).
"""

from __future__ import annotations

import errno
import hashlib
import io
import os
import re
from pathlib import Path
from xml.etree import ElementTree
from xml.sax.saxutils import escape, quoteattr

import numpy as np

from ..memory import check_needed
from ._core import SKIPPED_NAMES, TAG_NAMES, RawMesh, check_regular, mesh_data
from .atomic import atomic_paths, cannot_write
from .meshio_formats import check_one_group_per_name
from .xml_names import check_xml_names

__all__ = ["heavy_data_files", "read", "write"]

_TYPES = {"i1": ("Char", 1), "i2": ("Short", 2), "i4": ("Int", 4), "i8": ("Int", 8),
          "u1": ("UChar", 1), "u2": ("UShort", 2), "u4": ("UInt", 4), "u8": ("UInt", 8),
          "f4": ("Float", 4), "f8": ("Float", 8), "b1": ("UChar", 1)}


_SET = re.compile(rb"<!-- qdrefine set (\w+) -->")


def read(path: Path) -> RawMesh:
    from .meshio_formats import read_with_meshio

    check_regular(path)  # a FIFO or device is refused before it is opened
    _check_set(path)
    _check_heavy_data(path)
    return read_with_meshio(path, "xdmf", "XDMF")


def _heavy_items(text: bytes) -> dict[str, list[tuple[str, str, str]]]:
    """The data items of XDMF ``text`` by format: ``"HDF"``: ``(file, dataset,
    dimensions)`` of each item ``FILE:/dataset`` (the file is everything before the last
    ``:/``: a Windows drive letter or spaces in the name included); ``"BINARY"``: ``(file,
    "", dimensions)`` of the raw binary items. The XML is parsed as meshio parses it (a
    regular expression missed single-quoted attributes and CDATA, which meshio reads),
    once and incrementally, each item dropped when read (inline data can be most of the
    file); XML that does not parse has none (meshio refuses it)."""
    items: dict[str, list[tuple[str, str, str]]] = {"HDF": [], "BINARY": []}
    try:
        for _, element in ElementTree.iterparse(io.BytesIO(text), events=("end",)):
            if not isinstance(element.tag, str) or \
                    element.tag.rpartition("}")[2] != "DataItem":
                continue
            found = {k.rpartition("}")[2].lower(): v for k, v in element.attrib.items()}
            kind = found.get("format", "").strip().upper()
            content = (element.text or "").strip()
            element.clear()
            if kind == "BINARY":
                items[kind].append((content, "", found.get("dimensions", "")))
            elif kind == "HDF":
                name, sep, dataset = content.rpartition(":/")
                if sep:
                    items[kind].append((name, "/" + dataset, found.get("dimensions", "")))
    except (ElementTree.ParseError, ValueError):
        return {"HDF": [], "BINARY": []}
    return items


def heavy_data_files(path: str | Path) -> list[Path]:
    """The HDF5 files that the XDMF file ``path`` refers to (empty when it is not a regular
    file or cannot be read: a FIFO is never opened)."""
    path = Path(path)
    if not path.is_file():
        return []
    try:
        text = path.read_bytes()
    except OSError:
        return []
    folder = _folder(path)
    return [folder / name
            for name in dict.fromkeys(n for n, _, _ in _heavy_items(text)["HDF"])]


def _folder(path: Path) -> Path:
    """The folder of the heavy-data files of the XDMF file ``path``: that of the file it
    resolves to, as meshio reads them (through a link from another folder, the files
    beside the link are not the ones read)."""
    return path.resolve().parent


def _check_heavy_data(path: Path) -> None:
    """One line naming a missing HDF5 file that the XDMF file refers to (HDF5's own message
    is several lines of library detail), or a dataset whose size is not the one the XML
    gives (meshio reads the dataset whatever its size: a replaced HDF5 file would load as
    another mesh)."""
    try:
        text = path.read_bytes()
    except OSError:
        return  # the reader says what is wrong
    found = _heavy_items(text)
    for name, _, _ in found["BINARY"]:
        _check_binary_file(path, name)
    items = found["HDF"]
    folder = _folder(path)
    for name in dict.fromkeys(n for n, _, _ in items):
        h5_path = folder / name
        if h5_path.exists() and not h5_path.is_file():
            raise OSError(f"{h5_path}: not a regular file (the heavy data of {path.name}; a "
                          "FIFO or device is not read)")
        if not h5_path.is_file():
            raise FileNotFoundError(f"{h5_path}: no such file (the heavy data of "
                                    f"{path.name})")
    import h5py

    for name in dict.fromkeys(n for n, _, _ in items):
        if not h5py.is_hdf5(folder / name):  # HDF5's words named neither file (review)
            raise ValueError(f"{folder / name}: not an HDF5 file (the heavy data of "
                             f"{path.name})")

    expanded = 0  # bytes of the filtered (compressed) datasets once read
    for name, dataset, dimensions in items:
        try:
            size = int(np.prod([int(d) for d in dimensions.split()]))
            with h5py.File(folder / name, "r") as h5:
                data = h5[dataset]
                shape, stored = data.shape, data.id.get_storage_size()
                needed = data.size * data.dtype.itemsize
                # compressed (any filter): stored < needed is normal; a virtual dataset's
                # data is in its sources
                filtered = data.id.get_create_plist().get_nfilters() > 0
                virtual = data.is_virtual
        except (ValueError, KeyError, OSError, AttributeError, TypeError):
            continue  # no or odd Dimensions, or a damaged file: the reader says what is wrong
        if filtered:  # a 386 kB gzip dataset of zeros read as 946 MB, past any limit
            expanded += needed
            check_needed(expanded, f"reading {path} (its compressed HDF5 datasets, up to "
                                   f"{name}:{dataset})")
        unwritten = not virtual and (stored == 0 or (not filtered and stored < needed))
        if needed > _UNWRITTEN_LIMIT and unwritten:
            # never written: HDF5 reads fill values, as many as declared (a 2.6 kB file
            # declaring 150 M points took 7.7 GB; review); small ones are read
            raise ValueError(f"{path}: the data item {name}:{dataset} declares "
                             f"{' x '.join(map(str, shape))} values, but the HDF5 file holds "
                             f"{stored} of their {needed} bytes (data never written)")
        if int(np.prod(shape)) != size:
            raise ValueError(f"{path}: the data item {name}:{dataset} has Dimensions "
                             f"\"{dimensions}\", but the HDF5 dataset holds "
                             f"{' x '.join(map(str, shape))} values (a replaced or "
                             "mismatched HDF5 file)")


#: Bytes of a dataset whose data was never written beyond which it is refused rather than
#: read as fill values (a small one may be a writer's lazy zeros; meshio reads it).
_UNWRITTEN_LIMIT = 1 << 26


def _check_binary_file(path: Path, name: str) -> None:
    """A ``Format="Binary"`` data item's file, which meshio opens by its name from the
    working directory (as meshio writes it): a regular file (a FIFO would hang the
    reader); refused when it is not there but next to the XDMF file, or when the name
    leads to two different files from the two places (which one is meant is unknown)."""
    opened, beside = Path(name), _folder(path) / name
    for candidate in (opened, beside):
        if candidate.exists() and not candidate.is_file():
            raise OSError(f"{candidate}: not a regular file (a binary data item of "
                          f"{path.name}; a FIFO or device is not read)")
    if opened.is_file():
        if beside.is_file() and not opened.samefile(beside):
            raise ValueError(f"{path}: the binary data item {name!r} names {opened} from the "
                             f"working directory and {beside} from the XDMF file's folder, "
                             "two different files; read it from its own folder, or give the "
                             "item's file an absolute name")
        return
    if beside.is_file():
        raise ValueError(f"{path}: the binary data item {name!r} is opened from the working "
                         f"directory, where there is none ({beside} is next to the XDMF "
                         "file); read the file from its own folder")
    raise FileNotFoundError(f"{opened}: no such file (a binary data item of {path.name})")


def _check_set(path: Path) -> None:
    """Refuse an XDMF file and HDF5 file written by two different runs (both stamped)."""
    try:
        with open(path, "rb") as f:
            found = _SET.search(f.read(256))
    except OSError:
        return  # the reader says what is wrong
    h5_path = path.resolve().with_suffix(".h5")  # as read: beside the file linked to
    if found is None or not h5_path.is_file():
        return
    try:
        import h5py

        with h5py.File(h5_path, "r") as h5:
            theirs = h5.attrs.get("qdrefine_set")
    except Exception:  # noqa: BLE001 - a damaged HDF5 file: the reader says what is wrong
        return
    ours = found.group(1).decode()
    if theirs is not None and str(theirs) != ours:
        raise ValueError(f"{h5_path}: written by another run than {path.name} (qdrefine set "
                         f"{theirs}, {path.name}: {ours}): a mixed set, left by an "
                         "interrupted or concurrent write; write the mesh again")


def _check_names(path: Path, mesh) -> None:
    """Refuse names that the XML file cannot hold (control characters), and a physical name
    given to two groups (meshio reads the names as ``field_data``: one group per name)."""
    check_one_group_per_name(mesh.physical_names, f"{path}: ")
    check_xml_names(path, mesh)


#: Bytes of HDF5 bookkeeping per dataset (and for the file), beyond the data itself: above
#: what h5py writes (a file of three small datasets and an attribute takes 7.5 kB).
_H5_OVERHEAD = 1 << 12


def _check_room(h5_path: Path, needed: int) -> None:
    """Refuse, before HDF5 starts, an uncompressed HDF5 file that the file size limit
    (``ulimit -f``) or the free space of its folder cannot hold: HDF5 failing mid-write left
    h5py printing tracebacks while it cleaned up, then the process crashed (exit 139;
    review). A compressed file's size is not known beforehand: it is not checked."""
    import shutil

    try:
        import resource  # POSIX only
        soft, _ = resource.getrlimit(resource.RLIMIT_FSIZE)
        unlimited = soft == resource.RLIM_INFINITY
    except ImportError:
        soft, unlimited = 0, True
    if not unlimited and needed > soft:
        raise cannot_write(h5_path, f"{os.strerror(errno.EFBIG)} (the HDF5 file needs about "
                                    f"{needed} bytes; the file size limit, ulimit -f, is "
                                    f"{soft} bytes)", errno.EFBIG)
    try:
        free = shutil.disk_usage(h5_path.parent).free
        read_only = bool(os.statvfs(h5_path.parent).f_flag & os.ST_RDONLY)
    except (OSError, AttributeError):  # no statvfs (Windows): the write says what is wrong
        return
    if read_only:  # it has little room too, but that is not why (review)
        raise cannot_write(h5_path, os.strerror(errno.EROFS), errno.EROFS)
    if needed > free:
        raise cannot_write(h5_path, f"{os.strerror(errno.ENOSPC)} (the HDF5 file needs about "
                                    f"{needed} bytes, {free} are free)", errno.ENOSPC)


def _write_error(path: Path, exc: BaseException) -> OSError:
    """One line for a failed HDF5 write: the file and the system's reason (HDF5 puts the
    ``errno`` inside a long message)."""
    found = re.search(r"errno = (\d+)", str(exc))
    number = getattr(exc, "errno", None) or (int(found.group(1)) if found else None)
    reason = os.strerror(number) if number else str(exc).split("(")[0].strip()
    return cannot_write(path, reason, number if number else errno.EIO)


def _digest(xml: str, arrays: list[np.ndarray]) -> str:
    """A hash of the XML and of up to 4096 evenly spaced values of every array: equal for
    equal writes, different (but for a coincidence) for two writes of different meshes."""
    h = hashlib.blake2b(xml.encode(), digest_size=8)
    for a in arrays:
        flat = np.ascontiguousarray(a).reshape(-1)
        h.update(np.ascontiguousarray(flat[::max(1, flat.size // 4096)]).tobytes())
    return h.hexdigest()


def write(path: Path, mesh, *, binary: bool = True, compress: bool = False  # noqa: ARG001
          ) -> None:
    """Write ``name.xdmf`` and ``name.h5`` as one set; ``compress``: the HDF5 datasets
    gzip-compressed (with byte shuffle), which ParaView and meshio read as well."""
    import h5py

    _check_names(path, mesh)
    h5_path = path.with_suffix(".h5")
    if ":" in h5_path.name:
        raise ValueError(f"{path}: an XDMF file name cannot hold ':' (readers split the heavy "
                         f"data's 'FILE:/dataset' at it, so {h5_path.name} would not be "
                         "found); choose another name")
    m, n = mesh.n_triangles, mesh.n_points
    k = 0 if mesh.edges is None else len(mesh.edges)
    xyz = np.zeros((n, 3))
    xyz[:, :2] = mesh.points
    tris = np.asarray(mesh.triangles, dtype=np.int64)
    if k:
        mixed = np.concatenate([
            np.column_stack([np.full(m, 4), tris]).ravel(),
            np.column_stack([np.full(k, 2), np.full(k, 2),
                             np.asarray(mesh.edges, np.int64)]).ravel()])
        topology = ("Mixed", m + k, mixed)
    else:
        topology = ("Triangle", m, tris)
    point_data, cell_data = mesh_data(mesh, path, TAG_NAMES + SKIPPED_NAMES)  # read by meshio
    cells = {}
    if mesh.cell_tags is not None or k:
        cell_tags = mesh.cell_tags if mesh.cell_tags is not None else np.zeros(m, np.int64)
        cells["tag"] = np.concatenate([np.asarray(cell_tags, np.int64),
                                       np.asarray(mesh.edge_tags if k else [], np.int64)])
    for name, value in cell_data.items():
        a = np.asarray(value)
        cells[name] = np.concatenate([a, np.zeros((k, *a.shape[1:]), a.dtype)])
    datasets: list[tuple[str, np.ndarray]] = []

    def item(a: np.ndarray) -> str:
        a = np.asarray(a)
        if a.dtype == np.float16:  # XDMF has no 16-bit floats; float32 holds them exactly
            a = a.astype(np.float32)
        key = a.dtype.str[1:]
        if key not in _TYPES:
            raise ValueError(f"{path}: data of dtype {a.dtype} cannot be written to XDMF")
        kind, size = _TYPES[key]
        name = f"data{len(datasets)}"
        datasets.append((name, a))
        dims = " ".join(str(d) for d in a.shape)
        return (f'<DataItem DataType="{kind}" Precision="{size}" Dimensions="{dims}" '
                f'Format="HDF">{escape(h5_path.name)}:/{name}</DataItem>')

    def attribute(name: str, a: np.ndarray, center: str) -> str:
        kind = "Scalar" if a.ndim == 1 else ("Vector" if a.shape[1:] == (3,) else "Matrix")
        return (f"<Attribute Name={quoteattr(name)} AttributeType=\"{kind}\" "
                f"Center=\"{center}\">{item(a)}</Attribute>\n")

    kind, count, cells_array = topology
    xml = ['<?xml version="1.0"?>\n<Xdmf Version="3.0">\n<Domain>\n<Grid Name="mesh" '
           'GridType="Uniform">\n', f'<Geometry GeometryType="XYZ">{item(xyz)}</Geometry>\n',
           f'<Topology TopologyType="{kind}" NumberOfElements="{count}">{item(cells_array)}'
           "</Topology>\n"]
    xml += [attribute(name, np.asarray(v), "Node") for name, v in point_data.items()]
    xml += [attribute(name, v, "Cell") for name, v in cells.items()]
    if mesh.physical_names:
        maps = "".join(f'<map key={quoteattr(nm)} dim="{d}">{t}</map>'
                       for (d, t), nm in sorted(mesh.physical_names.items()))
        xml.append(f'<Information Name="Information" Value="{len(mesh.physical_names)}">'
                   f"<![CDATA[<main>{maps}</main>]]></Information>\n")
    xml.append("</Grid>\n</Domain>\n</Xdmf>\n")
    stamp = _digest("".join(xml), [a for _, a in datasets])
    xml[0] = xml[0].replace("?>\n", f"?>\n<!-- qdrefine set {stamp} -->\n", 1)
    if not compress:
        _check_room(h5_path, sum(a.nbytes for _, a in datasets) + _H5_OVERHEAD * (
            4 + len(datasets)))
    with atomic_paths([h5_path, path]) as (h5_tmp, xml_tmp):
        # a compressed file is made in memory (its size is not known beforehand, and HDF5
        # failing mid-write crashed the process) and written by Python, whose failures are
        # plain OSErrors; it is smaller than the data
        target = io.BytesIO() if compress else h5_tmp
        try:
            with h5py.File(target, "w") as h5:
                h5.attrs["qdrefine_set"] = stamp
                for name, a in datasets:
                    if compress and a.size:
                        h5.create_dataset(name, data=a, compression="gzip", shuffle=True)
                    else:
                        h5.create_dataset(name, data=a)
        except (OSError, RuntimeError) as exc:  # HDF5's own errors (a full disk ...)
            raise _write_error(h5_path, exc) from None
        if compress:
            try:
                with open(h5_tmp, "wb") as f:
                    f.write(target.getbuffer())
            except OSError as exc:
                raise cannot_write(h5_path, exc.strerror or str(exc), exc.errno) from None
        xml_tmp.write_text("".join(xml), encoding="utf-8")
