"""Writing a store safely: through a temporary store next to the target that replaces it
when complete (a rename locally; object by object, root metadata last, on object stores),
and removing what killed runs left behind."""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import shutil
import signal
import socket
from collections.abc import Iterator
from pathlib import Path

from ..interrupts import signals_held
from ..io import permission_bits
from ..io.atomic import WRITE_ERRNOS, cannot_write
from .layout import finish, is_store
from .locations import PathLike, filesystem, is_local, join, location, split

__all__ = ["writing", "clean", "remove", "TMP", "OLD"]

#: Suffixes of a run's temporary store and of the replaced target on its way out.
TMP, OLD = ".tmp", ".old"


@contextlib.contextmanager
def writing(path: PathLike) -> Iterator[str]:
    """Yield the URL of a fresh temporary store next to ``path``; on success it is marked
    complete and replaces ``path``.

    An existing store at ``path`` is replaced; an existing non-store is refused (before any
    work). Stale temporaries of earlier runs for the same target are removed first
    (:func:`clean`). On failure the temporary store is removed and ``path`` is left as it
    was.
    """
    url = location(path)
    check_target(url)
    clean(url)
    tmp = temporary(url, TMP)
    fs, root = filesystem(tmp)
    try:
        if is_local(url):
            try:
                os.mkdir(root, permission_bits(Path(url), 0o777))
                os.chmod(root, permission_bits(Path(url), 0o777))
            except OSError as exc:  # the message names the target, not our temporary
                raise cannot_write(url, exc.strerror or str(exc), exc.errno) from None
        yield tmp
        finish(tmp)
        replace(tmp, url)
    except OSError as exc:
        remove(tmp)
        if exc.errno in WRITE_ERRNOS and not str(exc).startswith(url):  # named already
            # a full disk, a size limit: named as files name it
            raise cannot_write(url, exc.strerror or str(exc), exc.errno) from None
        raise
    except BaseException:
        remove(tmp)
        raise


def temporary(url: str, suffix: str) -> str:
    """``.NAME~HOST~PID~TOKEN<suffix>`` next to ``url``: who made it, for :func:`clean`
    (a long NAME shortened, :func:`_stem`)."""
    parent, name = split(url)
    host = socket.gethostname().replace("~", "-").replace("/", "-")[:64]
    return join(parent, f".{_stem(name)}~{host}~{os.getpid()}~{os.urandom(4).hex()}{suffix}")


#: Bytes of a target's name kept in its temporaries' names (file names hold 255 bytes).
_STEM_BYTES = 120


def _stem(name: str) -> str:
    """``name``, or for a long one its start and a digest of the whole: the temporary's
    name must fit where the target's does (a 245-character target was refused)."""
    if len(name.encode()) <= _STEM_BYTES:
        return name
    start = name.encode()[:_STEM_BYTES - 9].decode(errors="ignore")
    return f"{start}-{hashlib.sha1(name.encode()).hexdigest()[:8]}"


def maker_of(entry: str, name: str) -> tuple[str, int] | None | bool:
    """For an entry of the target's parent: False if it is not a temporary of ``name``;
    ``(host, pid)`` of the run that made it (``.NAME~HOST~PID~TOKEN.tmp`` / ``.old``, the
    token 8 hex digits, :func:`temporary`); None when unknown (older qdrefine versions
    named them ``.NAME.XXXXXXXX.tmp`` / ``.work`` / ``.old`` with :func:`tempfile.mkdtemp`'s
    8 characters). Nothing else matches: a user's ``.NAME.backup.old`` is not ours, and
    neither is a temporary of ``NAME.zarr`` when ``name`` is ``NAME``."""
    names = "|".join(re.escape(n) for n in {name, _stem(name)})  # a long name: either form
    found = re.fullmatch(rf"\.(?:{names})~([^~/]+)~(\d+)~[0-9a-f]{{8}}(\.tmp|\.old)", entry)
    if found:
        return found.group(1), int(found.group(2))
    if re.fullmatch(rf"\.{re.escape(name)}\.[a-z0-9_]{{8}}(\.tmp|\.old|\.work)", entry):
        return None
    return False


def alive(host: str, pid: int) -> bool:
    """Whether the run ``(host, pid)`` may still be going (another host: assumed so)."""
    if host != socket.gethostname().replace("~", "-").replace("/", "-"):
        return True
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    except PermissionError:
        return True
    return True


