"""``qdrefine convert IN OUT``: between mesh formats and chunked Zarr mesh stores."""

from __future__ import annotations

import argparse

from ..io import read, write
from . import _common

HELP = "convert a mesh between file formats, or to and from a chunked Zarr store (.zarr)"


def add_args(parser: argparse.ArgumentParser) -> None:
    _common.setup(parser)
    parser.epilog = ("A name ending in .zarr is a chunked mesh store (docs/scale-out.md), the "
                     "input and output of 'qdrefine refine --dask'. Storing to .msh or "
                     "Triangle files streams chunk by chunk. Example: qdrefine convert "
                     "in.msh in.zarr; qdrefine refine in.zarr out.zarr --dask; qdrefine "
                     "convert out.zarr out.msh --binary")
    parser.add_argument("input", metavar="IN", help="mesh file or .zarr store, a path or a "
                        "URL such as s3://bucket/in.zarr (never modified)")
    parser.add_argument("output", metavar="OUT", help="mesh file or .zarr store (path or URL) "
                        "to write (complete or absent)")
    parser.add_argument("--binary", action="store_true",
                        help="write .msh or .stl as binary (text by default); .vtk, .vtu "
                        "and .ply are written binary anyway")
    _common.add_format_version(parser)
    _common.add_compress(parser)
    parser.add_argument("--chunk-size", type=_positive, default=None, metavar="ROWS",
                        help="rows per chunk of a new store (default 262144, at most 16777216)")


def run(args: argparse.Namespace) -> int:
    with _common.session():
        from_store = _is_store_name(args.input)
        to_store = _is_store_name(args.output)
        if "://" in args.output:  # a URL: only stores, and no local checks apply
            if not to_store or args.binary or args.compress:
                raise ValueError(f"{args.output}: a URL must name a Zarr store (ending in "
                                 f"{_common.STORE}), without --binary or --compress")
            _common.check_url_output(args.output, (args.input,))
        else:
            _common.check_output(args.output, (args.input,), kinds="any", binary=args.binary)
            _common.check_format_version(args.output, args.format_version)
            _common.check_compress(args.output, args.compress)
        if args.chunk_size is not None and not to_store:
            raise _common.UsageError("--chunk-size applies to a .zarr output only")
        if from_store or to_store:
            from .. import store

            if from_store and to_store:
                store.create(args.output, store.to_mesh(args.input), *_chunk(args))
            elif from_store:
                store.to_file(args.input, args.output, binary=args.binary or None,
                              compress=args.compress, format_version=args.format_version)
            else:
                store.from_file(args.input, args.output, *_chunk(args))
        else:
            write(args.output, read(args.input), binary=args.binary or None,
                  format_version=args.format_version, compress=args.compress)
        if not args.quiet:
            print(f"{args.output}: written from {args.input}")
    return 0


def _is_store_name(path: str) -> bool:
    return path.rstrip("/").lower().endswith(_common.STORE)


def _chunk(args: argparse.Namespace) -> tuple[int, ...]:
    return () if args.chunk_size is None else (args.chunk_size,)


def _positive(text: str) -> int:
    value = _common.non_negative(text)
    if value == 0:
        raise argparse.ArgumentTypeError("expected a number >= 1, got 0")
    return value
