"""Atomic writes: temporary files that replace their targets only when every one was
written, ordinary permissions, and the one-line error of a write the system refuses."""

from __future__ import annotations

import contextlib
import errno
import os
import re
import stat
from collections.abc import Iterator
from pathlib import Path

PathLike = str | os.PathLike

__all__ = ["WRITE_ERRNOS", "atomic_path", "atomic_paths", "cannot_write", "file_set",
           "make_directory", "permission_bits"]


@contextlib.contextmanager
def atomic_path(path: PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; on success it replaces ``path``.

    On any exception the temporary file is removed and ``path`` is left as it was. The
    temporary name keeps the extension, so tools that look at it still work.
    """
    with atomic_paths([path]) as (tmp,):
        yield tmp


#: System errors of a write that the disk or the system refuses (full disk, quota, file size
#: limit, read-only filesystem): reported as "FILE: cannot write: REASON".
WRITE_ERRNOS = frozenset({errno.ENOSPC, errno.EDQUOT, errno.EFBIG, errno.EROFS})


def cannot_write(path: PathLike, reason: str, number: int | None) -> OSError:
    """The one-line error of a refused write: ``"PATH: cannot write: REASON"``, with the
    system's error ``number`` kept as ``errno``."""
    return _os_error(f"{path}: cannot write: {reason}", number)


def _os_error(text: str, number: int | None) -> OSError:
    """An ``OSError`` whose message is ``text``, with the system's error ``number``."""
    error = OSError(text)
    error.errno = number
    return error


def make_directory(path: PathLike) -> Path:
    """Create the output directory ``path`` (and its parents) if missing; a refusal is one
    line naming it (:func:`cannot_write`)."""
    path = Path(path)
    try:
        path.mkdir(parents=True, exist_ok=True)
    except FileExistsError:  # a file, or a link to one
        raise NotADirectoryError(f"{path}: exists and is not a directory") from None
    except OSError as exc:
        raise cannot_write(path, exc.strerror or str(exc), exc.errno) from None
    return path


@contextlib.contextmanager
def file_set(folder: PathLike) -> Iterator[Path]:
    """Yield a temporary folder inside ``folder`` (made now if missing) for a set of files
    that appear in ``folder`` together: once every one is written, each is moved in by a
    rename, replacing a file of its name and keeping that file's permission bits. On any
    exception none appears: the temporary folder is removed, ``folder`` too if this made
    it, and errors name the files in ``folder``, not in the temporary one (``demo`` and
    ``paper`` left the files written before a full disk stopped them; review)."""
    import tempfile

    folder = Path(folder)
    made = not folder.exists()
    make_directory(folder)
    tmp = None
    try:
        try:
            tmp = Path(tempfile.mkdtemp(prefix=".qdrefine-", suffix=".tmp", dir=folder))
        except OSError as exc:
            raise cannot_write(folder, exc.strerror or str(exc), exc.errno) from None
        yield tmp
        entries = sorted(tmp.iterdir())
        for entry in entries:  # every check before the first rename: all or none
            target = folder / entry.name
            if target.is_dir() and not target.is_symlink():
                raise IsADirectoryError(f"{target}: is a directory")
        for entry in entries:
            os.chmod(entry, permission_bits(folder / entry.name))
            os.replace(entry, folder / entry.name)
        tmp.rmdir()
    except (OSError, ValueError) as exc:
        _remove_set(tmp, folder, made)
        if tmp is not None and str(tmp) in str(exc):  # named in the folder, as written
            text = str(exc).replace(str(tmp), str(folder))
            if isinstance(exc, OSError):
                raise _os_error(text, exc.errno) from None
            raise ValueError(text) from None
        raise
    except BaseException:
        _remove_set(tmp, folder, made)
        raise


def _remove_set(tmp: Path | None, folder: Path, made: bool) -> None:
    """What :func:`file_set` made: its temporary folder, and ``folder`` if it made it."""
    import shutil

    if tmp is not None:
        shutil.rmtree(tmp, ignore_errors=True)
    if made:
        with contextlib.suppress(OSError):
            folder.rmdir()  # only if empty


@contextlib.contextmanager
def atomic_paths(paths: list[PathLike]) -> Iterator[list[Path]]:
    """:func:`atomic_path` for a set of files written together (Triangle's three files, XDMF
    and its HDF5 file): temporary paths are yielded, and only when all were written do they
    replace their targets (one ``os.replace`` each, in order, after every write succeeded)."""
    targets = [Path(p) for p in paths]
    for path in targets:
        if not path.parent.is_dir():
            raise FileNotFoundError(f"{path}: directory {path.parent} does not exist")
        if path.is_dir():
            raise IsADirectoryError(f"{path}: is a directory")
    temps: list[Path] = []
    try:
        for path in targets:
            # named and listed before it exists, so that an interrupt (Ctrl-C, SIGTERM)
            # landing just after its creation still finds it to remove
            while True:
                tmp = path.parent / f".{path.stem}.{os.urandom(4).hex()}.tmp{path.suffix}"
                temps.append(tmp)
                try:
                    fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o600)
                    break
                except FileExistsError:
                    temps.pop()
                except OSError as exc:
                    raise cannot_write(path, exc.strerror or str(exc), exc.errno) from None
            os.close(fd)
            os.chmod(tmp, permission_bits(path))
        try:
            yield temps
            for tmp, path in zip(temps, targets, strict=True):
                os.replace(tmp, path)
        except OSError as exc:  # a full disk, a file size limit ...: name the file
            named = next((p for t, p in zip(temps, targets, strict=True)
                          if exc.filename is not None and str(t) == str(exc.filename)), None)
            if str(exc).startswith(tuple(str(p) for p in targets)) or (
                    named is None and exc.errno is not None and exc.errno not in WRITE_ERRNOS):
                raise  # named already, or not a write of ours (e.g. reading a source);
                # no errno: NumPy's tofile refused ("N requested and M written")
            short = re.fullmatch(r"(\d+) requested and (\d+) written", str(exc))
            reason = exc.strerror or str(exc) if short is None else \
                f"the system took {short[2]} of {short[1]} bytes (a file size limit or a " \
                "full disk)"  # NumPy's own words, without errno (review)
            raise cannot_write(named or targets[0], reason, exc.errno) from None
    except BaseException:
        for tmp in temps:
            with contextlib.suppress(OSError):
                tmp.unlink()
        raise


def permission_bits(path: Path, new: int = 0o666) -> int:
    """The permission bits of ``path`` if it is a regular file or a directory, else ``new``
    less the umask (``0o666`` for a new file, ``0o777`` for a new directory; also for a
    link to a device, whose 0666 a new file took, review)."""
    try:
        mode = path.stat().st_mode
        if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
            return mode & 0o777
    except OSError:
        pass
    umask = os.umask(0)
    os.umask(umask)
    return new & ~umask
