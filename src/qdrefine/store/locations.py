"""Where a store is: local paths and URLs (``memory://``, ``s3://``, ``gs://`` ... through
fsspec), made usable by every process."""

from __future__ import annotations

import os

__all__ = ["PathLike", "location", "is_local", "filesystem", "canonical", "overlap", "join",
           "split"]

PathLike = str | os.PathLike


def location(path: PathLike) -> str:
    """``path`` as the string every process can use: a URL (``scheme://...``) unchanged but
    for a trailing ``/``, a local path (``file://`` URLs included) made absolute.

    >>> location("memory://a/b.zarr/")
    'memory://a/b.zarr'
    """
    text = os.fspath(path)
    if text.startswith("file://"):  # a local path: one spelling, so that it compares
        # as fsspec and Zarr take it: no percent-decoding (the folder is named as written)
        text = text[len("file://"):]
    if "://" in text:
        return text.rstrip("/")
    return os.path.abspath(text)


def is_local(url: str) -> bool:
    """Whether ``url`` (from :func:`location`) is a local path."""
    return "://" not in url or url.startswith("file://")


#: Protocols of storage itself, which never start a chain (``zip://x.zarr::a.zip`` and
#: ``simplecache::s3://...`` do): after them ``::`` can only be part of a name.
_STORAGE = frozenset({"memory", "file", "local", "s3", "s3a", "gs", "gcs", "az", "abfs",
                      "abfss", "adl", "http", "https", "hdfs", "sftp", "ssh", "ftp", "webdav"})


def filesystem(url: str):
    """``(fsspec filesystem, path within it)`` of ``url``, with no stale listings cached
    (object stores' filesystems cache directory listings that other writers change)."""
    import fsspec

    if is_local(url) and "::" in url:  # fsspec and Zarr would open another path
        raise ValueError(f"{url}: a local store path cannot contain '::' (fsspec reads it "
                         "as URL chaining); rename it")
    outer = url.split("::")[0].split("://")[0]
    if "::" in url and outer in _STORAGE:  # memory://b/a::b.zarr: not a chain's start
        raise ValueError(f"{url}: a store name cannot contain '::' (fsspec reads it as URL "
                         "chaining and would write elsewhere); rename it")
    try:
        fs, root = fsspec.core.url_to_fs(url)
    except ImportError as exc:  # gs:// without gcsfs: fsspec says which package (a traceback)
        raise ValueError(f"{url}: {exc}") from None
    fs.invalidate_cache()
    return fs, root


def canonical(url: str) -> str:
    """One spelling of the place ``url`` (from :func:`location`) names, to compare two:
    a local path with its links resolved, a URL as its filesystem's protocol and path
    (``memory:///b/x.zarr`` and ``memory://b/x.zarr`` are one place); a chained URL
    (``simplecache::s3://...``, ``zip://...::...``) as written."""
    if "::" in url:
        return url
    if is_local(url):
        return os.path.realpath(url[len("file://"):] if url.startswith("file://") else url)
    fs, root = filesystem(url)
    protocol = fs.protocol if isinstance(fs.protocol, str) else fs.protocol[0]
    return f"{protocol}://{root.rstrip('/')}"


def overlap(target: str, source: str, words: tuple[str, str] = ("output", "input")
            ) -> str | None:
    """Why writing ``target`` (a URL from :func:`location`) would change ``source``: it is
    the same place, inside it, or holds it (a store is replaced as a whole, so a source
    inside the target would be deleted); None when they are apart. ``words``: what the
    message calls the two."""
    out, src = words
    here, there = canonical(target), canonical(location(source))
    if here == there:
        return f"the {out} would overwrite the {src}"
    if _inside(here, there):
        return f"the {out} would be inside the {src} {source}"
    if _inside(there, here):
        return f"the {src} {source} is inside the {out}, which writing replaces as a whole"
    return None


def _inside(url: str, folder: str) -> bool:
    """Whether canonical ``url`` lies below canonical ``folder`` (a local path by the
    platform's separators, ``C:\\a\\b`` on Windows)."""
    if "://" not in url and "://" not in folder:  # canonical local paths; a file:// URL
        return url.startswith(os.path.join(folder, ""))  # (fsspec's root) keeps '/'
    return url.startswith(folder.rstrip("/") + "/")


def join(url: str, name: str) -> str:
    """``name`` in the folder ``url`` (from :func:`location`)."""
    return os.path.join(url, name) if is_local(url) else f"{url}/{name}"


def split(url: str) -> tuple[str, str]:
    """``(parent URL, name)`` of ``url`` (from :func:`location`)."""
    if is_local(url):
        return os.path.split(url)
    parent, _, name = url.rpartition("/")
    return parent, name