def clean(path: PathLike, everything: bool = False) -> list[str]:
    """Remove the temporaries that runs writing ``path`` left behind; return their URLs.

    A temporary is removed when the process that made it is gone (same host) or its maker
    is unknown (older versions); with ``everything``, also those of running processes and
    of other hosts (when no run for ``path`` is in progress anywhere). Raises
    ``ValueError`` when ``path`` exists and is not a mesh store (a mesh file, say).
    """
    url = location(path)
    target_fs, target = filesystem(url)
    if target_fs.exists(target) and not is_store(url, complete=False):
        raise ValueError(f"{url}: not a qdrefine mesh store (clean removes the temporary "
                         "stores that runs writing a store leave next to it)")
    parent, name = split(url)
    fs, root = filesystem(parent or "/")
    try:
        entries = [e.rstrip("/").rsplit("/", 1)[-1] for e in fs.ls(root, detail=False)]
    except (FileNotFoundError, NotADirectoryError):
        return []
    removed = []
    for entry in sorted(entries):
        owner = maker_of(entry, name)
        if owner is False or not fs.isdir(f"{root.rstrip('/')}/{entry}"):
            continue  # not ours: temporaries are directories (stores)
        if owner is None and not _left_by_qdrefine(join(parent, entry)):
            continue  # an old-style name, but a user's directory (.NAME.20240101.old)
        if everything or owner is None or not alive(*owner):
            if entry.endswith(OLD) and is_local(url) and not os.path.exists(root_of(url)) \
                    and is_store(join(parent, entry)):
                # a run killed between its two renames: the target was this, put it back
                os.rename(f"{root.rstrip('/')}/{entry}", root_of(url))
                continue
            remove(join(parent, entry))
            removed.append(join(parent, entry))
    return removed


def _left_by_qdrefine(url: str) -> bool:
    """Whether the directory ``url``, named as older versions named their temporaries, holds
    what they left: a mesh store (finished or not), nothing, or (``.work``) only the
    ``.npy`` files of a run's intermediate data. Such names (``.NAME.`` and 8 characters)
    are common enough for a user's own folders (``.mesh.zarr.20240101.old``) that the name
    alone removed them (review)."""
    if is_store(url, complete=False):
        return True
    fs, root = filesystem(url)
    files = fs.find(root)
    return not files or (url.endswith(".work") and all(f.endswith(".npy") for f in files))


def root_of(url: str) -> str:
    return filesystem(url)[1]


def remove(url: str) -> None:
    """Remove whatever is at ``url`` (a store, a temporary), if anything; only that (fsspec's
    ``rm`` reads ``[``, ``?`` and ``*`` in a name as a pattern: ``out[1].zarr`` removed
    ``out1.zarr``, so the objects are listed and removed by name, :func:`_remove_tree`)."""
    fs, root = filesystem(url)
    with contextlib.suppress(FileNotFoundError, OSError):
        if is_local(url):
            if os.path.isdir(root) and not os.path.islink(root):
                shutil.rmtree(root)
            else:
                os.remove(root)
            return
        _remove_tree(fs, root)


#: The characters fsspec expands as patterns in the paths given to ``rm``, ``mv``, ``copy``.
_PATTERN = re.compile(r"[*?\[]")


def _remove_tree(fs, root: str) -> None:
    """Every object under ``root`` of an fsspec filesystem, then its folders, by name."""
    if fs.isfile(root):
        fs.rm_file(root)
        return
    found = fs.find(root, withdirs=True, detail=True)
    files = [path for path, info in found.items() if info.get("type") != "directory"]
    if files and not any(_PATTERN.search(path) for path in files):
        fs.rm(files)  # no pattern to expand: one batched request per 1000 objects on S3
    else:
        for path in files:
            fs.rm_file(path)
    folders = [p for p, info in found.items() if info.get("type") == "directory"] + [root]
    for folder in sorted(set(folders), key=len, reverse=True):
        with contextlib.suppress(FileNotFoundError, OSError, NotImplementedError):
            fs.rmdir(folder)


def check_target(url: str) -> None:
    fs, root = filesystem(url)
    if is_local(url):
        parent = os.path.dirname(root)
        if not os.path.isdir(parent):
            raise FileNotFoundError(f"{url}: directory {parent} does not exist")
    if fs.exists(root) and not is_store(url, complete=False):
        raise FileExistsError(f"{url}: exists and is not a qdrefine mesh store; refusing to "
                              "replace it")


def replace(tmp: str, url: str) -> None:
    fs, root = filesystem(url)
    _, tmp_root = filesystem(tmp)
    if is_local(url):
        if not os.path.exists(root):
            os.rename(tmp_root, root)
            return
        old = filesystem(temporary(url, OLD))[1]
        held: list[int] = []
        with signals_held(held):  # the target is absent between the renames
            os.rename(root, old)
            try:
                os.rename(tmp_root, root)
            except OSError:
                os.rename(old, root)
                raise
        remove(old)
        if held:  # the new store is in place: the interrupt acts now
            signal.raise_signal(held[0])
        return
    # object stores: no rename. The old target's root zarr.json goes first (it is no longer
    # a store), the new one's last (it becomes one only when everything else is there).
    if fs.exists(root):
        with contextlib.suppress(FileNotFoundError):
            fs.rm_file(f"{root}/zarr.json")
        _remove_tree(fs, root)
    files = sorted(fs.find(tmp_root))
    head = f"{tmp_root}/zarr.json"
    for f in [f for f in files if f != head] + [head]:  # by name: no pattern expansion
        fs.cp_file(f, root + f[len(tmp_root):])
        fs.rm_file(f)
    remove(tmp)
